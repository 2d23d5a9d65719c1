"""Closed-loop runs of the safety filter against adversarial, seeded scenarios.

A *naive controller* holds full thrust straight ahead; the scenario puts an obstacle, a
coastline or a crossing vessel on its path. :func:`run_closed_loop` simulates the own
ship on the project's simulator (thruster lag included), calling the filter every stage
(or not at all, for the unfiltered comparison). Used by the tests, the benchmark and
``asvtwin psf demo``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from asvtwin.checks import F8 as _F8
from asvtwin.control.obstacles import CircleObstacles, CoastSegments, MovingObstacles
from asvtwin.control.psf import FilterResult, SafetyFilter
from asvtwin.vessel.params import VesselParams
from asvtwin.vessel.simulator import VesselSimulator

__all__ = [
    "SCENARIO_KINDS",
    "ClosedLoopRun",
    "Scenario",
    "adversarial_scenario",
    "run_closed_loop",
]

SCENARIO_KINDS = ("obstacle", "coast", "crossing")


@dataclass(frozen=True)
class Scenario:
    """Own start state, static circles, coast segments and constant-velocity vessels."""

    kind: str
    x0: _F8
    circles: CircleObstacles
    coast: CoastSegments
    movers_p0: _F8 = field(default_factory=lambda: np.zeros((0, 2)))
    movers_v: _F8 = field(default_factory=lambda: np.zeros((0, 2)))
    movers_r: _F8 = field(default_factory=lambda: np.zeros(0))

    def movers_at(self, t_s: float) -> _F8:
        """Centres of the moving vessels at time ``t_s``, (m, 2) [m]."""
        return self.movers_p0 + t_s * self.movers_v

    def obstacles(self, t_s: float, N: int, dt_s: float) -> list:
        """What the filter sees at ``t_s``: ground-truth constant-velocity predictions."""
        out: list = [self.circles, self.coast]
        if len(self.movers_r):
            out.append(MovingObstacles.constant_velocity(
                self.movers_at(t_s), self.movers_v, self.movers_r, N=N, dt_s=dt_s))
        return out

    def clearance(self, xy: _F8, t_s: float) -> float:
        """Smallest distance from ``xy`` to any obstacle's edge [m] (< 0: inside)."""
        d: list[float] = [np.inf]
        if len(self.circles):
            d.append(float(np.min(np.linalg.norm(self.circles.centres - xy, axis=1)
                                  - self.circles.radii)))
        if len(self.coast):
            d.append(float(self.coast.distances(xy[None])[0].min()))
        if len(self.movers_r):
            d.append(float(np.min(np.linalg.norm(self.movers_at(t_s) - xy, axis=1)
                                  - self.movers_r)))
        return min(d)


def _time_to_reach(u0: float, dist: float) -> float:
    """Time [s] CyberShip II at full thrust from surge ``u0`` needs to cover ``dist``."""
    from asvtwin.vessel.params import cybership2

    sim = VesselSimulator(cybership2(), [0.0, 0.0, 0.0, u0, 0.0, 0.0], dt_s=0.1)
    t = 0.0
    while sim.state[0] < dist and t < 300.0:
        sim.step([2.0, 0.0, 0.0])
        t += 0.1
    return t


def adversarial_scenario(rng: np.random.Generator, kind: str | None = None,
                         *, n_clutter: int = 0) -> Scenario:
    """A scenario in which full thrust straight ahead ends in a collision.

    The own ship starts at the origin heading north at 0.2–0.5 m/s (model scale); the
    hazard lies 12–25 m ahead. ``n_clutter`` extra circles are scattered off the track.
    """
    kind = kind or str(rng.choice(SCENARIO_KINDS))
    u0 = rng.uniform(0.2, 0.5)
    x0 = np.array([0.0, 0.0, 0.0, u0, 0.0, 0.0])
    dist = rng.uniform(12.0, 25.0)
    centres = [np.zeros((0, 2))]
    radii = [np.zeros(0)]
    coast = np.zeros((0, 4))
    mp, mv, mr = np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0)
    if kind == "obstacle":
        r = rng.uniform(1.0, 4.0)
        centres.append(np.array([[dist + r, rng.uniform(-0.5, 0.5) * r]]))
        radii.append(np.array([r]))
    elif kind == "coast":
        ang = rng.uniform(-0.5, 0.5)  # shore line tilted up to ±29°
        t = np.array([np.sin(ang), np.cos(ang)])  # along-shore direction (n, e)
        c = np.array([dist, 0.0])
        coast = np.array([np.concatenate([c - 40 * t, c + 40 * t])])
    elif kind == "crossing":
        r = rng.uniform(1.0, 2.0)
        speed = rng.uniform(0.2, 0.4)
        side = rng.choice([-1.0, 1.0])
        t_meet = _time_to_reach(u0, dist)  # when the unfiltered own ship gets there
        mv = np.array([[0.0, -side * speed]])
        mp = np.array([[dist, side * speed * t_meet]])
        mr = np.array([r])
    else:
        raise ValueError(f"kind must be one of {SCENARIO_KINDS}, actually: {kind!r}")
    if n_clutter:
        bearings = rng.uniform(0, 2 * np.pi, n_clutter)
        rr = rng.uniform(8.0, 45.0, n_clutter)
        cc = np.stack([rr * np.cos(bearings), rr * np.sin(bearings)], axis=1)
        off = np.abs(cc[:, 1]) > 6.0  # keep the track itself for the hazard
        centres.append(cc[off])
        radii.append(rng.uniform(0.5, 2.0, n_clutter)[off])
    return Scenario(kind=kind, x0=x0,
                    circles=CircleObstacles(np.concatenate(centres), np.concatenate(radii)),
                    coast=CoastSegments(coast), movers_p0=mp, movers_v=mv, movers_r=mr)


@dataclass
class ClosedLoopRun:
    """Trajectory and filter outputs of one run."""

    t_s: _F8
    x: _F8
    u_applied: _F8
    clearance_m: _F8
    results: list[FilterResult]

    @property
    def min_clearance_m(self) -> float:
        return float(self.clearance_m.min())


def run_closed_loop(params: VesselParams, scenario: Scenario, psf: SafetyFilter | None, *,
                    duration_s: float = 60.0, u_L: _F8 | None = None,
                    sim_dt_s: float = 0.1,
                    mode: Literal["filtered", "unfiltered"] = "filtered") -> ClosedLoopRun:
    """Simulate the naive controller (``u_L``, default full thrust ahead) with or without
    the filter; the filter is called every stage (its ``dt_s``)."""
    u_L = np.array([params.actuators.tau_max[0], 0.0, 0.0]) if u_L is None else u_L
    dt = psf.config.dt_s if psf is not None else 0.5
    N = psf.config.N if psf is not None else 0
    per = max(1, round(dt / sim_dt_s))
    sim = VesselSimulator(params, scenario.x0, dt_s=dt / per)
    if psf is not None:
        psf.reset()
    ts, xs, us, cl, res = [], [], [], [], []
    x = scenario.x0.copy()
    for k in range(int(duration_s / dt)):
        t = k * dt
        if mode == "filtered" and psf is not None:
            r = psf.filter(x, u_L, scenario.obstacles(t, N, dt), t_s=t)
            u = r.u0
            res.append(r)
        else:
            u = u_L
        for j in range(per):
            x = sim.step(u)
            ts.append(t + (j + 1) * dt / per)
            xs.append(x)
            us.append(u)
            cl.append(scenario.clearance(x[:2], t + (j + 1) * dt / per))
    return ClosedLoopRun(t_s=np.asarray(ts), x=np.asarray(xs), u_applied=np.asarray(us),
                         clearance_m=np.asarray(cl), results=res)
