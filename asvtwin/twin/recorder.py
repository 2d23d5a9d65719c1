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
import struct
import threading
import zlib
from collections import defaultdict
from pathlib import Path
from typing import IO, Any

import orjson
import zstandard
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Message,
    MessageIndex,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)

from asvtwin.twin.snapshot import SCHEMA_ID, json_schema

__all__ = ["METADATA_NAME", "TOPICS", "ZSTD_LEVEL", "Recorder"]

_log = logging.getLogger(__name__)

#: zstd level of the chunks. The ``mcap`` package's writer (1.6) compresses its chunks with
#: ``zstandard.compress`` at the library default (3) and has no option for the level; on the
#: twin's snapshot stream level 1 is 3x faster for < 1 % more bytes (20 snapshots of the
#: benchmark scene, 1.10 MB: 337 kB in 5.7 ms vs 339 kB in 16.6 ms of CPU). Readers see
#: ordinary zstd frames either way.
ZSTD_LEVEL = 1

#: The magic bytes that open and close an MCAP file (MCAP specification, "Magic").
_MAGIC = b"\x89MCAP0\r\n"


class _ChunkedWriter:
    """An MCAP writer whose zstd chunks are compressed at a level of its own.

    The ``mcap`` package writes its chunks through a module-level call with no level
    option; rather than patch that module for every writer in the process, this writer
    lays out the file itself from the package's record classes (``mcap.records``, each of
    which serialises itself): magic, header, metadata, zstd chunks (schemas and channels in
    the first, as ``mcap.writer.Writer`` puts them) each followed by its message indexes,
    data end, a summary (schemas, channels, statistics, chunk and metadata indexes, summary
    offsets), the footer with the summary's CRC, magic. Files read back with
    ``mcap.reader.make_reader`` (seeking and streaming) and ``asvtwin replay``.
    """

    def __init__(self, stream: Any, *, chunk_size: int, level: int) -> None:
        self._out = stream
        self._chunk_size = int(chunk_size)
        self._zstd = zstandard.ZstdCompressor(level=int(level))
        self._pos = 0  # bytes handed to the stream (it may not support tell())
        self._schemas: list[Schema] = []
        self._channels: list[Channel] = []
        self._chunk = RecordBuilder()
        self._chunk_messages = 0
        self._chunk_t: tuple[int, int] = (0, 0)
        self._msg_index: dict[int, MessageIndex] = {}
        self._chunk_indexes: list[ChunkIndex] = []
        self._meta_indexes: list[MetadataIndex] = []
        # the chunk being compressed on the other core: (thread, result box, raw, times,
        # message indexes); joined at the next message, write or finish
        self._flight: tuple[threading.Thread, list[Any], bytes, tuple[int, int],
                            dict[int, MessageIndex]] | None = None
        self._stats = Statistics(attachment_count=0, channel_count=0,
                                 channel_message_counts=defaultdict(int), chunk_count=0,
                                 message_count=0, message_end_time=0, message_start_time=0,
                                 metadata_count=0, schema_count=0)

    def _write(self, data: bytes) -> None:
        self._join()
        self._out.write(data)
        self._pos += len(data)

    @staticmethod
    def _bytes(*records: Any) -> bytes:
        b = RecordBuilder()
        for r in records:
            r.write(b)
        return bytes(b.end())

    def start(self, *, library: str) -> None:
        self._write(_MAGIC + self._bytes(Header(profile="", library=library)))

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        s = Schema(id=len(self._schemas) + 1, data=data, encoding=encoding, name=name)
        self._schemas.append(s)
        self._stats.schema_count += 1
        s.write(self._chunk)
        return s.id

    def register_channel(self, topic: str, message_encoding: str, schema_id: int) -> int:
        c = Channel(id=len(self._channels) + 1, topic=topic, message_encoding=message_encoding,
                    schema_id=schema_id, metadata={})
        self._channels.append(c)
        self._stats.channel_count += 1
        c.write(self._chunk)
        return c.id

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        rec = self._bytes(Metadata(name=name, metadata=data))
        self._meta_indexes.append(MetadataIndex(offset=self._pos, length=len(rec), name=name))
        self._stats.metadata_count += 1
        self._write(rec)

    def add_message(self, channel_id: int, log_time: int, data: bytes, publish_time: int,
                    sequence: int) -> None:
        if self._flight is not None:
            self._join()
        st = self._stats
        t0, t1 = self._chunk_t
        self._chunk_t = ((log_time, log_time) if self._chunk_messages == 0
                         else (min(t0, log_time), max(t1, log_time)))
        st.message_start_time = (log_time if st.message_count == 0
                                 else min(st.message_start_time, log_time))
        st.message_end_time = max(st.message_end_time, log_time)
        st.message_count += 1
        st.channel_message_counts[channel_id] += 1
        idx = self._msg_index.get(channel_id)
        if idx is None:
            idx = self._msg_index[channel_id] = MessageIndex(channel_id=channel_id, records=[])
        idx.records.append((log_time, self._chunk.count))
        Message(channel_id=channel_id, log_time=log_time, data=data, publish_time=publish_time,
                sequence=sequence).write(self._chunk)
        self._chunk_messages += 1
        if self._chunk.count > self._chunk_size:
            self._finish_chunk()

    def _finish_chunk(self) -> None:
        """Close the open chunk: its zstd compression and CRC (C code that releases the
        GIL) run on a thread of their own while the twin goes on ticking; the chunk is laid
        out and written when that thread is joined (:meth:`_join`: at the next message,
        write or :meth:`finish`), so the file's bytes and their order are those of a
        writer that compresses in line. An ``OSError`` of that write reaches the caller of
        the call that joined (the next message), not the one that filled the chunk."""
        if self._chunk_messages == 0:
            return
        self._join()
        raw = bytes(self._chunk.end())
        box: list[Any] = []
        zstd = self._zstd

        def pack() -> None:
            box.append(zstd.compress(raw))
            box.append(zlib.crc32(raw))

        th = threading.Thread(target=pack, name="mcap-chunk", daemon=False)
        self._flight = (th, box, raw, self._chunk_t, self._msg_index)
        self._chunk_messages = 0
        self._msg_index = {}
        th.start()

    def sync(self) -> None:
        """Write the chunk in flight now (if any)."""
        self._join()

    def _join(self) -> None:
        """Wait for the chunk in flight (if any) and write it with its message indexes."""
        flight, self._flight = self._flight, None
        if flight is None:
            return
        th, box, raw, (t0, t1), msg_index = flight
        th.join()
        if len(box) != 2:  # pragma: no cover - compression itself failed (memory)
            box[:] = [self._zstd.compress(raw), zlib.crc32(raw)]
        packed, crc = box
        chunk = self._bytes(Chunk(compression="zstd", data=packed, message_start_time=t0,
                                  message_end_time=t1, uncompressed_crc=crc,
                                  uncompressed_size=len(raw)))
        start = self._pos
        offsets, index = {}, RecordBuilder()
        for cid, mi in msg_index.items():
            offsets[cid] = start + len(chunk) + index.count
            mi.write(index)
        indexes = bytes(index.end())
        # the chunk and its message indexes in one write: a full disk leaves either both or
        # a damaged tail that readers skip
        self._write(chunk + indexes)
        self._chunk_indexes.append(ChunkIndex(
            message_start_time=t0, message_end_time=t1, chunk_start_offset=start,
            chunk_length=len(chunk), message_index_offsets=offsets,
            message_index_length=len(indexes), compression="zstd",
            compressed_size=len(packed), uncompressed_size=len(raw)))
        self._stats.chunk_count += 1

    def finish(self) -> None:
        self._finish_chunk()
        self._join()
        self._write(self._bytes(DataEnd(data_section_crc=0)))
        summary_start = self._pos
        groups: list[tuple[int, list[Any]]] = [
            (Opcode.SCHEMA, list(self._schemas)), (Opcode.CHANNEL, list(self._channels)),
            (Opcode.STATISTICS, [self._stats]), (Opcode.CHUNK_INDEX, self._chunk_indexes),
            (Opcode.METADATA_INDEX, self._meta_indexes)]
        body = RecordBuilder()
        offsets = []
        for opcode, records in groups:
            g0 = body.count
            for r in records:
                r.write(body)
            offsets.append(SummaryOffset(group_opcode=opcode, group_start=summary_start + g0,
                                         group_length=body.count - g0))
        offset_start = summary_start + body.count
        for o in offsets:
            o.write(body)
        summary = bytes(body.end())
        crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 20, summary_start, offset_start),
                         zlib.crc32(summary))
        self._write(summary + self._bytes(Footer(summary_start=summary_start,
                                                 summary_offset_start=offset_start,
                                                 summary_crc=crc)) + _MAGIC)

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
        self._writer: _ChunkedWriter | None = None
        try:
            w = _ChunkedWriter(self._stream, chunk_size=int(chunk_size), level=ZSTD_LEVEL)
            w.start(library="asvtwin")
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
        """Bytes written to the file so far (compressed chunks, the one being compressed
        included; the open chunk is not)."""
        w = self._writer
        if w is not None and self.error is None and not self.closed:
            try:
                w.sync()
            except OSError as exc:
                self._fail(exc)
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
