"""The twin's clock: the one object that reads the system clock.

Simulation time advances in fixed ticks owned by the runtime; the clock decides *when* the
next tick may run in wall time:

- ``max`` — as fast as possible (no waiting; headless studies, the benchmark);
- ``realtime`` — one simulated second per wall second;
- ``scaled`` — ``speed`` simulated seconds per wall second (×N);
- paused — no tick runs until :meth:`Clock.resume` or a single step (:meth:`Clock.step`).

Every wall-time reading of the package goes through :meth:`Clock.perf` (component timings,
pacing) so a test can drive a :class:`Clock` with a fake time source and a fake sleep. The
controls (:meth:`pause`, :meth:`resume`, :meth:`set_speed`, :meth:`step`) are thread-safe:
the server calls them from its event loop while the runtime waits in :meth:`wait_for_tick`.

When a paced run falls behind (a slow tick, a machine under load) by more than
``max_lag_s`` of wall time, the clock re-anchors instead of racing to catch up, and counts
it in :attr:`Clock.lag_resets`.

Examples
--------
>>> t = [0.0]
>>> clock = Clock("realtime", time_source=lambda: t[0], sleep=lambda s: t.__setitem__(0, t[0] + s))
>>> clock.wait_for_tick(0.0), clock.wait_for_tick(0.5), t[0]   # waits half a second
(True, True, 0.5)
>>> clock.set_speed("max"); clock.state().mode
'max'
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from datetime import UTC, datetime, timedelta

from asvtwin.errors import ConfigError
from asvtwin.twin.snapshot import ClockState

__all__ = ["CLOCK_MODES", "Clock", "parse_speed"]

#: Modes a clock starts in (``paused`` is a flag on top of any of them).
CLOCK_MODES = ("max", "realtime", "scaled")


def parse_speed(value: float | str) -> float | str:
    """``"max"``, or a speed factor > 0 (``"10"``, ``"x10"``, ``10.0``; ``"realtime"`` is 1)
    as a float.

    Raises
    ------
    ConfigError
        Anything else, naming the allowed values.
    """
    if isinstance(value, str):
        v = value.strip().lower()
        if v in ("max", "inf", "fast"):
            return "max"
        if v in ("realtime", "real-time", "real time"):
            return 1.0
        v = v.removeprefix("x").removesuffix("x")
        try:
            value = float(v)
        except ValueError:
            raise ConfigError(f"speed must be 'max' or a factor > 0 (e.g. 1, 10, x50), "
                              f"actually: {value!r}") from None
    f = float(value)
    if math.isinf(f) and f > 0:
        return "max"
    if not (math.isfinite(f) and 0.0 < f <= 1e6):
        raise ConfigError(f"speed must be 'max' or a factor in (0, 1e6], actually: {value!r}")
    return f


class Clock:
    """Wall-time pacing of the simulation, thread-safe.

    Parameters
    ----------
    speed : float or "max"
        Simulated seconds per wall second (1 = real time), or ``"max"``.
    paused : bool
        Start paused (ticks run only on :meth:`step`).
    start_time_utc : datetime, optional
        The wall-clock (UTC) time of simulation time 0, reported in :meth:`state`.
    max_lag_s : float
        Wall seconds behind schedule after which the clock re-anchors [s].
    time_source : callable, optional
        Monotonic seconds; :func:`time.perf_counter` by default (tests pass a fake).
    sleep : callable, optional
        Sleeps that many seconds; :func:`time.sleep` by default. The runtime wakes up at
        least every ``poll_s`` to see control changes.
    """

    def __init__(self, speed: float | str = "max", *, paused: bool = False,
                 start_time_utc: datetime | None = None, max_lag_s: float = 1.0,
                 time_source: Callable[[], float] | None = None,
                 sleep: Callable[[float], None] | None = None, poll_s: float = 0.05) -> None:
        self._perf = time_source or time.perf_counter
        self._sleep = sleep
        self._cond = threading.Condition()
        self._speed: float | str = parse_speed(speed)
        self._paused = bool(paused)
        self._steps = 0
        self._anchor: tuple[float, float] | None = None  # (wall, sim)
        self.start_time_utc = start_time_utc
        self.max_lag_s = float(max_lag_s)
        self.poll_s = float(poll_s)
        self.lag_resets = 0
        self._stopped = False

    # ------------------------------------------------------------------ readings
    def perf(self) -> float:
        """Monotonic wall time [s] (the only reading of the system clock)."""
        return self._perf()

    def now_utc(self) -> datetime:
        """The current wall-clock time, UTC (for edges that need one: live feeds)."""
        return datetime.now(UTC)

    @property
    def speed(self) -> float | str:
        """Current speed factor, or ``"max"``."""
        return self._speed

    @property
    def paused(self) -> bool:
        """Whether ticks wait for :meth:`resume` or :meth:`step`."""
        return self._paused

    def state(self, t_s: float | None = None) -> ClockState:
        """The clock as the snapshot shows it (wall time of ``t_s`` when known)."""
        sp = self._speed
        mode = ("step" if self._paused else "max" if sp == "max"
                else "realtime" if sp == 1.0 else "scaled")
        wall = None
        if self.start_time_utc is not None and t_s is not None:
            wall = (self.start_time_utc + timedelta(seconds=float(t_s))).isoformat()
        return ClockState(mode=mode, speed=float("inf") if sp == "max" else float(sp),
                          paused=self._paused, wall_utc=wall)

    # ------------------------------------------------------------------ controls
    def pause(self) -> None:
        """Stop ticking after the current tick."""
        with self._cond:
            self._paused = True
            self._anchor = None
            self._cond.notify_all()

    def resume(self) -> None:
        """Continue at the current speed (re-anchored: no catching up the pause)."""
        with self._cond:
            self._paused = False
            self._anchor = None
            self._cond.notify_all()

    def set_speed(self, speed: float | str) -> None:
        """Change the speed factor (or ``"max"``); takes effect at the next tick."""
        sp = parse_speed(speed)
        with self._cond:
            self._speed = sp
            self._anchor = None
            self._cond.notify_all()

    def step(self, n_ticks: int = 1) -> None:
        """Allow ``n_ticks`` more ticks while paused (single-stepping)."""
        if int(n_ticks) < 1:
            raise ConfigError(f"n_ticks must be >= 1, actually: {n_ticks}")
        with self._cond:
            self._steps += int(n_ticks)
            self._cond.notify_all()

    def start(self) -> None:
        """Undo :meth:`stop`: ticks may run again."""
        with self._cond:
            self._stopped = False
            self._anchor = None

    def stop(self) -> None:
        """Wake any waiting :meth:`wait_for_tick` and make it return False."""
        with self._cond:
            self._stopped = True
            self._cond.notify_all()

    @property
    def stopped(self) -> bool:
        """Whether :meth:`stop` was called (and not undone by :meth:`start`)."""
        return self._stopped

    def wait_while_paused(self, timeout_s: float | None = None) -> None:
        """Block while paused with no step pending, at most ``timeout_s`` (``poll_s`` by
        default); return at once when running, stepping or stopped."""
        with self._cond:
            if self._paused and self._steps == 0 and not self._stopped:
                self._cond.wait(timeout=self.poll_s if timeout_s is None else timeout_s)

    # ------------------------------------------------------------------ pacing
    def _sleep_for(self, s: float) -> None:
        if self._sleep is not None:
            self._sleep(s)
        else:
            with self._cond:
                self._cond.wait(timeout=s)

    def wait_for_tick(self, t_s: float, *, block: bool = True) -> bool:
        """Wait until the tick at simulation time ``t_s`` may run.

        Returns True when it may run, False when paused with no step pending and
        ``block`` is False, or when :meth:`stop` was called.
        """
        while True:
            with self._cond:
                if self._stopped:
                    return False
                if self._paused:
                    if self._steps > 0:
                        self._steps -= 1
                        return True
                    if not block:
                        return False
                    self._cond.wait(timeout=self.poll_s)
                    continue
                sp = self._speed
                if sp == "max":
                    return True
                now = self._perf()
                if self._anchor is None:
                    self._anchor = (now, t_s)
                    return True
                w0, s0 = self._anchor
                due = w0 + (t_s - s0) / float(sp)
                late = now - due
                if late >= 0.0:
                    if late > self.max_lag_s:
                        self._anchor = (now, t_s)
                        self.lag_resets += 1
                    return True
                wait = min(-late, self.poll_s)
            self._sleep_for(wait)
