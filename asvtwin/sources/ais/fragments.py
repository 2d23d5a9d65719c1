"""Assembly of multi-sentence AIS messages, with a timeout enforced on every line.

pyais's own streams assemble fragments but drop broken ones silently and key them without the
receiving station, so the pipeline uses this small assembler. Fragments are keyed by
*(station, talker, channel, sequence id, fragment count)*: messages from two stations
interleave safely. What cannot be completed is counted, never decoded:

- a later fragment without its first one: ``orphan_fragment``;
- a fragment number that skips or repeats: ``out_of_order_fragment``;
- a message not completed within ``timeout_s`` of its first fragment, replaced by a new first
  fragment under the same key, pushed out by ``max_pending``, or still waiting when the stream
  ends (:meth:`FragmentAssembler.flush`): ``incomplete_fragment``.

The timeout is checked on every line that carries a time (:meth:`FragmentAssembler.expire`),
not only when a new message starts: a second fragment arriving 60 s late is an orphan, and
the halves of two vessels' messages that share a sequence id are never joined.
"""

from __future__ import annotations

import math

from pyais.messages import AISSentence

from asvtwin.sources.ais.counters import ErrorCounter, ErrorKind

__all__ = ["FragmentAssembler"]

_Key = tuple[object, ...]


class FragmentAssembler:
    """Collect fragments until their message is complete.

    Parameters
    ----------
    counters : ErrorCounter
        Where failures are counted.
    timeout_s : float
        Longest time between the first and the last fragment of a message [s].
    max_pending : int
        Most messages assembled at once (the oldest is dropped beyond).
    """

    def __init__(self, counters: ErrorCounter, *, timeout_s: float, max_pending: int) -> None:
        self.counters = counters
        self.timeout_s = float(timeout_s)
        self.max_pending = int(max_pending)
        self._pending: dict[_Key, tuple[list[AISSentence], float | None, str | None]] = {}
        #: no pending message times out before this time [UNIX s] (a lower bound: may be stale
        #: low after completions; :meth:`expire` then finds nothing and recomputes it)
        self.deadline = math.inf

    def __len__(self) -> int:
        return len(self._pending)

    def add(self, msg: AISSentence, t: float | None, station: str | None, raw: bytes
            ) -> tuple[AISSentence, float | None, str | None] | None:
        """Take one fragment; return ``(message, time of fragment 1, station)`` when complete."""
        key = (station, msg.talker_id, msg.channel, msg.seq_id, msg.frag_cnt)
        pending = self._pending
        count = self.counters.count
        if msg.frag_num == 1:
            if key in pending:
                del pending[key]
                count(ErrorKind.INCOMPLETE_FRAGMENT, raw,
                      "a new message started before the last one with the same sequence id "
                      "completed")
            elif len(pending) >= self.max_pending:
                pending.pop(next(iter(pending)))
                count(ErrorKind.INCOMPLETE_FRAGMENT, raw,
                      f"more than {self.max_pending} messages waiting for fragments")
            pending[key] = ([msg], t, station)
            if t is not None and t + self.timeout_s < self.deadline:
                self.deadline = t + self.timeout_s
            return None
        entry = pending.get(key)
        if entry is None:
            count(ErrorKind.ORPHAN_FRAGMENT, raw,
                  f"fragment {msg.frag_num}/{msg.frag_cnt} without fragment 1 (lost, or timed "
                  f"out after {self.timeout_s:g} s)")
            return None
        parts, t0, st0 = entry
        if msg.frag_num != len(parts) + 1:
            del pending[key]
            count(ErrorKind.OUT_OF_ORDER_FRAGMENT, raw,
                  f"fragment {len(parts) + 1} expected, actually {msg.frag_num}/{msg.frag_cnt}")
            return None
        parts.append(msg)
        if len(parts) < msg.frag_cnt:
            return None
        del pending[key]
        return AISSentence.assemble_from_iterable(parts), (t0 if t0 is not None else t), st0

    def expire(self, t: float) -> int:
        """Drop (and count) the messages whose first fragment is older than ``t - timeout_s``."""
        limit = t - self.timeout_s
        pending = self._pending
        old = [k for k, (_, t0, _) in pending.items() if t0 is not None and t0 < limit]
        for k in old:
            n = len(pending.pop(k)[0])
            self.counters.count(ErrorKind.INCOMPLETE_FRAGMENT, None,
                                f"{n} of {k[-1]} fragments, not completed within "
                                f"{self.timeout_s:g} s")
        times = [t0 for _, t0, _ in pending.values() if t0 is not None]
        self.deadline = min(times) + self.timeout_s if times else math.inf
        return len(old)

    def flush(self) -> int:
        """End of stream: count every message still waiting as incomplete; return how many."""
        n = len(self._pending)
        for _ in range(n):
            self.counters.count(ErrorKind.INCOMPLETE_FRAGMENT, None,
                                "the stream ended before the message completed")
        self._pending.clear()
        self.deadline = math.inf
        return n
