"""Recording and replay: MCAP with JSON Schema channels, metadata, seek, and a full disk."""

from __future__ import annotations

import errno
import io
import json

import jsonschema
import orjson
import pytest
from mcap.reader import make_reader

from asvtwin.errors import SourceError
from asvtwin.twin.recorder import TOPICS, Recorder
from asvtwin.twin.replay import Recording
from asvtwin.twin.snapshot import empty_snapshot, encode, json_schema

EPOCH = 1_732_100_400.0


def _write(rec: Recorder, n: int, dt: float = 0.5) -> None:
    for i in range(n):
        rec.write("/twin/snapshot", i * dt, encode(empty_snapshot(t_s=i * dt, seq=i)))
        if i % 10 == 0:
            rec.write_json("/twin/nmea", i * dt, {"t_s": i * dt, "tick": i, "lines": ["!AIVDM"]})


def test_round_trip_metadata_seek_and_schema(tmp_path):
    path = tmp_path / "run.mcap"
    rec = Recorder(path, scenario_json='{"name": "x", "seed": 5}', seed=5, epoch_unix_s=EPOCH,
                   chunk_size=4096)
    _write(rec, 200)
    rec.write_json("/twin/summary", 99.5, {"collisions": 0})
    rec.close()
    assert rec.error is None and rec.messages == 221

    r = Recording(path)
    assert not r.truncated
    assert r.seed == 5 and r.scenario == {"name": "x", "seed": 5}
    assert r.metadata["schema"] == "asvtwin.snapshot/1"
    assert r.duration_s == pytest.approx(99.5)
    assert r.summary == {"collisions": 0}
    # the last message at or before t; the first one before the start
    assert orjson.loads(r.message_at(42.7))["t_s"] == 42.5
    assert orjson.loads(r.message_at(42.5))["seq"] == 85
    assert orjson.loads(r.message_at(-10.0))["t_s"] == 0.0
    ts = [t for t, _ in r.iter_messages(start_s=90.0)]
    assert ts == [90.0 + 0.5 * k for k in range(20)]
    assert len(list(r.iter_messages(topic="/twin/nmea"))) == 20

    # what any MCAP tool sees: jsonschema channels whose schema validates the messages
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and len(summary.chunk_indexes) > 3
        schemas = {s.id: s for s in summary.schemas.values()}
        for ch in summary.channels.values():
            assert ch.message_encoding == "json"
            assert schemas[ch.schema_id].encoding == "jsonschema"
            assert json.loads(schemas[ch.schema_id].data) == TOPICS[ch.topic][1]
        for schema, channel, msg in reader.iter_messages(topics=["/twin/snapshot"]):
            jsonschema.validate(json.loads(msg.data), json.loads(schema.data))
            assert msg.log_time == round((EPOCH + json.loads(msg.data)["t_s"]) * 1e9)
            break
    assert json.loads(schemas[1].data)["$id"] == json_schema()["$id"]


class FullDisk(io.RawIOBase):
    """A file on a disk with ``free`` bytes: writes what fits, then ENOSPC."""

    def __init__(self, path, free: int) -> None:
        self.f = open(path, "wb")  # noqa: SIM115
        self.free = free

    def writable(self) -> bool:
        return True

    def write(self, b) -> int:
        b = bytes(b)
        if len(b) > self.free:
            self.f.write(b[: self.free])
            self.free = 0
            self.f.flush()
            raise OSError(errno.ENOSPC, "No space left on device")
        self.free -= len(b)
        return self.f.write(b)

    def tell(self) -> int:
        return self.f.tell()

    def flush(self) -> None:
        self.f.flush()

    def close(self) -> None:
        self.f.close()


@pytest.mark.parametrize("how", ["enospc", "quota"])
def test_full_disk_stops_recording_and_leaves_a_readable_file(tmp_path, how):
    path = tmp_path / "full.mcap"
    if how == "enospc":
        rec = Recorder(FullDisk(path, 30_000), scenario_json="{}", seed=1, chunk_size=4096)
    else:
        rec = Recorder(path, scenario_json="{}", seed=1, chunk_size=4096, max_bytes=30_000)
    _write(rec, 2000)
    assert not rec.active
    assert "No space left on device" in rec.error
    written = rec.messages
    assert 50 < written < 2000
    rec.close()  # nothing more happens, no exception
    r = Recording(path)
    assert r.truncated and r.damage
    got = [orjson.loads(d)["seq"] for _, d in r.iter_messages()]
    # every complete chunk survives: a prefix of what was written, up to the last chunk
    assert got == list(range(len(got)))
    n_nmea = sum(1 for _ in r.iter_messages(topic="/twin/nmea"))
    # at most the chunk being written is lost (4 kB: a few ~1.6 kB snapshots)
    assert 0 < written - (len(got) + n_nmea) <= 8, (written, len(got), n_nmea)
    assert r.summary is None


def test_not_a_recording(tmp_path):
    with pytest.raises(SourceError, match="does not exist"):
        Recording(tmp_path / "missing.mcap")
    p = tmp_path / "junk.mcap"
    p.write_bytes(b"hello world, not mcap at all" * 10)
    with pytest.raises(SourceError, match="metadata"):
        Recording(p)
