"""Recording a run to MCAP: the snapshot stream, the raw inputs, the scenario and seed.

The file follows the convention Foxglove/Lichtblick and the ROS 2 tools read: JSON
messages (``message_encoding="json"``) on channels whose schema is a JSON Schema
(``encoding="jsonschema"``), zstd-compressed chunks, a summary with chunk indexes at the
end so a reader can seek. Channels (see :data:`TOPICS`):

- ``/twin/snapshot`` — :class:`~asvtwin.twin.snapshot.Snapshot` messages
  (schema :data:`~asvtwin.twin.snapshot.SCHEMA_ID`);
- ``/twin/nmea`` — the NMEA lines that reached the twin in a tick (raw AIS input);
- ``/twin/weather`` — the weather the twin took in (raw weather input);
- ``/twin/commands`` — operator commands applied at a tick (pause/route/wind/...);
- ``/twin/summary`` — the run summary, once, at the end.

The metadata record ``asvtwin.run`` holds the scenario (JSON), the seed, the snapshot
schema id and the epoch (``log_time`` = epoch + simulation time, in ns).

A full disk (``ENOSPC``, or any ``OSError`` while writing, or the optional byte quota)
stops the recording, keeps the reason in :attr:`Recorder.error`, and leaves the file as it
is: every chunk completed before the failure is readable
(:class:`asvtwin.twin.replay.Recording` reads up to the damaged tail). The run goes on.
"""

from __future__ import annotations

import errno
import logging
import os
from pathlib import Path
from typing import IO, Any

import orjson
from mcap.writer import CompressionType, Writer

from asvtwin.twin.snapshot import SCHEMA_ID, json_schema

__all__ = ["METADATA_NAME", "TOPICS", "ZSTD_LEVEL", "Recorder"]

_log = logging.getLogger(__name__)

#: zstd level of the chunks. The mcap writer calls ``zstandard.compress`` at the library
#: default (3); on the twin's snapshot stream level 1 is 5x faster for < 2 % more bytes
#: (measured on 20 snapshots of the benchmark scene: 345 kB vs 350 kB of 1.1 MB, 13 ms vs
#: 67 ms). Readers see ordinary zstd frames either way.
ZSTD_LEVEL = 1


class _ZstdAtLevel:
    """Stands in for the ``zstandard`` module inside ``mcap.writer`` so its chunks are
    compressed at :data:`ZSTD_LEVEL`; everything else is the real module."""

    def __init__(self, module: Any, level: int) -> None:
        self._module = module
        self._level = int(level)

    def compress(self, data: bytes) -> bytes:
        # a compressor per chunk: ZstdCompressor objects are not thread-safe, and two
        # twins may record in two threads
        return bytes(self._module.ZstdCompressor(level=self._level).compress(data))

    def __getattr__(self, name: str) -> Any:
        return getattr(self._module, name)


def _use_fast_zstd() -> None:
    import mcap.writer as mw

    if mw.zstandard is not None and not isinstance(mw.zstandard, _ZstdAtLevel):
        mw.zstandard = _ZstdAtLevel(mw.zstandard, ZSTD_LEVEL)  # type: ignore[assignment]

#: The metadata record's name.
METADATA_NAME = "asvtwin.run"

_OBJ = {"type": "object"}
_T = {"t_s": {"type": "number", "description": "simulation time [s]"}}

#: Topic -> (schema name, JSON Schema) of every channel.
TOPICS: dict[str, tuple[str, dict[str, Any]]] = {
    "/twin/snapshot": (SCHEMA_ID, json_schema()),
    "/twin/nmea": ("asvtwin.nmea/1", {**_OBJ, "title": "NmeaLines", "properties": {
        **_T, "lines": {"type": "array", "items": {"type": "string"},
                        "description": "NMEA 0183 sentences with IEC 61162-450 tag blocks"}}}),
    "/twin/weather": ("asvtwin.weather_input/1", {**_OBJ, "title": "WeatherInput",
                                                  "properties": {**_T, "source": {"type": "string"}}}),
    "/twin/commands": ("asvtwin.command/1", {**_OBJ, "title": "Command", "properties": {
        **_T, "tick": {"type": "integer"}, "command": {"type": "string"},
        "args": {"type": "object"}}}),
    "/twin/summary": ("asvtwin.summary/1", {**_OBJ, "title": "RunSummary"}),
}


class _QuotaStream:
    """A binary file that raises ``OSError(ENOSPC)`` once ``max_bytes`` would be passed,
    after writing what still fits (as a full disk does)."""

    def __init__(self, raw: IO[bytes], max_bytes: int | None) -> None:
        self._raw = raw
        self._max = max_bytes
        self.written = 0

    def write(self, data: bytes | bytearray | memoryview) -> int:
        n = len(data)
        if self._max is not None and self.written + n > self._max:
            fit = max(0, self._max - self.written)
            self._raw.write(bytes(data[:fit]))
            self.written += fit
            raise OSError(errno.ENOSPC, f"recording quota of {self._max} bytes reached")
        self._raw.write(data)
        self.written += n
        return n

    def tell(self) -> int:
        return self._raw.tell()

    def flush(self) -> None:
        self._raw.flush()

    def close(self) -> None:
        self._raw.close()


class Recorder:
    """Writes one run to an MCAP file.

    Parameters
    ----------
    path : path or binary stream
        The ``.mcap`` file to create (parent directories are made), or an open binary
        stream (tests pass one that fails like a full disk).
    scenario_json : str
        The scenario as JSON (metadata; a replay rebuilds the run from it).
    seed : int
        The run's seed (metadata).
    epoch_unix_s : float
        UNIX time of simulation time 0 (``log_time`` = epoch + t).
    chunk_size : int
        Bytes of messages per chunk (the unit that survives a full disk).
    max_bytes : int, optional
        Stop recording (as on a full disk) once the file would exceed this size.
    """

    def __init__(self, path: str | os.PathLike[str] | IO[bytes], *, scenario_json: str,
                 seed: int, epoch_unix_s: float = 0.0, chunk_size: int = 1 << 20,
                 max_bytes: int | None = None, extra_metadata: dict[str, str] | None = None
                 ) -> None:
        if isinstance(path, (str, os.PathLike)):
            self.path: Path | None = Path(path)
            self.path.parent.mkdir(parents=True, exist_ok=True)
            raw: IO[bytes] = open(self.path, "wb")  # noqa: SIM115 - closed in close()
        else:
            self.path, raw = None, path
        self._stream = _QuotaStream(raw, max_bytes)
        self._epoch_ns = round(epoch_unix_s * 1e9)
        self.error: str | None = None
        self.messages = 0
        self.closed = False
        self._seq = 0
        self._writer: Writer | None = None
        _use_fast_zstd()
        try:
            w = Writer(self._stream, chunk_size=int(chunk_size),  # type: ignore[arg-type]
                       compression=CompressionType.ZSTD)
            w.start(profile="", library="asvtwin")
            self._channels: dict[str, int] = {}
            for topic, (name, schema) in TOPICS.items():
                sid = w.register_schema(name=name, encoding="jsonschema",
                                        data=orjson.dumps(schema))
                self._channels[topic] = w.register_channel(topic=topic, message_encoding="json",
                                                           schema_id=sid)
            meta = {"scenario": scenario_json, "seed": str(int(seed)),
                    "schema": SCHEMA_ID, "epoch_unix_s": repr(float(epoch_unix_s)),
                    **(extra_metadata or {})}
            w.add_metadata(METADATA_NAME, meta)
            self._writer = w
        except OSError as exc:
            self._fail(exc)

    @property
    def active(self) -> bool:
        """True while messages are being written (False after a failure or close)."""
        return self._writer is not None and self.error is None and not self.closed

    @property
    def bytes_written(self) -> int:
        """Bytes written to the file so far (compressed chunks; the open chunk is not)."""
        return self._stream.written

    def _fail(self, exc: OSError) -> None:
        why = os.strerror(exc.errno) if exc.errno else str(exc)
        self.error = (f"recording stopped after {self.messages} messages: {why} "
                      f"({exc}); the file is readable up to its last complete chunk")
        _log.error("%s%s", self.error, f" [{self.path}]" if self.path else "")
        self._writer = None
        try:
            self._stream.close()
        except OSError:
            pass

    def write(self, topic: str, t_s: float, data: bytes) -> bool:
        """Add one JSON message at simulation time ``t_s``; False when not recording."""
        w = self._writer
        if w is None or self.error is not None or self.closed:
            return False
        ns = self._epoch_ns + round(t_s * 1e9)
        try:
            w.add_message(self._channels[topic], log_time=ns, publish_time=ns, data=data,
                          sequence=self._seq)
        except OSError as exc:
            self._fail(exc)
            return False
        self._seq += 1
        self.messages += 1
        return True

    def write_json(self, topic: str, t_s: float, obj: Any) -> bool:
        """:meth:`write` of ``obj`` encoded with orjson (numpy arrays allowed)."""
        return self.write(topic, t_s, orjson.dumps(obj, option=orjson.OPT_SERIALIZE_NUMPY))

    def close(self) -> None:
        """Finish the file (summary and index); after a failure, nothing more is written."""
        if self.closed:
            return
        self.closed = True
        w, self._writer = self._writer, None
        if w is None:
            return
        try:
            w.finish()
            self._stream.close()
        except OSError as exc:
            self.closed = False
            self._fail(exc)
            self.closed = True
