"""Configuration and answer of the predictive safety filter: :class:`PsfConfig`,
:class:`FilterResult` and :class:`ActiveConstraint` (plain values, frozen)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Literal

import numpy as np

from asvtwin.checks import F8 as _F8
from asvtwin.errors import ConfigError

__all__ = ["ActiveConstraint", "FilterResult", "PsfConfig", "ResolvedPsfConfig",
           "comfort_config"]

_HPIPM_MODES = ("BALANCE", "SPEED", "SPEED_ABS", "ROBUST")

#: CyberShip II's length [m]: the reference for the model-scale defaults below.
CS2_LENGTH_M = 1.255


@dataclass(frozen=True)
class PsfConfig:
    """Settings of the safety filter (defaults: the published settings of Vaaler et al.
    2023 at model scale, Froude-scaled
    by the vessel's length for other hulls when left at None).

    Attributes
    ----------
    N : int
        Stages (50).
    dt_s : float, optional
        Stage length [s]; default 0.5 s at model scale, Froude-scaled by √(L / 1.255 m)
        (4.18 s for the 88 m hull). The horizon N·Δt must cover the braking time from top
        speed into the terminal set, or :class:`SafetyFilter` raises ConfigError.
    backend : str
        ``"auto"`` (fastest installed: acados, else casadi-ipopt), ``"acados"``,
        ``"casadi-ipopt"`` or ``"casadi-fatrop"``.
    d_safe_m : float, optional
        Safety distance from the own ship's origin to an obstacle's edge [m]; default
        the ship's length.
    d_f_m : float, optional
        Terminal distance d_f [m] (braking distance bound); default 6 ship lengths.
    nu_max : tuple of 3 floats, optional
        Soft velocity bounds |u|, |v| [m/s], |r| [rad/s]; default (2, 2, 0.15) scaled.
    terminal_r_max : float, optional
        Largest yaw rate of the terminal ellipsoid [rad/s]; default 4·nu_max[2].
    gamma : tuple of 3 floats
        γ_u of the paper's W = diag(γ_i / (u_ub,i − u_lb,i)²).
    later_weight : float
        Weight of stages 1..N-1 in the cost (the published code: 0, only u_0 counts).
    slack_l1, slack_l2 : float
        L1 (100 in the published code) and small L2 penalty of the slacks.
    n_circles, n_segments : int
        Obstacle slots: the circles and coast segments nearest to the predicted path (the
        previous plan and the learner's) are given to the solver; certification checks all.
    certify_tol_m : float, optional
        Tolerance of the certification of a plan [m]; default 2 % of the ship length.
    max_iter : int
        Iteration limit of the CasADi solvers.
    rti_steps : int
        Largest number of SQP-RTI steps per call (acados).
    retry_rti_steps : int
        Largest number of SQP-RTI steps of a retry (acados; stops earlier when a step
        changes the inputs by less than 0.1 % of their range): a retry runs the SQP
        towards convergence, one step at a time, each iterate re-simulated and judged;
        it ends on the last iterate when that is certified, else on the last certified
        one on the way (the steps have no globalisation and need not improve). 10 since
        2026-12-07: with 3, two of 480 random encounters lost the certificate for good
        (full scale 0.355 d_safe, a collision; model scale 0.781), with 4–5 one of them
        still did (docs/psf.md, "Random encounters").
    cold_start_solves : int
        Solver calls allowed when there is no previous solver plan to warm-start from.
        The SQP-RTI iterates of a cold start do not improve monotonically: on three
        first calls 7–8 m from a rock at 0.4–0.5 m/s, with the thrusters' lag in the
        plan, 5 left two uncertified and 8 certified all three (10 and 15 did not;
        the retry from the best candidate that follows is what usually certifies).
        8 since 2026-12-07, with the lag model (5 before).
    uncertified_retries : int
        Solves more when the answer is not certified, each warm-started from the best
        fallback candidate (SQP-RTI: one more QP linearised at a safe trajectory).
    retry_in_streak : bool
        Also retry when the previous call ended on a fallback too, less than a horizon
        N·Δt earlier (a fallback streak). With ``False`` such a call makes one solve and
        ends on its checked fallback candidate if that solve is not certified; the first
        fallback of a streak still retries. In the RL world's early training (model
        scale, the policy pushing at an obstacle for hundreds of steps) this saved ~40 %
        of a training process's CPU with the encounter set's model-scale results
        unchanged; at full scale the retry's extra SQP step is what ends the coast
        streaks (fallbacks 0.95 → 3.6 % of calls without it): on by default, the RL
        world turns it off (docs/psf.md, speed).
    retry_failed_solves : bool
        Within a fallback streak (the previous call fell back less than a horizon N·Δt
        earlier), retry also when the solve itself failed (the QP stopped at its
        iteration limit or failed), not only when its converged plan was not certified.
        In the twin among 50 extra vessels, retries after a failed solve certified a
        plan in 1 of 911 calls and were a third of all solves, the most expensive ones;
        outside a streak (an isolated failure) the retry is kept, since at full scale
        it is what avoids a fallback in the two-vessel encounters (docs/psf.md, speed):
        off by default.
    hpipm_mode : str
        The acados backend's HPIPM mode (``"BALANCE"``, ``"SPEED"``, ``"SPEED_ABS"``,
        ``"ROBUST"``); other backends ignore it. ``"SPEED"``: ~30 % less CPU per solve,
        same model-scale encounter results, more fallbacks at full scale (0.95 → 4.2 %
        of calls): the RL world (model scale) uses it, the default stays ``"BALANCE"``.
    qp_tol : float or None
        The acados backend's HPIPM stopping tolerance (stationarity, equality,
        inequality and complementarity residuals alike; the QP is in the solver's scaled
        inputs and model-scale metres); other backends ignore it. None: the mode's own
        (in BALANCE a tight one: an explicit 1e-8 behaved alike), at which 6 % of the
        full-scale QPs in the twin's benchmark scene stopped at HPIPM's iteration limit
        (100) and ended as failed solves; at 1e-4, 0 % of the same 2,453 recorded QPs.
        The twin's filter uses 1e-4 (1.09-1.33 times as fast there: docs/twin.md,
        "Speed"); the default stays None because the model-scale steered field of
        ``benchmarks/psf.py`` fell back more with it.
    colreg : bool
        Prefer the starboard side where COLREG rules 14, 15 and 17(c) expect it: the
        solver is warm-started from a starboard turn when a head-on or crossing vessel
        (classified from the moving obstacles) makes the learner's plan unsafe.
    comfort_pass_through : bool
        During an avoidance (u_L was not safe at a call within the last horizon N·Δt),
        keep u_L only when the plan that certifies it turns no faster than the comfort
        bound ν_max,r after u_L's own step (or than that step left it, if faster);
        otherwise ask the solver for a gentler certified plan first, and keep u_L (it is
        certified) only if there is none. Outside an avoidance u_L is not judged by the
        bound: a learner turning hard far from everything is left be (0 of 800 calls
        changed in ``benchmarks/psf_encounters.py``'s open-water turns; without the
        window 195 of 200 at model scale). With it, too, a solver's certified plan that
        turns faster than the bound gives way to the last certified plan's remainder
        when that, re-simulated against the obstacles known now, is certified and keeps
        the bound (a certified plan: no fallback), and the fallback turns come also
        governed to hold |r| at the bound. On by default since 2026-12-07, with
        ``model_actuator_lag``: together they keep the filter's own avoidance within
        1.05 ν_max,r in every case of the encounter set on both backends and hull
        scales (docs/psf.md, "The comfort bound by default"). With
        ``yaw_slack_weight=10`` the twin's optional comfort setting
        (``asvtwin.twin.components.twin_filter_config(comfort=True)``).
    yaw_slack_weight : float
        What a unit of the yaw-rate bound's slack costs relative to the others' (each
        counted in model-scale units): 1 prices it like a model-scale metre of obstacle
        margin. Higher values make the solver's plans keep the comfort bound ν_max,r
        where they can, and trade clearance for it: IPOPT's converged answers at 10
        (with the comfort pass-through) cut into d_safe and fell back on 2 % of the
        full-scale encounter set's calls (none at 1). With the comfort pass-through on
        acados at full scale, the set's avoidance turned at most 1.11 times ν_max,r
        (1.26 without); at model scale faster, with four times the fallbacks
        (docs/psf.md, "The comfort bound in the twin's filter").
    model_actuator_lag : bool
        Plan with the thrusters' first-order lag (``ActuatorParams.time_constant_s``,
        when every constant is > 0): the solver and the certifying rollouts carry the
        thrust produced as a state that follows the command, starting from the thrust
        of the call (:meth:`SafetyFilter.filter`'s ``tau``). CyberShip II's 0.2 s (1.67 s
        at 88 m) is 40 % of a stage: without it a commanded reversal of the yaw moment
        acts a fifth of a second late in every plan, and the avoidance overshot the
        comfort bound ν_max,r by 4–25 % (docs/psf.md, "The thrusters' lag"). On by
        default since 2026-12-07.
    clearance_slack_weight : float
        What the obstacle margins' slack costs relative to the velocity bounds' (per
        model-scale metre against a model-scale m/s or rad/s): safety before comfort.
        At 1, with the lag modelled, the solver's plans traded 2.5 cm of d_safe for a
        yaw rate within ν_max,r: 14 of the 200 adversarial closed loops of
        ``tests/control/test_closed_loop.py`` came inside d_safe, the deepest 29 mm
        (2.3 %, beyond the certification's 2 % tolerance). 2 (the default since
        2026-12-07) and 3 leave one 1.5 mm inside; 3 costs ``benchmarks/psf.py``'s
        corridor its speed goal (call p95 8–100 ms against 0.2–0.3 ms at 2;
        docs/psf.md, "The comfort bound by default").
    """

    N: int = 50
    dt_s: float | None = None
    backend: str = "auto"
    d_safe_m: float | None = None
    d_f_m: float | None = None
    nu_max: tuple[float, float, float] | None = None
    terminal_r_max: float | None = None
    gamma: tuple[float, float, float] = (1.0, 1.0, 1.0)
    later_weight: float = 1e-3
    slack_l1: float = 100.0
    slack_l2: float = 1.0
    n_circles: int = 20
    n_segments: int = 12
    certify_tol_m: float | None = None
    max_iter: int = 200
    rti_steps: int = 1
    retry_rti_steps: int = 10
    cold_start_solves: int = 8
    uncertified_retries: int = 1
    retry_in_streak: bool = True
    retry_failed_solves: bool = False
    hpipm_mode: str = "BALANCE"
    qp_tol: float | None = None
    colreg: bool = True
    comfort_pass_through: bool = True
    yaw_slack_weight: float = 1.0
    model_actuator_lag: bool = True
    clearance_slack_weight: float = 2.0

    def __post_init__(self) -> None:
        checks: list[tuple[str, bool, str]] = [
            ("N", isinstance(self.N, int) and 1 <= self.N <= 500, "an int in [1, 500]"),
            ("dt_s", self.dt_s is None or (math.isfinite(self.dt_s) and self.dt_s > 0),
             "None or > 0"),
            ("later_weight", self.later_weight >= 0, ">= 0"),
            ("slack_l1", self.slack_l1 > 0, "> 0"),
            ("slack_l2", self.slack_l2 >= 0, ">= 0"),
            ("yaw_slack_weight", math.isfinite(self.yaw_slack_weight)
             and self.yaw_slack_weight > 0, "finite and > 0"),
            ("clearance_slack_weight", math.isfinite(self.clearance_slack_weight)
             and self.clearance_slack_weight > 0, "finite and > 0"),
            ("n_circles", self.n_circles >= 1, ">= 1"),
            ("n_segments", self.n_segments >= 0, ">= 0"),
            ("max_iter", self.max_iter >= 1, ">= 1"),
            ("rti_steps", self.rti_steps >= 1, ">= 1"),
            ("retry_rti_steps", self.retry_rti_steps >= 1, ">= 1"),
            ("cold_start_solves", self.cold_start_solves >= 1, ">= 1"),
            ("uncertified_retries", 0 <= self.uncertified_retries <= 5, "in [0, 5]"),
            ("gamma", len(self.gamma) == 3 and min(self.gamma) >= 0, "3 values >= 0"),
            ("hpipm_mode", self.hpipm_mode in _HPIPM_MODES, f"one of {_HPIPM_MODES}"),
        ]
        for name in ("d_safe_m", "d_f_m", "terminal_r_max", "certify_tol_m", "qp_tol"):
            v = getattr(self, name)
            checks.append((name, v is None or (math.isfinite(v) and v > 0), "None or > 0"))
        if self.nu_max is not None:
            checks.append(("nu_max", len(self.nu_max) == 3 and min(self.nu_max) > 0,
                           "3 values > 0"))
        for name, ok, expected in checks:
            if not ok:
                raise ConfigError(f"PsfConfig.{name} must be {expected}, actually: "
                                  f"{getattr(self, name)!r}")


PLAIN_FIELDS: dict[str, Any] = {"model_actuator_lag": False, "comfort_pass_through": False,
                                "cold_start_solves": 5, "clearance_slack_weight": 1.0}


def plain_config(**overrides: Any) -> PsfConfig:
    """The filter as its defaults were until 2026-12-07: lag-free plans, no comfort
    pass-through, five cold-start solves, the obstacle margins' slack priced like the
    velocity bounds' (:data:`PLAIN_FIELDS`); ``overrides`` set any other field. What the
    twin's dense scene and speed goal were measured with and the RL policies were
    trained behind (``twin_filter_config``, ``asvtwin.rl.vec_env``,
    ``asvtwin.whatif.rollout.filter_config``; docs/psf.md, "The comfort bound by
    default")."""
    return PsfConfig(**{**PLAIN_FIELDS, **overrides})


def comfort_config(**overrides: Any) -> PsfConfig:
    """The comfort-first settings as first measured (2026-12-03): the thrusters' lag in
    the plans, the comfort pass-through, ``cold_start_solves=8`` (all three the defaults
    since 2026-12-07) and ``clearance_slack_weight=3`` (the defaults' 2);
    ``overrides`` set any other field.

    Kept for comparison: on the encounter set (acados, 2026-12-07) it holds the comfort
    bound as the defaults do (steered yaw 1.031 / 1.024 ν_max,r at model / full scale,
    against 1.032 / 1.017), but in ``benchmarks/psf.py``'s full-thrust corridor its
    call time p95 is 8–100 ms over seeds 0–4 (goal 5 ms; the defaults 0.2–0.3 ms) and
    it intervenes on 15–76 of 300 calls (0–3): docs/psf.md, "The comfort bound by
    default"."""
    fields: dict[str, Any] = {"model_actuator_lag": True, "comfort_pass_through": True,
                              "clearance_slack_weight": 3.0, "cold_start_solves": 8}
    fields.update(overrides)
    return PsfConfig(**fields)


@dataclass(frozen=True)
class ResolvedPsfConfig(PsfConfig):
    """A :class:`PsfConfig` as a filter uses it: ``dt_s`` resolved to a number [s]
    (``SafetyFilter.config``)."""

    dt_s: float = 0.5


@dataclass(frozen=True)
class ActiveConstraint:
    """A constraint at (or within the activity tolerance of) its bound.

    ``kind`` is ``"circle"``, ``"segment"``, ``"velocity"`` or ``"terminal_set"``;
    ``index`` the obstacle's index in the order given (circles: static then moving) or the
    velocity component; ``stage`` k; ``margin`` its value [m, m/s or 1]; ``time_s`` the
    stage's time ahead of the call [s]; ``label`` the obstacle's name ("track 2", "the
    coast").
    """

    kind: Literal["circle", "segment", "velocity", "terminal_set"]
    index: int
    stage: int
    margin: float
    time_s: float = float("nan")
    label: str = ""


@dataclass(frozen=True)
class FilterResult:
    """The filter's answer for one call, with its explanation.

    Attributes
    ----------
    u0 : ndarray, shape (3,)
        The safe input to apply [N, N, Nm].
    delta_u : ndarray, shape (3,)
        Intervention δ_u = u_L − u_0.
    x_pred, u_pred : ndarray, shapes (N+1, 6) and (N, 3)
        The plan behind ``u0`` (states simulated on the model from the current state).
    obstacle_margin_m : ndarray, shape (N+1,)
        Per stage, the smallest distance to an obstacle minus the required clearance
        (d_safe; at N d_safe + d_f √V_N for static obstacles and the coast, V_N =
        ν_Nᵀ P_f ν_N, the braking distance bound from the plan's end velocity; d_safe for
        moving ones) [m]; stage 0 is the current state.
    velocity_margin : ndarray, shape (N+1, 3)
        ν_max − |ν| per stage [m/s, m/s, rad/s] (soft bounds).
    terminal_margin : float
        1 − ν_Nᵀ P_f ν_N (≥ 0: inside the terminal ellipsoid).
    active : tuple of ActiveConstraint
        Constraints within the activity tolerance (the explanation of an intervention).
    success : bool
        The fresh plan was certified and used (``fallback == "none"``).
    status : str
        Solver status word (and the reason when not certified).
    iterations : int
        Solver iterations.
    solve_time_s : float
        Solver wall time [s].
    fallback : str
        ``"none"`` or the checked fallback candidate applied: ``"plan_tail"``,
        ``"solver_plan"``, ``"braking"``, ``"astern"``, ``"turn_starboard"``,
        ``"turn_port"`` (:class:`asvtwin.control.fallback.Fallback`).
    backend : str
        Backend name.
    critical : tuple of (north, east, radius)
        The binding obstacles at the stage where they bind (a moving one's *predicted*
        position), grown by d_safe [m]: the red region of the paper's figure.
    explanation : str
        What the filter did and why, for a navigator.
    reason : str
        Why the fresh plan was not used ("" when it was).
    critical_stages : tuple of int
        Stages of the applied plan within the activity tolerance of an obstacle.
    candidates : tuple of (kind, detail, closest approach [m], certified)
        Fallback candidates scored on this call (empty when none were needed).
    recovery : bool
        The own ship was within d_safe of an obstacle at the call (or inside its circle):
        plans were certified by the recovery rule (no margin decreases, all restored by
        the horizon's end).
    passed_through : bool
        u_L was kept because a plan starting with it was certified (no solve needed).
    u_L : ndarray, shape (3,)
        The learner's input as used: clipped to the actuator range (see ``explanation``).
    u_range : ndarray, shape (3,)
        Actuator range u_ub − u_lb [N, N, Nm] (for :attr:`intervened`).
    """

    u0: _F8
    delta_u: _F8
    x_pred: _F8
    u_pred: _F8
    obstacle_margin_m: _F8
    velocity_margin: _F8
    terminal_margin: float
    active: tuple[ActiveConstraint, ...]
    success: bool
    status: str
    iterations: int
    solve_time_s: float
    fallback: str
    backend: str
    critical: tuple[tuple[float, float, float], ...] = field(default=())
    explanation: str = ""
    reason: str = ""
    critical_stages: tuple[int, ...] = field(default=())
    candidates: tuple[tuple[str, str, float, bool], ...] = field(default=())
    recovery: bool = False
    passed_through: bool = False
    u_L: _F8 | None = None
    u_range: _F8 | None = None

    @cached_property
    def intervened(self) -> bool:
        """True when u_0 differs from the (range-clipped) u_L by more than 1 % of the
        actuator range in some actuated DOF (an unactuated DOF, range 0, never counts;
        without ``u_range``: |δu| > 0.01 in the input's units). Computed once per result
        (the result is frozen; the twin asks it at every snapshot)."""
        if self.u_range is None or self.u_L is None:
            return bool(np.max(np.abs(self.delta_u)) > 1e-2)
        rng = self.u_range
        d = np.abs(self.u_L - self.u0)
        return bool(np.any((rng > 0) & (d > 0.01 * rng)))
