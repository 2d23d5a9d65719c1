"""Monte Carlo rollouts of a fork: every alternative × every draw, batched in one simulator.

The futures of all alternatives and all draws are one :class:`~asvtwin.vessel.BatchSimulator`
of own ships (n = alternatives × rollouts) stepped together, with one batched autopilot;
the targets move kinematically (the tracker's constant-velocity model plus an *intent*),
vectorised over draws. The same draws are used for every alternative (common random
numbers: the difference between two alternatives is not blurred by different draws).

Draws (:func:`draw_samples`, from a ``numpy.random.Generator``):

- each target's state from its track, ``N(mean, cov)`` of ``[x, y, v_x, v_y]``;
- each target's intent: keep course (probability ``p_keep``), alter course by
  ``U(10°, turn_max)`` to a random side from a random time in the first half of the
  horizon, or speed up by ``U(1.1, speed_up_max)``;
- the disturbance τ_d = d̂ ⊙ (1 + σ ε), ε ~ N(0, I), per draw (the observer's estimate
  with a relative error ``d_hat_rel_std``), held in the body frame.

The safety filter (:class:`~asvtwin.control.SafetyFilter`, one per filtered future, a
cheap object once the solver is loaded) is the expensive part: 100 futures × 240 calls of
~1–4 ms is minutes of CPU, and a call that has to solve costs 10–100 ms. Its economy
(``economy=True``), cheapest first:

1. the filter is asked only while an obstacle (a target or the coast) is *within reach
   of its horizon*: own and target can close the gap within N·Δt at their speeds; out of
   reach it could only return u_L, so u_L is applied;
2. the filter's own first step, *batched across futures*
   (:class:`~asvtwin.whatif.certify.ULCertifier`): "u_L now, then the rest of the last
   certified plan" or "u_L now, then coast" is re-simulated on the filter's model and
   certified by its compiled kernels for every due future at once; a certified future
   gets u_L, exactly what the filter would have answered (it is stricter than the
   filter, never looser: ``tests/whatif/test_certify.py``). Only the others call the
   filter;
3. a certified solver plan is *followed* (its input of the present stage) for
   ``plan_hold_stages`` stages (4 × 4.2 s at full scale, 4 × 0.5 s at model scale): the
   plan is certified for the predicted obstacles over its whole horizon, so following it
   stays safe unless a target departs from its prediction, which the next call sees;
4. before a future's own solve, the plans the filter solved for *sibling futures* (the
   same alternative, within the last stage; ``share_plans`` of them) are shifted to now
   and certified for this future by the same strict rule; the first certified one is
   followed as in 3. Sibling futures share the own ship's policy and differ in their
   draws, so their solutions are close; a shared plan is certified for this future's own
   targets, but it is not the filter's minimal change to *this* u_L, so it is measured
   against the full rate (below);
5. a fallback plan (nothing certified) is followed for ``fallback_hold_stages`` stage
   (one 4.2 s stage at full scale instead of re-solving every 0.5 s; at model scale the
   stage is the period, so nothing changes), unless the strict rule of 2 certifies it
   for this future's targets: then it is held like a certified plan, as in 3
   (``hold_certified_fallbacks``);
6. a future's filter, new at its first call, starts its solver from the last plan a
   sibling's filter solved (``warm_from_siblings``): the filter's warm start, two QPs,
   instead of ``cold_start_solves`` (5) from a coasting guess;
7. the solver's circle slots are sized to the fork (:func:`filter_config`, 4 for up to
   four targets instead of 20): the unused slots are far-away dummies that never bind,
   but every QP iteration carries them;
8. after an uncertified solve the filter takes its checked fallback without a retry QP
   (``filter_retries`` = 0; the twin's filter retries once).

The solver is shared by the filters of a process; its iterate is reset before every call,
so a future's answer does not depend on which future solved before it (same seed, same
answer with any number of workers).

``tests/whatif/test_rollout.py`` measures the economy against the full-rate filter: the
collision probability agrees within its confidence interval.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.control import (
    CoastSegments,
    MovingObstacles,
    PsfConfig,
    SafetyFilter,
    plain_config,
)
from asvtwin.control.backends import backend_lock
from asvtwin.environment import wind_force, wind_vector
from asvtwin.errors import ParameterError
from asvtwin.geo import LandMask
from asvtwin.guidance import HeadingSpeedAutopilot, LosGuidance
from asvtwin.vessel import BatchSimulator, VesselParams
from asvtwin.whatif.alternatives import Alternative
from asvtwin.whatif.certify import ULCertifier
from asvtwin.whatif.fork import Fork

__all__ = ["RolloutConfig", "RolloutResult", "Samples", "draw_samples", "filter_config",
           "simulate"]

_CS2_L = 1.255  # model-scale CyberShip II length [m] (the Froude reference)


@dataclass(frozen=True)
class RolloutConfig:
    """Settings of the rollouts.

    Attributes
    ----------
    horizon_s : float
        How far ahead [s] (120 s by default).
    dt_s : float, optional
        Simulation step [s]; default 0.05 s·√(L / 1.255 m) (0.42 s for the 88 m hull).
    filter_period_s : float, optional
        Period of the safety filter [s]; default the forked twin's
        (:attr:`Fork.filter_period_s`: ``1 / rates.filter_hz``, 4 s in the default scene,
        0.5 s at the schema's 2 Hz), or 0.5 s when the fork does not say.
    economy : bool
        Filter only within reach, and hold a certified answer for a plan stage (module
        docstring); False: the twin's full rate wherever the filter is on.
    psf_backend : str
        Safety filter backend.
    p_keep, p_turn : float
        Probabilities of a target's intent "keep course" and "alter course" (the rest:
        "speed up").
    turn_max_deg, speed_up_max : float
        Largest course alteration [deg] and speed factor of a target's intent.
    d_hat_rel_std : float
        Relative standard deviation of the disturbance around d̂.
    tracker_q : float
        Acceleration noise [m²/s³] growing the filter's obstacle covariances.
    record_every_s : float
        Period of the stored trajectories (ghost futures) [s].
    plan_hold_stages : int
        Economy: stages of a certified plan followed before the next filter call.
    share_plans : int
        Economy: how many of the plans the filter solved for sibling futures (same
        alternative, within the last stage) are tried before this future's own call
        (0: none).
    cold_start_solves : int
        Solves of a future's first filter call (the filter's ``cold_start_solves``; 0: the
        filter's default, 5).
    share_group : int
        Economy: futures share plans within fixed groups of this many draws (by their
        index in the question); :func:`~asvtwin.whatif.ask` splits work between processes
        on group edges, so the answer does not depend on the number of workers.
    fallback_hold_stages : int
        Economy: stages of a fallback plan followed before the next filter call (0: the
        filter is asked again at its period, as at the full rate).
    warm_from_siblings : bool
        Economy: a future's filter, new at its first call, starts its solver from the
        last plan the filter solved for a sibling future (same alternative and group)
        instead of a cold guess (two QPs instead of ``cold_start_solves``).
    filter_retries : int
        Economy: the filter's ``uncertified_retries`` (the twin's filter: 1). A retry is
        one more QP, linearised at the fallback candidate, after an uncertified solve.
    hold_certified_fallbacks : bool
        Economy: a fallback plan that the strict rule of
        :class:`~asvtwin.whatif.certify.ULCertifier` certifies for this future is held
        for ``plan_hold_stages`` like a certified solver plan (else
        ``fallback_hold_stages``).
    """

    horizon_s: float = 120.0
    dt_s: float | None = None
    filter_period_s: float | None = None
    economy: bool = True
    psf_backend: str = "auto"
    p_keep: float = 0.7
    p_turn: float = 0.15
    turn_max_deg: float = 45.0
    speed_up_max: float = 1.5
    d_hat_rel_std: float = 0.2
    tracker_q: float = 0.01
    record_every_s: float = 5.0
    plan_hold_stages: int = 4
    fallback_hold_stages: int = 1
    share_plans: int = 3
    cold_start_solves: int = 0
    share_group: int = 10
    warm_from_siblings: bool = True
    hold_certified_fallbacks: bool = True
    circle_slots: bool = True
    filter_retries: int = 0

    def __post_init__(self) -> None:
        for name in ("horizon_s", "turn_max_deg", "record_every_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ParameterError(f"RolloutConfig.{name} must be finite and > 0, actually: {v}")
        for name in ("dt_s", "filter_period_s"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and v > 0):
                raise ParameterError(f"RolloutConfig.{name} must be finite and > 0 [s], "
                                     f"actually: {v}")
        if not (0 <= self.p_keep <= 1 and 0 <= self.p_turn <= 1 - self.p_keep):
            raise ParameterError(f"RolloutConfig: intent probabilities p_keep={self.p_keep}, "
                                 f"p_turn={self.p_turn} must be in [0, 1] with a sum <= 1")
        for name, lo in (("plan_hold_stages", 1), ("fallback_hold_stages", 0),
                         ("share_plans", 0), ("share_group", 1),
                         ("cold_start_solves", 0), ("filter_retries", 0)):
            v = getattr(self, name)
            if not (isinstance(v, int) and lo <= v <= 50):
                raise ParameterError(f"RolloutConfig.{name} must be an integer in [{lo}, 50], "
                                     f"actually: {v!r}")
        if not 1.0 <= self.speed_up_max <= 3.0:
            raise ParameterError(f"RolloutConfig.speed_up_max must be in [1, 3], actually: "
                                 f"{self.speed_up_max}")

    def resolved(self, length_m: float, twin_period_s: float = math.nan
                 ) -> tuple[float, float]:
        """(dt_s, filter_period_s) for a hull of ``length_m``; ``twin_period_s`` the
        forked twin's filter period (:attr:`Fork.filter_period_s`), used when
        ``filter_period_s`` is not set."""
        sq = math.sqrt(length_m / _CS2_L)
        dt = self.dt_s if self.dt_s is not None else 0.05 * sq
        fp = (self.filter_period_s if self.filter_period_s is not None
              else twin_period_s if math.isfinite(twin_period_s) and twin_period_s > 0
              else 0.5)
        return dt, max(fp, dt)


@dataclass(frozen=True, eq=False)
class Samples:
    """The random draws of R rollouts with m targets (shared by every alternative).

    ``x0`` (R, m, 4) target states; ``intent`` (R, m) 0 keep, 1 turn, 2 speed up;
    ``t_change_s`` (R, m) when the intent starts [s]; ``turn_rad`` (R, m) signed course
    change; ``speed_factor`` (R, m); ``d`` (R, 3) disturbance [N, N, Nm], body frame;
    ``first``: index of the first of these draws in the whole question (for a worker's
    slice)."""

    x0: _F8
    intent: NDArray[np.int64]
    t_change_s: _F8
    turn_rad: _F8
    speed_factor: _F8
    d: _F8
    first: int = 0

    @property
    def n(self) -> int:
        return int(self.d.shape[0])

    def take(self, idx: slice) -> Samples:
        """The draws of rollouts ``idx`` (for a worker)."""
        return Samples(self.x0[idx], self.intent[idx], self.t_change_s[idx],
                       self.turn_rad[idx], self.speed_factor[idx], self.d[idx],
                       first=self.first + (idx.start or 0))


def _sqrt_psd(c: _F8) -> _F8:
    w, v = np.linalg.eigh(0.5 * (c + np.swapaxes(c, -1, -2)))
    return v * np.sqrt(np.maximum(w, 0.0))[..., None, :]


def draw_samples(fork: Fork, n: int, rng: np.random.Generator, config: RolloutConfig
                 ) -> Samples:
    """Draw ``n`` futures' targets, intents and disturbances (see the module docstring)."""
    if n < 1:
        raise ParameterError(f"the number of rollouts must be >= 1, actually: {n}")
    m = fork.n_tracks
    z = rng.standard_normal((n, m, 4))
    x0 = fork.track_mean[None] + np.einsum("mij,rmj->rmi", _sqrt_psd(fork.track_cov), z) \
        if m else np.zeros((n, 0, 4))
    u = rng.random((n, m))
    intent = np.where(u < config.p_keep, 0, np.where(u < config.p_keep + config.p_turn, 1, 2))
    t_change = rng.random((n, m)) * 0.5 * config.horizon_s
    side = np.where(rng.random((n, m)) < 0.5, -1.0, 1.0)
    turn = side * np.radians(rng.uniform(10.0, max(10.0, config.turn_max_deg), (n, m)))
    factor = rng.uniform(1.1, max(1.1, config.speed_up_max), (n, m))
    d = fork.d_hat[None] * (1.0 + config.d_hat_rel_std * rng.standard_normal((n, 3)))
    return Samples(x0, intent.astype(np.int64), t_change, turn, factor, d)


@dataclass(frozen=True, eq=False)
class RolloutResult:
    """Outcomes per alternative a and rollout r (arrays (A, R, ...)).

    ``min_distance_m`` (A, R, m): smallest centre distance to each target [m];
    ``t_min_s`` (A, R, m): when it happened [s after the fork]; ``clearance_m`` (A, R):
    smallest distance between hull circles (centre distance − both half-lengths) over all
    targets [m], negative = contact; ``collision``/``grounding`` (A, R) bool;
    ``land_clearance_m`` (A, R) smallest distance to the shore [m] (inf without a chart);
    ``filter_calls``, ``interventions``, ``fallbacks`` (A, R) int; ``track`` (A, R, T, 2)
    own positions every ``record_every_s`` [m] with ``track_t_s`` (T,)."""

    min_distance_m: _F8
    t_min_s: _F8
    clearance_m: _F8
    collision: NDArray[np.bool_]
    grounding: NDArray[np.bool_]
    land_clearance_m: _F8
    filter_calls: NDArray[np.int64]
    interventions: NDArray[np.int64]
    fallbacks: NDArray[np.int64]
    track: _F8
    track_t_s: _F8
    info: dict[str, float] = field(default_factory=dict)

    @staticmethod
    def join(parts: list[RolloutResult]) -> RolloutResult:
        """Rollouts of several workers side by side (axis 1), in the order given."""
        cat = {k: np.concatenate([getattr(p, k) for p in parts], axis=1) for k in (
            "min_distance_m", "t_min_s", "clearance_m", "collision", "grounding",
            "land_clearance_m", "filter_calls", "interventions", "fallbacks", "track")}
        info = dict(parts[0].info)
        for k in ("filter_calls", "filters_built", "u_L_precertified",
                  "filter_kept_u_L", "plans_shared", "warm_from_siblings",
                  "fallbacks_certified", "cpu_s"):
            info[k] = float(sum(p.info.get(k, 0.0) for p in parts))
        return RolloutResult(**cat, track_t_s=parts[0].track_t_s, info=info)


def filter_config(config: RolloutConfig, n_targets: int) -> PsfConfig:
    """The safety filter's settings in the rollouts of a fork with ``n_targets`` tracks.

    The filter's solver has a fixed number of circle slots (``PsfConfig.n_circles``, 20);
    the slots no obstacle fills hold far-away dummies, which never bind but which the QP
    solver carries through every iteration. With ``circle_slots`` (economy) the slots
    are sized to the fork: the smallest of 4, 8, 20 that holds every target, so the
    solver sees the same obstacles with fewer idle constraints (one solver build per
    size, cached on disk). The economy also sets the filter's ``uncertified_retries`` to
    ``filter_retries`` (0: after an uncertified solve the filter takes its checked
    fallback at once, without a second QP linearised at it)."""
    nc = PsfConfig.n_circles
    if config.economy and config.circle_slots:
        nc = next((k for k in (4, 8) if n_targets <= k), nc)
    retries = config.filter_retries if config.economy else PsfConfig.uncertified_retries
    # the twin's own filter is the plain one (asvtwin.twin.components.twin_filter_config):
    # so are its forks
    return plain_config(backend=config.psf_backend,
                        cold_start_solves=config.cold_start_solves or 5, n_circles=nc,
                        uncertified_retries=retries)


def _course_over_ground(x: _F8) -> float:
    c, s = math.cos(x[2]), math.sin(x[2])
    vn, ve = c * x[3] - s * x[4], s * x[3] + c * x[4]
    return math.atan2(ve, vn) if math.hypot(vn, ve) > 0.05 else float(x[2])


class _Targets:
    """Kinematic targets of R draws: constant velocity plus intent, vectorised."""

    def __init__(self, fork: Fork, s: Samples, alt: Alternative, tau_s: float,
                 rate_rad_s: float) -> None:
        self.p = s.x0[..., :2].copy()
        v = s.x0[..., 2:]
        self.course = np.arctan2(v[..., 1], v[..., 0])
        self.speed = np.hypot(v[..., 0], v[..., 1])
        self.course_goal = self.course + np.where(s.intent == 1, s.turn_rad, 0.0)
        self.speed_goal = self.speed * np.where(s.intent == 2, s.speed_factor, 1.0)
        self.t_change = np.where(s.intent == 0, np.inf, s.t_change_s)
        if alt.target_id >= 0:
            j = np.flatnonzero(fork.track_ids == alt.target_id)
            if j.size == 0:
                raise ParameterError(f"alternative {alt.label!r}: no believed track "
                                     f"{alt.target_id}; tracks: {fork.track_ids.tolist()}")
            j0 = int(j[0])
            self.course_goal[:, j0] = self.course[:, j0] + alt.target_course_change_rad
            self.speed_goal[:, j0] = self.speed[:, j0] * alt.target_speed_factor
            self.t_change[:, j0] = 0.0
        self.tau_s = tau_s
        self.rate = rate_rad_s
        self._update_velocity()

    def step(self, t: float, dt: float) -> None:
        active = t >= self.t_change
        err = np.angle(np.exp(1j * (self.course_goal - self.course)))
        self.course += np.where(active, np.clip(err, -self.rate * dt, self.rate * dt), 0.0)
        self.speed += np.where(active, (self.speed_goal - self.speed) * min(1.0, dt / self.tau_s),
                               0.0)
        self.p[..., 0] += dt * self.speed * np.cos(self.course)
        self.p[..., 1] += dt * self.speed * np.sin(self.course)
        self._update_velocity()

    def _update_velocity(self) -> None:
        #: (R, m, 2) velocities [m/s] after the last step (read per future by the filter)
        self.velocity = np.stack([self.speed * np.cos(self.course),
                                  self.speed * np.sin(self.course)], -1)


def simulate(fork: Fork, alternatives: tuple[Alternative, ...] | list[Alternative],
             samples: Samples, *, config: RolloutConfig | None = None,
             land: LandMask | None = None, params: VesselParams | None = None
             ) -> RolloutResult:
    """Roll every alternative out over every draw in ``samples`` (one process).

    Parameters
    ----------
    fork : Fork
    alternatives : sequence of Alternative
    samples : Samples
        From :func:`draw_samples` (or a worker's slice of them).
    config : RolloutConfig, optional
    land : LandMask, optional
        The chart, for grounding and the filter's coast (none: open water).
    params : VesselParams, optional
        The own ship's parameters (default ``fork.params``; pass the twin's, e.g. with
        astern thrust).
    """
    cpu0 = time.process_time()
    cfg = config or RolloutConfig()
    p = params or fork.params
    A, R, m = len(alternatives), samples.n, fork.n_tracks
    if A == 0:
        raise ParameterError("at least one alternative is needed")
    L = p.length
    dt, fper = cfg.resolved(L, fork.filter_period_s)
    steps = round(cfg.horizon_s / dt)
    sq = math.sqrt(L / 88.0)
    x0 = np.broadcast_to(fork.own_state, (A * R, 6))
    sim = BatchSimulator(p, x0, dt_s=dt)
    ap = HeadingSpeedAutopilot(p)
    chi0 = _course_over_ground(fork.own_state)
    u_now = float(fork.own_state[3])
    route = fork.route
    los = [LosGuidance(route, lookahead_m=2.5 * L, acceptance_radius_m=2.0 * L)
           if len(route) else None for _ in alternatives]
    targets = [_Targets(fork, samples, a, 30.0 * sq, 0.02 / sq) for a in alternatives]
    # disturbances: d̂ per draw, plus the rise of the wind of a "wind" hypothesis
    d_base = np.tile(samples.d, (A, 1))
    old_wind = (wind_vector(fork.wind_speed_m_s, fork.wind_from_rad)
                if math.isfinite(fork.wind_speed_m_s) and math.isfinite(fork.wind_from_rad)
                else np.zeros(2))
    wind_rise = [wind_vector(a.wind_speed_m_s, a.wind_from_rad) - old_wind
                 if a.kind == "wind" else None for a in alternatives]
    r_t = 0.5 * fork.track_length_m
    r_own = 0.5 * L
    # per alternative: course and speed references when not following the route
    fixed: list[tuple[float, float] | None] = []
    for a in alternatives:
        if a.kind == "keep_course":
            fixed.append((chi0, u_now))
        elif a.kind in ("starboard", "port"):
            fixed.append((chi0 + a.course_change_rad, fork.cruise_speed_m_s))
        elif a.kind == "stop":
            fixed.append((chi0, 0.0))
        elif not len(route):
            fixed.append((chi0, fork.cruise_speed_m_s * a.speed_factor))
        else:
            fixed.append(None)
    # the filter: one per filtered future, built when first needed
    filt: dict[int, SafetyFilter] = {}
    plans: dict[int, tuple[float, _F8]] = {}  # per future: (time of the call, u_pred)
    proto: SafetyFilter | None = None
    next_call = np.zeros(A * R)
    u0 = np.zeros((A * R, 3))
    calls = np.zeros(A * R, np.int64)
    inter = np.zeros(A * R, np.int64)
    falls = np.zeros(A * R, np.int64)
    reach_t = 0.0
    cert: ULCertifier | None = None
    due_segs: dict[int, _F8] = {}
    n_precert = 0
    n_passed = 0  # filter calls that kept u_L
    certified_plan: dict[int, tuple[float, _F8]] = {}  # per future: the filter's last plan
    # per (alternative, group of share_group draws): recent solver plans; groups are fixed
    # by the draw's index in the question, so a worker split on group edges changes nothing
    shared: dict[tuple[int, int], list[tuple[float, _F8]]] = {}
    G = cfg.share_group
    n_shared = 0
    # per group: the last plan any filter of it solved, (t, x_pred, u_pred): a warm start
    group_last: dict[tuple[int, int], tuple[float, _F8, _F8]] = {}
    n_warm = 0  # new filters warm-started from a sibling's plan
    n_fb_cert = 0  # fallback plans certified by the strict rule (held like solver plans)
    if any(a.filter for a in alternatives):
        psf_cfg = filter_config(cfg, m)
        proto = SafetyFilter(p, config=psf_cfg)
        N, pdt = proto.config.N, proto.config.dt_s
        reach_t = N * pdt
        coast_r = reach_t * float(proto.nu_max[0]) + proto.d_safe_m + proto.d_f_m
        cert = ULCertifier(proto, r_t, fork.track_cov[:, :2, :2], cfg.tracker_q * pdt)
    mind = np.full((A, R, m), np.inf)
    tmin = np.zeros((A, R, m))
    land_min = np.full(A * R, np.inf)
    grounded = np.zeros(A * R, bool)
    every = max(1, round(cfg.record_every_s / dt))
    rec_t = [0.0]
    rec = [sim.state[:, :2].reshape(A, R, 2).copy()]
    n_filtered = 0

    x = sim.state
    for k in range(steps):
        t = k * dt
        # own ship: references, autopilot
        chi = np.empty(A * R)
        spd = np.empty(A * R)
        for i, a in enumerate(alternatives):
            sl = slice(i * R, (i + 1) * R)
            ref = fixed[i]
            if ref is not None:
                chi[sl], spd[sl] = ref
            else:
                out = los[i].step(x[sl, :2])  # type: ignore[union-attr]
                chi[sl] = out.course_rad
                spd[sl] = np.where(out.done, 0.0, fork.cruise_speed_m_s * a.speed_factor)
        u_L = ap.tau(x, chi, spd)
        u_apply = u_L.copy()
        # safety filter (per future, Python loop over the filtered ones that are due)
        if proto is not None:
            due_j: list[int] = []
            for lst in shared.values():  # a shared plan is offered for one stage
                lst[:] = [e for e in lst if t - e[0] < pdt - 1e-9]
            for i, a in enumerate(alternatives):
                if not a.filter:
                    continue
                tg = targets[i]
                for r in range(R):
                    j = i * R + r
                    if t + 1e-9 < next_call[j]:
                        plan = plans.get(j)
                        if plan is None:
                            u_apply[j] = u0[j]
                        else:  # follow the held plan: its input of the present stage
                            kk = min(int((t - plan[0]) / pdt + 1e-9), N - 1)
                            u_apply[j] = plan[1][kk]
                        continue
                    xj = x[j]
                    segs = (land.segments_within(xj[:2], coast_r) if land is not None
                            else np.zeros((0, 4)))
                    if cfg.economy:
                        pos, vel = tg.p[r], tg.velocity[r]
                        gap = np.hypot(pos[:, 0] - xj[0], pos[:, 1] - xj[1]) - r_t
                        close = (float(np.hypot(xj[3], xj[4])) + np.hypot(vel[:, 0], vel[:, 1])) \
                            * reach_t + proto.d_safe_m + proto.d_f_m
                        if not (np.any(gap < close) or len(segs)):
                            plans.pop(j, None)
                            next_call[j] = t + fper
                            u0[j] = u_L[j]
                            continue
                    due_j.append(j)
                    due_segs[j] = segs
            if due_j and cfg.economy and cert is not None:
                # the filter's first step, batched: "u_L now, then coast" certified
                jj = np.array(due_j)
                ii, rr = jj // R, jj % R
                pos = np.stack([targets[i].p[r] for i, r in zip(ii, rr)]).reshape(len(jj), m, 2)
                vel = np.stack([targets[i].velocity[r] for i, r in zip(ii, rr)]
                               ).reshape(len(jj), m, 2)
                tails: list[_F8 | None] = []
                for j in due_j:  # the rest of the last certified plan, as the filter's
                    last = certified_plan.get(j)
                    s_i = -1 if last is None else round((t - last[0]) / pdt)
                    if last is not None and 0 <= s_i < N - 1:
                        tail = np.zeros((N, 3))
                        rest = last[1][s_i + 1:]
                        tail[1: 1 + len(rest)] = rest
                        tails.append(tail)
                    else:
                        tails.append(None)
                ok, kept = cert.certified(x[jj], u_L[jj], samples.d[rr], pos, vel,
                                          [due_segs[j] for j in due_j], tails)
                for q in np.flatnonzero(ok):
                    j = int(jj[q])
                    plans.pop(j, None)
                    due_segs.pop(j, None)
                    certified_plan[j] = (t, kept[q])  # type: ignore[assignment]
                    next_call[j] = t + fper
                    u0[j] = np.clip(u_L[j], proto.u_lb, proto.u_ub)
                    u_apply[j] = u0[j]
                n_precert += int(ok.sum())
                due_j = [int(j) for j in jj[~ok]]
            for j in due_j:
                i, r = divmod(j, R)
                tg = targets[i]
                grp = (i, (samples.first + r) // G)
                if cfg.economy and cfg.share_plans and cert is not None and shared.get(grp):
                    # a plan the filter certified for a sibling future of this alternative
                    # within the last stage, shifted to now, certified for this one
                    cands = []
                    for t0, Up in shared[grp][-cfg.share_plans:][::-1]:
                        s_i = round((t - t0) / pdt)
                        Us = np.zeros((N, 3))
                        Us[: N - s_i] = Up[s_i:]
                        cands.append(Us)
                    segs = due_segs.get(j, np.zeros((0, 4)))
                    k_ok = cert.first_certified(x[j], samples.d[r], tg.p[r], tg.velocity[r],
                                                segs, cands)
                    if k_ok >= 0:
                        due_segs.pop(j, None)
                        Us = cands[k_ok]
                        plans[j] = (t, Us)
                        certified_plan[j] = (t, Us)
                        u0[j] = Us[0]
                        u_apply[j] = Us[0]
                        lim = 0.01 * (proto.u_ub - proto.u_lb)
                        uLc = np.clip(u_L[j], proto.u_lb, proto.u_ub)
                        inter[j] += int(np.any((lim > 0) & (np.abs(uLc - Us[0]) > lim)))
                        next_call[j] = t + max(cfg.plan_hold_stages * pdt, fper)
                        n_shared += 1
                        continue
                f = filt.get(j)
                if f is None:
                    f = filt[j] = SafetyFilter(p, config=psf_cfg)
                    sib = group_last.get(grp) if cfg.economy and cfg.warm_from_siblings else None
                    if sib is not None and round((t - sib[0]) / pdt) < N - 1:
                        # a new filter's first solve starts from a sibling's last solved
                        # plan (the same alternative, a nearby state) instead of a cold
                        # guess: the filter's warm start (2 QPs, not cold_start_solves)
                        f._last = (fork.t_s + sib[0], sib[1], sib[2])
                        n_warm += 1
                obs: list[MovingObstacles | CoastSegments] = []
                if m:
                    obs.append(MovingObstacles.constant_velocity(
                        tg.p[r], tg.velocity[r], r_t, N=N, dt_s=pdt,
                        covariances=fork.track_cov[:, :2, :2],
                        process_noise=cfg.tracker_q * pdt,
                        ids=[int(q) for q in fork.track_ids]))
                segs = due_segs.pop(j)
                if len(segs):
                    obs.append(CoastSegments(segs))
                # the solver is shared per process: start every call from a zero iterate,
                # so a future's answer does not depend on which future solved before it
                # (same seed, same answer with any number of workers)
                with backend_lock(f.backend):
                    f.backend.reset()
                res = f.filter(x[j], u_L[j], obs, samples.d[r], t_s=fork.t_s + t)
                n_filtered += 1
                n_passed += int(res.passed_through)
                calls[j] += 1
                u0[j] = res.u0
                u_apply[j] = res.u0
                inter[j] += int(res.intervened)
                falls[j] += int(res.fallback != "none")
                if not res.passed_through:
                    group_last[grp] = (t, np.asarray(res.x_pred, float),
                                       np.asarray(res.u_pred, float))
                held_ok = res.success
                if (not held_ok and cfg.economy and cfg.hold_certified_fallbacks
                        and cert is not None and not res.passed_through):
                    # a fallback candidate that the strict rule certifies for this
                    # future's targets is as safe to follow as a certified solver plan
                    held_ok = cert.first_certified(
                        x[j], samples.d[r], tg.p[r], tg.velocity[r], segs,
                        [np.asarray(res.u_pred, float)]) == 0
                    n_fb_cert += int(held_ok)
                if held_ok:
                    certified_plan[j] = (t, np.asarray(res.u_pred, dtype=float))
                    if not res.passed_through:
                        shared.setdefault(grp, []).append((t, np.asarray(res.u_pred, float)))
                # economy: a certified solver plan is followed for plan_hold_stages of its
                # stages, a fallback plan for one stage; u_L kept is asked again at fper
                if not cfg.economy or res.passed_through:
                    plans.pop(j, None)
                    next_call[j] = t + fper
                elif held_ok:
                    plans[j] = (t, np.asarray(res.u_pred, dtype=float))
                    next_call[j] = t + max(cfg.plan_hold_stages * pdt, fper)
                else:
                    plans[j] = (t, np.asarray(res.u_pred, dtype=float))
                    next_call[j] = t + max(cfg.fallback_hold_stages * pdt, fper)
        # disturbance
        d = d_base.copy()
        for i, w in enumerate(wind_rise):
            if w is not None:
                sl = slice(i * R, (i + 1) * R)
                d[sl] += wind_force(p, x[sl], w) - wind_force(p, x[sl], np.zeros(2))
        x = sim.step(u_apply, d)
        for tg in targets:
            tg.step(t, dt)
        # scoring
        tpos = np.stack([tg.p for tg in targets])  # (A, R, m, 2)
        own = x[:, :2].reshape(A, R, 1, 2)
        dist = np.hypot(*(tpos - own).transpose(3, 0, 1, 2))
        closer = dist < mind
        mind = np.where(closer, dist, mind)
        tmin = np.where(closer, t + dt, tmin)
        if land is not None:
            sd = land.signed_distance(x[:, :2])
            land_min = np.minimum(land_min, sd)
            grounded |= sd < 0.0
        if (k + 1) % every == 0:
            rec.append(x[:, :2].reshape(A, R, 2).copy())
            rec_t.append(t + dt)
    clear = (mind - r_t[None, None] - r_own).min(axis=2) if m else np.full((A, R), np.inf)
    sh = (A, R)
    return RolloutResult(
        min_distance_m=mind, t_min_s=tmin, clearance_m=clear, collision=clear < 0.0,
        grounding=grounded.reshape(sh), land_clearance_m=land_min.reshape(sh),
        filter_calls=calls.reshape(sh), interventions=inter.reshape(sh),
        fallbacks=falls.reshape(sh), track=np.stack(rec, axis=2), track_t_s=np.array(rec_t),
        info={"filter_calls": float(n_filtered), "filters_built": float(len(filt)),
              "u_L_precertified": float(n_precert), "filter_kept_u_L": float(n_passed),
              "plans_shared": float(n_shared), "warm_from_siblings": float(n_warm),
              "fallbacks_certified": float(n_fb_cert),
              "cpu_s": time.process_time() - cpu0,
              "steps": float(steps), "dt_s": dt, "filter_period_s": fper})
