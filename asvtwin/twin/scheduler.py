"""Components at their own rates, timed, with their failures isolated.

The runtime owns one :class:`Scheduler`. Each component (AIS, LiDAR, tracker, observer,
controller, filter, ...) is registered with a period [s of simulation time]; at every tick
:meth:`Scheduler.due` says whether it runs and :meth:`Scheduler.call` runs it:

- the call is timed with the twin's :class:`~asvtwin.twin.clock.Clock` (no other clock);
- an exception is caught, counted, its message kept (``last_error``) and logged once per
  component; the call returns the fallback value the runtime gave, so the loop goes on;
- in a paced run (real time or ×N) a call longer than the component's wall-time budget
  is an *overrun*, counted; a component that overruns ``backoff_after`` times in a row
  has its period doubled (up to ×8) so it stops stalling the loop, and its status shows
  ``degraded``; a ``max``-speed run has no deadline, so nothing is an overrun, nothing
  is stretched and the run stays deterministic;
- after ``fail_after`` errors in a row the component is ``failed``: it is not called any
  more and the runtime uses its fallback (the summary names it).

Health is exported as :class:`~asvtwin.twin.snapshot.ComponentHealth` values.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, TypeVar

from asvtwin.errors import ConfigError
from asvtwin.twin.clock import Clock
from asvtwin.twin.snapshot import ComponentHealth

__all__ = ["ComponentStats", "Scheduler"]

_log = logging.getLogger(__name__)
T = TypeVar("T")

_EPS = 1e-9


@dataclass
class ComponentStats:
    """Mutable bookkeeping of one component (the scheduler's; exported as health)."""

    name: str
    period_s: float
    budget_ms: float
    next_t_s: float = 0.0
    stretch: int = 1
    calls: int = 0
    errors: int = 0
    errors_in_row: int = 0
    overruns: int = 0
    overruns_in_row: int = 0
    total_ms: float = 0.0
    last_ms: float = 0.0
    max_ms: float = 0.0
    last_error: str | None = None
    failed: bool = False
    logged: bool = False
    notes: list[str] = field(default_factory=list)

    @property
    def mean_ms(self) -> float:
        return self.total_ms / self.calls if self.calls else 0.0

    @property
    def status(self) -> str:
        if self.failed:
            return "failed"
        return "degraded" if (self.errors or self.overruns or self.notes) else "ok"

    def health(self) -> ComponentHealth:
        return ComponentHealth(
            name=self.name, period_s=self.period_s * self.stretch, calls=self.calls,
            errors=self.errors, overruns=self.overruns, last_ms=self.last_ms,
            mean_ms=self.mean_ms, max_ms=self.max_ms,
            last_error=self.last_error if self.last_error else
            (self.notes[-1] if self.notes else None),
            status=self.status)


class Scheduler:
    """Periods, timing and failure isolation of the twin's components.

    Parameters
    ----------
    clock : Clock
        The twin's clock (timings and whether the run is paced).
    fail_after : int
        Consecutive errors after which a component is marked failed and no longer called.
    backoff_after : int
        Consecutive overruns (paced runs only) after which a component's period doubles.
    """

    def __init__(self, clock: Clock, *, fail_after: int = 50, backoff_after: int = 3) -> None:
        self.clock = clock
        self.fail_after = int(fail_after)
        self.backoff_after = int(backoff_after)
        self._c: dict[str, ComponentStats] = {}

    def add(self, name: str, period_s: float, *, budget_ms: float | None = None,
            first_t_s: float = 0.0) -> None:
        """Register ``name`` to run every ``period_s`` seconds of simulation time (0: every
        tick); ``budget_ms`` of wall time per call (default: the period, i.e. real time)."""
        if not (math.isfinite(period_s) and period_s >= 0):
            raise ConfigError(f"period of component {name!r} must be finite and >= 0 s, "
                              f"actually: {period_s}")
        budget = budget_ms if budget_ms is not None else max(period_s, 0.05) * 1e3
        self._c[name] = ComponentStats(name, float(period_s), float(budget),
                                       next_t_s=float(first_t_s))

    def __contains__(self, name: str) -> bool:
        return name in self._c

    def stats(self, name: str) -> ComponentStats:
        """The bookkeeping of ``name``."""
        return self._c[name]

    def due(self, name: str, t_s: float) -> bool:
        """Whether ``name`` runs at tick time ``t_s`` (and is not failed)."""
        c = self._c[name]
        return not c.failed and t_s + _EPS >= c.next_t_s

    def note(self, name: str, message: str) -> None:
        """Record a degradation that is not an exception (a dead feed, a full disk)."""
        c = self._c[name]
        if not c.notes or c.notes[-1] != message:
            c.notes.append(message)
            _log.warning("%s: %s", name, message)

    def call(self, name: str, tick_t_s: float, fn: Callable[..., T], *args: Any,
             fallback: T | None = None, **kwargs: Any) -> tuple[bool, T | None]:
        """Run ``fn(*args, **kwargs)`` as component ``name`` at tick time ``tick_t_s``.

        Returns ``(True, result)``, or ``(False, fallback)`` when it raised (the error is
        counted and kept). The next due time advances by the (possibly stretched) period.
        """
        c = self._c[name]
        t_s = tick_t_s
        step = c.period_s * c.stretch
        c.next_t_s = t_s + step if step > 0 else t_s
        t0 = self.clock.perf()
        ok = True
        out: T | None
        try:
            out = fn(*args, **kwargs)
        except Exception as exc:  # noqa: BLE001 - isolation is the point
            ok, out = False, fallback
            c.errors += 1
            c.errors_in_row += 1
            c.last_error = f"t={t_s:.2f} s: {type(exc).__name__}: {exc}"
            if not c.logged:
                c.logged = True
                _log.warning("component %s raised at t=%.2f s (isolated; further errors are "
                             "counted, not logged): %s", name, t_s, exc, exc_info=exc)
            if c.errors_in_row >= self.fail_after:
                c.failed = True
                _log.error("component %s failed %d times in a row; it is disabled",
                           name, c.errors_in_row)
        else:
            c.errors_in_row = 0
        ms = (self.clock.perf() - t0) * 1e3
        c.calls += 1
        c.last_ms = ms
        c.total_ms += ms
        c.max_ms = max(c.max_ms, ms)
        paced = self.clock.speed != "max" and not self.clock.paused
        if paced and ms > c.budget_ms:
            c.overruns += 1
            c.overruns_in_row += 1
            if c.overruns_in_row >= self.backoff_after and c.stretch < 8:
                c.stretch *= 2
                c.overruns_in_row = 0
                c.next_t_s = t_s + c.period_s * c.stretch
                self.note(name, f"overran its {c.budget_ms:.0f} ms budget "
                                f"{self.backoff_after} times in a row; period stretched "
                                f"to {c.period_s * c.stretch:g} s")
        else:
            c.overruns_in_row = 0
        return ok, out

    def health(self) -> tuple[ComponentHealth, ...]:
        """Every component's health, in registration order."""
        return tuple(c.health() for c in self._c.values())

    def ms_per_tick(self, ticks: int) -> dict[str, float]:
        """Mean wall time per tick of each component over ``ticks`` ticks [ms]."""
        return {n: (c.total_ms / ticks if ticks else 0.0) for n, c in self._c.items()}

    def degradations(self) -> list[str]:
        """A sentence per component that was not healthy."""
        out = []
        for c in self._c.values():
            if c.status == "ok":
                continue
            parts = []
            if c.errors:
                parts.append(f"{c.errors} error(s), last: {c.last_error}")
            if c.overruns:
                parts.append(f"{c.overruns} overrun(s) of {c.budget_ms:.0f} ms")
            parts.extend(c.notes)
            state = "failed and disabled" if c.failed else "degraded"
            out.append(f"{c.name} {state}: " + "; ".join(parts))
        return out
