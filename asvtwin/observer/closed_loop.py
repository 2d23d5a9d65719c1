"""Closed loop of the safety filter fed by the disturbance observer.

The own ship (CyberShip II by default) is pushed by a steady ocean current; a naive
controller ``u_L`` (full thrust straight ahead) drives it, and the predictive safety
filter (:class:`asvtwin.control.SafetyFilter`) corrects ``u_L`` every stage. Two ways to
run the filter are compared on the same seeded scenario:

- ``use_observer=True``: the filter's model gets d̂ from a :class:`DisturbanceObserver`
  fed with the *measured* ν (seeded white noise) and the thrust the actuators applied;
- ``use_observer=False``: ``d_hat=None``, the filter believes the water is still.

The plant is the project's simulator (thruster lag included) with the true current force
τ_d = n(ν) − n(ν − ν_c) (:func:`asvtwin.environment.current_force`) recomputed every
simulator step. Before the episode the vessel sails for ``preroll_s`` in the same current
with no obstacle in reach (its position then reset to the scenario's start, velocity and
thrust kept): the observer is in steady state, as on a vessel that has been under way.

:func:`current_scenario` builds the hazards: a coast or a rock ahead, with a following
current setting the ship onto it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from asvtwin.checks import F8 as _F8
from asvtwin.control.closed_loop import Scenario
from asvtwin.control.obstacles import CircleObstacles, CoastSegments
from asvtwin.control.psf import FilterResult, SafetyFilter
from asvtwin.environment import current_force
from asvtwin.errors import ParameterError
from asvtwin.guidance import AutopilotGains, HeadingSpeedAutopilot
from asvtwin.observer.disturbance import DisturbanceObserver, ObserverGains
from asvtwin.observer.runs import SensorNoise
from asvtwin.vessel import BatchSimulator, VesselParams

__all__ = [
    "CURRENT_KINDS",
    "CurrentRun",
    "CurrentScenario",
    "current_scenario",
    "naive_autopilot",
    "run_with_current",
]

CURRENT_KINDS = ("coast_ahead", "rock_ahead")


@dataclass(frozen=True)
class CurrentScenario:
    """A :class:`~asvtwin.control.closed_loop.Scenario` plus the steady current.

    Attributes
    ----------
    scenario : Scenario
        Start state and hazards (model scale, NED).
    current_ned_m_s : ndarray, shape (2,)
        Current velocity over ground [V_N, V_E] [m/s].
    """

    scenario: Scenario
    current_ned_m_s: _F8

    @property
    def speed_m_s(self) -> float:
        """Current speed [m/s]."""
        return float(np.hypot(*self.current_ned_m_s))


def current_scenario(rng: np.random.Generator, kind: str, *,
                     speed_m_s: tuple[float, float] = (0.06, 0.09)) -> CurrentScenario:
    """A seeded hazard ahead with a following current setting the own ship onto it.

    Model scale. The own ship starts at the origin heading north (ψ = 0); the current
    flows within ±15° of north (from astern: the naive autopilot can hold its heading in
    it, see docs/observer.md), at a speed drawn from ``speed_m_s`` [m/s] (default
    0.06-0.09 m/s: 0.5-0.75 m/s, 1-1.5 kn, at full scale by Froude scaling ×√70, a
    strong tidal current; 10-15 % of CyberShip II's top speed). ``kind``:

    - ``"coast_ahead"``: an 80 m shore line 14–20 m ahead, tilted up to ±29°;
    - ``"rock_ahead"``: a rock of radius 1.5–3 m whose edge is 14–20 m ahead, off the
      track by up to half its radius.
    """
    lo, hi = speed_m_s
    if not (0.0 <= lo <= hi and math.isfinite(hi)):
        raise ParameterError(f"speed_m_s must be 0 <= low <= high [m/s], actually: "
                             f"{speed_m_s}")
    speed = rng.uniform(lo, hi)
    x0 = np.array([0.0, 0.0, 0.0, 0.4, 0.0, 0.0])
    circles = CircleObstacles(np.zeros((0, 2)), np.zeros(0))
    coast = np.zeros((0, 4))
    dist = rng.uniform(14.0, 20.0)
    if kind == "coast_ahead":
        ang = rng.uniform(-0.5, 0.5)
        along = np.array([np.sin(ang), np.cos(ang)])  # shore direction (n, e)
        c = np.array([dist, 0.0])
        coast = np.array([np.concatenate([c - 40 * along, c + 40 * along])])
    elif kind == "rock_ahead":
        r = rng.uniform(1.5, 3.0)
        circles = CircleObstacles(np.array([[dist + r, rng.uniform(-0.5, 0.5) * r]]),
                                  np.array([r]))
    else:
        raise ParameterError(f"kind must be one of {CURRENT_KINDS}, actually: {kind!r}")
    beta = rng.uniform(-math.radians(15.0), math.radians(15.0))
    vc = speed * np.array([math.cos(beta), math.sin(beta)])
    scene = Scenario(kind=kind, x0=x0, circles=circles, coast=CoastSegments(coast))
    return CurrentScenario(scenario=scene, current_ned_m_s=vc)


@dataclass
class CurrentRun:
    """One closed loop: trajectory, true and estimated disturbance, filter outputs.

    Attributes
    ----------
    t_s, x, clearance_m : ndarrays (T,), (T, 6), (T,)
        Simulator samples after the pre-roll [s, state, m].
    tau_d, d_hat : ndarrays (T, 3)
        True current force and the observer's estimate (zero without observer) [N, N, Nm].
    results : list of FilterResult
        One per filter call (every stage).
    d_safe_m : float
        The filter's safety distance [m].
    collided : bool
        The run ended at an obstacle's edge.
    """

    t_s: _F8
    x: _F8
    clearance_m: _F8
    tau_d: _F8
    d_hat: _F8
    results: list[FilterResult]
    d_safe_m: float
    collided: bool = False

    @property
    def min_clearance_m(self) -> float:
        """Smallest distance to any hazard's edge over the run [m]."""
        return float(self.clearance_m.min())

    @property
    def violation_s(self) -> float:
        """Time spent closer than d_safe [s]."""
        dt = float(self.t_s[1] - self.t_s[0]) if self.t_s.size > 1 else 0.0
        return float(np.count_nonzero(self.clearance_m < self.d_safe_m)) * dt

    @property
    def fallbacks(self) -> int:
        """Filter calls whose plan was not certified (plan tail or braking used)."""
        return sum(r.fallback != "none" for r in self.results)

    @property
    def max_slack_m(self) -> float:
        """Largest obstacle-constraint violation in the plans the filter returned [m]:
        max over calls of max(0, −min over stages 1..N of the clearance margin)."""
        worst = [float(-np.min(r.obstacle_margin_m[1:])) for r in self.results]
        return max([0.0, *worst])


def run_with_current(params: VesselParams, case: CurrentScenario, psf: SafetyFilter, *,
                     use_observer: bool, seed: int, duration_s: float = 120.0,
                     preroll_s: float = 40.0, sim_dt_s: float = 0.1,
                     noise: SensorNoise | None = None,
                     gains: ObserverGains | None = None) -> CurrentRun:
    """Simulate the naive controller under the filter in a steady current.

    Parameters
    ----------
    params : VesselParams
        The vessel (the filter's and the simulator's).
    case : CurrentScenario
        Hazards, start state and current.
    psf : SafetyFilter
        The filter (reset here).
    use_observer : bool
        Pass the observer's d̂ as ``d_hat`` (True) or ``d_hat=None`` (False). The
        observer runs either way (same noise draws), so both runs see the same plant.
    seed : int
        Seed of the measurement noise.
    duration_s, preroll_s, sim_dt_s : float
        Episode length, observer warm-up before it, simulator/observer step [s].
    noise : SensorNoise, optional
        Noise on measured ν; :meth:`SensorNoise.for_vessel` by default.
    gains : ObserverGains, optional
        Observer gains; the default ones otherwise.

    Notes
    -----
    The naive controller is :func:`naive_autopilot`: full thrust, heading held on the
    start heading. A run ends early when the ship reaches an obstacle's edge (collision:
    ``collided`` True, the clearance is then ≤ 0).
    """
    for name, v in (("duration_s", duration_s), ("sim_dt_s", sim_dt_s)):
        if not (math.isfinite(v) and v > 0):
            raise ParameterError(f"{name} must be finite and > 0 [s], actually: {v}")
    if not (math.isfinite(preroll_s) and preroll_s >= 0):
        raise ParameterError(f"preroll_s must be finite and >= 0 [s], actually: {preroll_s}")
    sig = np.asarray((noise or SensorNoise.for_vessel(params)).sigma_nu)
    rng = np.random.default_rng(seed)
    scene, vc = case.scenario, case.current_ned_m_s
    dt = psf.config.dt_s
    per = max(1, round(dt / sim_dt_s))
    h = dt / per
    sim = BatchSimulator(params, scene.x0[None], dt_s=h)
    obs = DisturbanceObserver(params, 1, dt_s=h, gains=gains)
    obs.update(scene.x0[None, 3:] + sig * rng.standard_normal(3), np.zeros(3))

    def step(u: _F8) -> tuple[_F8, _F8, _F8]:
        x = sim.state
        d = current_force(params, x, vc)
        x = sim.step(u, d=d)
        dh = obs.update(x[:, 3:] + sig * rng.standard_normal((1, 3)), sim.thrust)
        return x[0], d[0], dh[0]

    psi0 = float(scene.x0[2])
    for _ in range(round(preroll_s / h)):  # open water: sail on, observer settles
        step(naive_autopilot(params, sim.state[0], psi0))
    xr = sim.state
    xr[0, :2] = scene.x0[:2]  # same heading, velocity and thrust, at the start point
    sim.reset(xr, tau0=sim.thrust)
    psf.reset()  # also zeroes the solver's iterate
    x = xr[0]
    dh = obs.estimate[0]
    ts, xs, cl, tds, dhs, res = [], [], [], [], [], []
    N = psf.config.N
    collided = False
    for k in range(round(duration_s / dt)):
        t = k * dt
        if scene.clearance(x[:2], t) <= 0.0:
            collided = True
            break
        r = psf.filter(x, naive_autopilot(params, x, psi0), scene.obstacles(t, N, dt),
                       d_hat=dh if use_observer else None, t_s=t)
        res.append(r)
        for j in range(per):
            x, d, dh = step(r.u0)
            ts.append(t + (j + 1) * h)
            xs.append(x)
            cl.append(scene.clearance(x[:2], ts[-1]))
            tds.append(d)
            dhs.append(dh if use_observer else np.zeros(3))
    return CurrentRun(t_s=np.asarray(ts), x=np.asarray(xs), clearance_m=np.asarray(cl),
                      tau_d=np.asarray(tds), d_hat=np.asarray(dhs), results=res,
                      d_safe_m=psf.d_safe_m, collided=collided)


def naive_autopilot(params: VesselParams, x: _F8, psi_ref: float) -> _F8:
    """The naive controller u_L: full surge thrust, heading held on ``psi_ref``.

    Heading: the project's :class:`~asvtwin.guidance.HeadingSpeedAutopilot` as the critically
    damped PD τ_r = m_r(ω²e_ψ − 2ω r), m_r = M[2, 2], ω = 0.8 rad/s ÷ √λ (the heading
    loop of :mod:`asvtwin.observer.runs`), saturated to the rudder's range; it ignores
    every hazard, so only the filter keeps the ship clear.
    """
    w = 0.8 / math.sqrt(params.length / 1.255)
    ap = HeadingSpeedAutopilot(params, AutopilotGains.critically_damped(params, w))
    tau = ap.tau(x, psi_ref, 0.0)
    tau[0] = params.actuators.tau_max[0]  # full ahead, whatever the speed
    return tau
