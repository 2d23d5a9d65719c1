"""What a log holds regardless of the twin's filters (``AisPipeline(census=True)``)."""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["LogCensus"]


@dataclass
class LogCensus:
    """Every MMSI and the time span of a log, counted before the scene and time filters.

    ``asvtwin ais stats`` summarises a whole log with it: a log summary counts all messages,
    all MMSIs and the full time span, whatever the scene box keeps.

    Attributes
    ----------
    mmsis : set of int
        The MMSI of every assembled message with a checksum-valid sentence, of any type.
    t_first_unix_s, t_last_unix_s : float or None
        Earliest and latest plausible (2000..2100) tag-block time of any checksum-valid line.
    timed_lines, untimed_lines : int
        Checksum-valid sentences with and without a tag-block time.
    """

    mmsis: set[int] = field(default_factory=set)
    t_first_unix_s: float | None = None
    t_last_unix_s: float | None = None
    timed_lines: int = 0
    untimed_lines: int = 0

    def see_time(self, t: float) -> None:
        """Count one line with the plausible time ``t`` [UNIX s]."""
        self.timed_lines += 1
        if self.t_first_unix_s is None or t < self.t_first_unix_s:
            self.t_first_unix_s = t
        if self.t_last_unix_s is None or t > self.t_last_unix_s:
            self.t_last_unix_s = t
