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


def test_own_chunk_writer_matches_the_mcap_writer_and_leaves_it_alone(tmp_path):
    """The recorder lays out its chunks itself (zstd at ZSTD_LEVEL): the file must read
    back, CRCs checked, exactly as the same messages written by ``mcap``'s own Writer do,
    and the ``mcap`` package is left untouched for every other writer in the process."""
    import mcap.writer as mw
    import zstandard
    from mcap.stream_reader import StreamReader

    from asvtwin.twin.recorder import ZSTD_LEVEL

    ours = tmp_path / "ours.mcap"
    rec = Recorder(ours, scenario_json='{"name": "x"}', seed=3, epoch_unix_s=EPOCH,
                   chunk_size=4096)
    _write(rec, 300)
    rec.close()
    assert mw.zstandard is zstandard  # no module patched

    # the reference: the same records through mcap's Writer (library default level)
    ref = tmp_path / "ref.mcap"
    with open(ref, "wb") as f:
        w = mw.Writer(f, chunk_size=4096, compression=mw.CompressionType.ZSTD)
        w.start(profile="", library="asvtwin")
        for topic, (name, schema) in TOPICS.items():
            sid = w.register_schema(name=name, encoding="jsonschema", data=orjson.dumps(schema))
            w.register_channel(topic=topic, message_encoding="json", schema_id=sid)
        with open(ours, "rb") as g:
            for md in make_reader(g).iter_metadata():
                w.add_metadata(md.name, md.metadata)
            g.seek(0)
            for _, _, m in make_reader(g).iter_messages():
                w.add_message(m.channel_id, m.log_time, m.data, m.publish_time, m.sequence)
        w.finish()

    def content(path):
        with open(path, "rb") as f:
            r = make_reader(f, validate_crcs=True)
            s = r.get_summary()
            msgs = [(c.topic, m.log_time, m.sequence, m.data) for _, c, m in r.iter_messages()]
            rev = [m.log_time for _, _, m in r.iter_messages(reverse=True)]
            meta = [(md.name, md.metadata) for md in r.iter_metadata()]
        with open(path, "rb") as f:  # front to back, as a tool without the index reads it
            streamed = [(m.log_time, m.data) for m in StreamReader(f, validate_crcs=True,
                                                                  skip_magic=False).records
                        if type(m).__name__ == "Message"]
        return s, msgs, rev, streamed, meta

    s1, m1, rev1, st1, md1 = content(ours)
    s2, m2, rev2, st2, md2 = content(ref)
    assert md1 == md2 and md1[0][1]["seed"] == "3"
    assert len(m1) == 330 and m1 == m2 and rev1 == rev2 == sorted(rev1, reverse=True)
    assert st1 == st2 == [(t, d) for _, t, _, d in m1]
    assert s1.statistics == s2.statistics
    assert [(c.topic, c.schema_id) for c in s1.channels.values()] == \
        [(c.topic, c.schema_id) for c in s2.channels.values()]
    assert {k: (v.name, v.data) for k, v in s1.schemas.items()} == \
        {k: (v.name, v.data) for k, v in s2.schemas.items()}
    assert len(s1.chunk_indexes) == len(s2.chunk_indexes) > 10
    for a, b in zip(s1.chunk_indexes, s2.chunk_indexes, strict=True):
        assert (a.message_start_time, a.message_end_time, a.uncompressed_size,
                a.compression) == (b.message_start_time, b.message_end_time,
                                   b.uncompressed_size, "zstd")
    # every chunk holds zstd at ZSTD_LEVEL: recompressing its content gives its bytes
    with open(ours, "rb") as f:
        data = f.read()
    assert ZSTD_LEVEL == 1
    at_default = []
    for ci in s1.chunk_indexes:
        with open(ours, "rb") as f:
            f.seek(ci.chunk_start_offset)
            rec0 = next(iter(StreamReader(f, skip_magic=True, emit_chunks=True).records))
        raw = zstandard.ZstdDecompressor().decompress(rec0.data)
        assert zstandard.ZstdCompressor(level=ZSTD_LEVEL).compress(raw) == rec0.data
        at_default.append(zstandard.compress(raw) == rec0.data)
    assert not all(at_default)  # (the check tells level 1 from the library's default 3)
    assert data.endswith(b"\x89MCAP0\r\n")
