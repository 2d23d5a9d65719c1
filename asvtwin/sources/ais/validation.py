"""Stage 5 of the AIS pipeline: is a decoded report true enough to enter the picture?

Checks, in order, each failure counted under its own
:class:`~asvtwin.sources.ais.counters.ErrorKind`:

- identity: MMSI in 1..999 999 999 (``invalid_mmsi``);
- time: present (``missing_time``, unless the pipeline accepts untimed logs) and plausible,
  2000..2100 (``invalid_time``);
- position: available (lat 91 / lon 181: ``position_unavailable``), valid
  (``invalid_position``) and inside the scene box (``outside_scene``, or kept with the notice
  ``outside_scene_kept``);
- time order: not more than ``lead`` ahead of the reference (the receive clock, or the robust
  stream time, which no single report moves: ``time_future``), not behind the MMSI's last
  accepted report (``time_backwards``); far behind the receive clock is kept and counted as
  the notice ``feed_clock_lags`` (the feed's clock, not the report, is wrong).
"""

from __future__ import annotations

import math

from asvtwin.geo import GeoBounds
from asvtwin.sources.ais.counters import ErrorCounter, ErrorKind, NoticeKind
from asvtwin.sources.ais.timebase import T_MAX_UNIX_S, T_MIN_UNIX_S, StreamClock

__all__ = ["ReportValidator", "TimeReference"]


class TimeReference:
    """What "in the future" and "lagging" mean during one batch (the pipeline updates it).

    Attributes
    ----------
    clock_now : float or None
        The receive clock read for this batch [UNIX s], None without a clock.
    ref : float or None
        Reference time [UNIX s]: ``clock_now``, or the robust stream time.
    lead : float
        Allowed lead over ``ref`` [s].
    lag_limit : float
        Reports older than this are counted as a lagging feed clock [UNIX s].
    hwm : float or None
        Latest accepted report time [UNIX s].
    """

    __slots__ = ("clock_now", "hwm", "lag_limit", "lead", "ref")

    def __init__(self, clock_now: float | None, ref: float | None, lead: float,
                 lag_limit: float, hwm: float | None) -> None:
        self.clock_now = clock_now
        self.ref = ref
        self.lead = lead
        self.lag_limit = lag_limit
        self.hwm = hwm


class ReportValidator:
    """Checks decoded reports and keeps each MMSI's last accepted report time.

    Parameters
    ----------
    box : GeoBounds
        The scene's latitude/longitude box [deg].
    counters, notices : ErrorCounter
        Where rejections and accepted quirks are counted.
    stream_clock : StreamClock
        The stream's robust time (recomputed before a report is called "in the future").
    bounds : bool
        Reject positions outside the box (else keep them with a notice).
    require_time : bool
        Reject reports without a time (else accept them untimed, no time checks).
    max_tracked_mmsi : int
        Most MMSIs whose last report time is kept (the oldest half is forgotten beyond).
    """

    def __init__(self, box: GeoBounds, counters: ErrorCounter, notices: ErrorCounter,
                 stream_clock: StreamClock, *, bounds: bool, require_time: bool,
                 max_tracked_mmsi: int) -> None:
        self.box = (box.lat_min_deg, box.lat_max_deg, box.lon_min_deg, box.lon_max_deg)
        self.counters = counters
        self.notices = notices
        self.stream_clock = stream_clock
        self.bounds = bool(bounds)
        self.require_time = bool(require_time)
        self.max_tracked = int(max_tracked_mmsi)
        self.last_t: dict[int, float] = {}

    def identity_and_time(self, raw: bytes, mmsi: int, t: float | None) -> float | None:
        """5a. MMSI range and a plausible time: the report's time (NaN when it has none and
        none is required), or None when rejected (counted)."""
        if not 0 < mmsi <= 999_999_999:
            self.counters.count(ErrorKind.INVALID_MMSI, raw,
                                f"MMSI in 1..999999999 expected, actually {mmsi}")
            return None
        if t is None:
            if self.require_time:
                self.counters.count(ErrorKind.MISSING_TIME, raw,
                                    "no tag block c: and no receive time")
                return None
            self.notices.count(NoticeKind.UNTIMED, raw, "no time: accepted without time checks")
            return math.nan
        if not T_MIN_UNIX_S <= t <= T_MAX_UNIX_S:
            self.counters.count(ErrorKind.INVALID_TIME, raw,
                                f"time in 2000..2100 expected, actually {t}")
            return None
        return t

    def position(self, run: TimeReference, raw: bytes, mmsi: int, t: float, lat: float,
                  lon: float) -> bool:
        """5b. Position available, valid and in the scene; time in order and not ahead of
        the clock or the stream. True when accepted (the MMSI's last time updated)."""
        lat_lo, lat_hi, lon_lo, lon_hi = self.box
        # inside the scene's box (the usual case) is valid and available; outside it, why
        if not (lat_lo <= lat <= lat_hi and lon_lo <= lon <= lon_hi):
            count = self.counters.count
            if lat == 91.0 or lon == 181.0:
                count(ErrorKind.POSITION_UNAVAILABLE, raw, f"lat {lat}, lon {lon}")
                return False
            if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
                count(ErrorKind.INVALID_POSITION, raw, "lat in [-90, 90] and lon in "
                      f"[-180, 180] expected, actually {lat}, {lon}")
                return False
            if self.bounds:
                count(ErrorKind.OUTSIDE_SCENE, raw, f"lat {lat_lo}..{lat_hi}, lon "
                      f"{lon_lo}..{lon_hi} expected, actually {lat}, {lon}")
                return False
            self.notices.count(NoticeKind.OUTSIDE_SCENE_KEPT, raw, "outside the scene box, kept")
        if math.isnan(t):  # untimed: no time checks
            return True
        ref = run.ref
        if ref is not None and t > ref + run.lead:
            if run.clock_now is None:
                ref = run.ref = self.stream_clock.update()  # recompute (quiet feeds)
            if ref is not None and t > ref + run.lead:
                src = "receive clock" if run.clock_now is not None else "stream time"
                self.counters.count(ErrorKind.TIME_FUTURE, raw,
                                    f"time <= {ref + run.lead:.0f} expected "
                                    f"({src} + {run.lead:g} s), actually {t:.0f}")
                return False
        last = self.last_t.get(mmsi)
        if last is not None and t < last:
            self.counters.count(ErrorKind.TIME_BACKWARDS, raw, f"time >= {last:.3f} (last "
                                f"report of {mmsi}) expected, actually {t:.3f}")
            return False
        if t < run.lag_limit:
            self.notices.count(NoticeKind.CLOCK_LAG, raw,
                               f"{run.clock_now - t:.0f} s behind the receive "  # type: ignore[operator]
                               "clock")
        self.last_t[mmsi] = t
        if run.hwm is None or t > run.hwm:
            run.hwm = t
        return True

    def trim(self) -> None:
        """Forget the MMSIs heard longest ago (keeps memory bounded under MMSI churn)."""
        if len(self.last_t) > self.max_tracked:
            items = sorted(self.last_t.items(), key=lambda kv: kv[1])
            self.last_t = dict(items[len(items) // 2:])
