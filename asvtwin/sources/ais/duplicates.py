"""Stage 3 of the AIS pipeline: one transmission heard by two base stations is one report.

The national feed relays what several base stations hear, so a vessel's report arrives two or
three times within a second or two. :class:`DuplicateFilter` drops a payload seen again within
``window_s`` of its first reception. Memory stays bounded: payloads older than twice the
window behind the latest accepted report time are forgotten at the end of every batch
(:meth:`DuplicateFilter.trim`), and the test in :meth:`DuplicateFilter.is_duplicate` ignores
exactly those, so the result does not depend on how a stream is cut into batches.
"""

from __future__ import annotations

__all__ = ["DuplicateFilter"]


class DuplicateFilter:
    """Remember payloads and their first reception time [UNIX s] (a dict in time order).

    Parameters
    ----------
    window_s : float
        Identical payloads closer than this are one transmission heard twice [s].
    max_payloads : int
        A pathological feed (times far apart, nothing ever expires) starts afresh beyond this.
    """

    def __init__(self, window_s: float, *, max_payloads: int = 200_000) -> None:
        self.window_s = float(window_s)
        self.max_payloads = int(max_payloads)
        self.seen: dict[bytes, float] = {}

    def __len__(self) -> int:
        return len(self.seen)

    def is_duplicate(self, payload: bytes, t: float, hwm: float | None) -> float | None:
        """The earlier reception time if ``payload`` at ``t`` repeats one, else None (and
        ``payload`` is remembered at ``t``). ``hwm`` is the latest accepted report time."""
        seen = self.seen
        prev = seen.get(payload)
        if prev is not None:
            if abs(t - prev) <= self.window_s and (hwm is None or prev >= hwm - 2 * self.window_s):
                return prev
            del seen[payload]  # re-insert at the end: the dict stays in time order
        seen[payload] = t
        return None

    def trim(self, hwm: float | None) -> None:
        """Forget payloads older than ``hwm - 2 window_s``."""
        seen = self.seen
        if hwm is None or not seen:
            return
        oldest = hwm - 2 * self.window_s
        # one pass, then delete: next(iter(seen)) after each deletion would rescan the freed
        # slots at the front of the dict every time (quadratic in the payloads per batch)
        stale = []
        for payload, t in seen.items():
            if t >= oldest:
                break
            stale.append(payload)
        for payload in stale:
            del seen[payload]
        if len(seen) > self.max_payloads:
            seen.clear()
