"""Reading a recorded run back: metadata, summary, messages in order, seeking by time.

:class:`Recording` opens an MCAP file written by :class:`~asvtwin.twin.recorder.Recorder`.
A complete file is read through its summary and chunk indexes (seeking to a time reads
only the chunks around it). A file cut short (a full disk, a killed process) has no
summary: it is read as a stream up to its last intact record and kept in memory;
:attr:`Recording.truncated` says so and :attr:`Recording.damage` says where it stopped.

Examples
--------
The snapshot messages are the same bytes the server pushes: ``asvtwin replay FILE`` serves
them, ``asvtwin replay FILE --headless`` prints :attr:`Recording.summary`.
"""

from __future__ import annotations

import bisect
import itertools
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import orjson
from mcap.reader import SeekingReader
from mcap.records import Channel, Message, Metadata
from mcap.stream_reader import StreamReader

from asvtwin.errors import SourceError
from asvtwin.twin.recorder import METADATA_NAME

__all__ = ["SNAPSHOT_TOPIC", "Recording"]

#: Channel of the snapshot stream.
SNAPSHOT_TOPIC = "/twin/snapshot"


class Recording:
    """A recorded run (read-only).

    Parameters
    ----------
    path : path
        An ``.mcap`` file written by the twin's recorder.

    Raises
    ------
    SourceError
        The file cannot be read, is not MCAP, or holds no asvtwin run metadata.
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise SourceError(f"recording {self.path} does not exist (expected an .mcap file "
                              "written by 'asvtwin run')")
        self.truncated = False
        self.damage: str | None = None
        self._mem: dict[str, tuple[list[int], list[bytes]]] | None = None
        self._meta: dict[str, str] | None = None
        try:
            with open(self.path, "rb") as f:
                r = SeekingReader(f)
                summary = r.get_summary()
                if summary is None or not summary.chunk_indexes:
                    raise ValueError("no summary")
                self._meta = next((m.metadata for m in r.iter_metadata()
                                   if m.name == METADATA_NAME), None)
                self._start_ns = summary.statistics.message_start_time if summary.statistics else 0
                self._end_ns = summary.statistics.message_end_time if summary.statistics else 0
        except Exception:  # noqa: BLE001 - any failure means: read it as a stream
            self._read_stream()
        if self._meta is None:
            raise SourceError(f"{self.path} holds no {METADATA_NAME!r} metadata: not a "
                              "recording of 'asvtwin run' (or cut before its first chunk)")
        self.epoch_ns = round(float(self._meta.get("epoch_unix_s", "0")) * 1e9)
        self.metadata: dict[str, Any] = {
            "scenario": orjson.loads(self._meta["scenario"]) if self._meta.get("scenario") else None,
            "seed": int(self._meta.get("seed", "0")),
            "schema": self._meta.get("schema", ""),
            "epoch_unix_s": float(self._meta.get("epoch_unix_s", "0")),
        }
        self._summary: dict[str, Any] | None | bool = False

    # ------------------------------------------------------------------ reading
    def _read_stream(self) -> None:
        self.truncated = True
        mem: dict[str, tuple[list[int], list[bytes]]] = {}
        topics: dict[int, str] = {}
        try:
            with open(self.path, "rb") as f:
                try:
                    for rec in StreamReader(f, skip_magic=False).records:
                        if isinstance(rec, Channel):
                            topics[rec.id] = rec.topic
                        elif isinstance(rec, Message):
                            ts, data = mem.setdefault(topics.get(rec.channel_id, ""), ([], []))
                            ts.append(rec.log_time)
                            data.append(bytes(rec.data))
                        elif isinstance(rec, Metadata) and rec.name == METADATA_NAME:
                            self._meta = dict(rec.metadata)
                except Exception as exc:  # noqa: BLE001 - the damaged tail
                    self.damage = f"{type(exc).__name__}: {exc}".rstrip(": ")
        except OSError as exc:
            raise SourceError(f"cannot read recording {self.path}: {exc}") from exc
        for ts, data in mem.values():  # log-time order (chunks are written in time order)
            if any(b < a for a, b in itertools.pairwise(ts)):
                order = sorted(range(len(ts)), key=ts.__getitem__)
                ts[:] = [ts[i] for i in order]
                data[:] = [data[i] for i in order]
        self._mem = mem
        times = [t for ts, _ in mem.values() for t in ts]
        self._start_ns = min(times) if times else 0
        self._end_ns = max(times) if times else 0

    def _t(self, ns: int) -> float:
        return (ns - self.epoch_ns) / 1e9

    @property
    def seed(self) -> int:
        """The run's seed."""
        return int(self.metadata["seed"])

    @property
    def scenario(self) -> dict[str, Any] | None:
        """The scenario as plain JSON values."""
        return self.metadata["scenario"]  # type: ignore[no-any-return]

    @property
    def duration_s(self) -> float:
        """Time of the last snapshot [s] (simulation time)."""
        last = None
        for t, _ in self.iter_messages(start_s=max(0.0, self._t(self._end_ns) - 5.0)):
            last = t
        return float(last) if last is not None else 0.0

    @property
    def summary(self) -> dict[str, Any] | None:
        """The run summary written at the end (None when the file was cut short)."""
        if self._summary is False:
            self._summary = None
            for _, data in self.iter_messages(topic="/twin/summary"):
                self._summary = orjson.loads(data)
        return self._summary  # type: ignore[return-value]

    def iter_messages(self, start_s: float = 0.0, *, topic: str = SNAPSHOT_TOPIC,
                      end_s: float | None = None) -> Iterator[tuple[float, bytes]]:
        """``(t_s, message bytes)`` of ``topic`` from ``start_s`` on, in time order."""
        start_ns = self.epoch_ns + round(start_s * 1e9)
        end_ns = None if end_s is None else self.epoch_ns + round(end_s * 1e9)
        if self._mem is not None:
            ts, data = self._mem.get(topic, ([], []))
            i = bisect.bisect_left(ts, start_ns)
            for j in range(i, len(ts)):
                if end_ns is not None and ts[j] > end_ns:
                    return
                yield self._t(ts[j]), data[j]
            return
        with open(self.path, "rb") as f:
            r = SeekingReader(f)
            for _, _, msg in r.iter_messages(topics=[topic], starting_at=start_ns,
                                             ending_at=end_ns):
                yield self._t(msg.log_time), bytes(msg.data)

    def message_at(self, t_s: float, *, topic: str = SNAPSHOT_TOPIC) -> bytes:
        """The last ``topic`` message at or before ``t_s`` (the first one when ``t_s`` is
        before the start).

        Raises
        ------
        SourceError
            The recording holds no message on ``topic``.
        """
        window = 10.0
        t_s = max(float(t_s), self._t(self._start_ns))
        while True:
            last = None
            for _, data in self.iter_messages(max(0.0, t_s - window), topic=topic, end_s=t_s):
                last = data
            if last is not None:
                return last
            if t_s - window <= self._t(self._start_ns):
                for _, data in self.iter_messages(0.0, topic=topic):
                    return data
                raise SourceError(f"recording {self.path} has no {topic} messages")
            window *= 4.0
