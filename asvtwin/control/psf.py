"""The predictive safety filter: minimally correct any input so the vessel stays safe.

:class:`SafetyFilter` keeps the learner's input ``u_L`` when a plan that starts with it
is certified safe (≥ d_safe from every obstacle over the horizon, inside the terminal
ellipsoid P_f at its end and there ≥ d_safe + d_f √V_N from static obstacles and the coast,
d_f √V_N ≤ d_f being the braking distance bound from the plan's end velocity, V_N =
ν_Nᵀ P_f ν_N); otherwise it solves the paper's OCP
(a)-(g) (:mod:`asvtwin.control.backends.ocp`) for the closest such input in the W-norm.

Every plan, the learner's or a backend's, is *re-simulated* on the model from the current
state and certified on the simulated states before use: this covers SQP-RTI's one-QP
answers and any solver that claims more than it did. When no fresh plan is certified the
filter scores its fallback candidates (the last plan's tail, the solver's best effort,
braking, astern, hard turns either way; :mod:`asvtwin.control.fallback`) against the
obstacles known *now* and applies the best; the raw input is never passed through.
Inside d_safe (or inside an obstacle's circle) the filter does not raise: plans are then
certified by a *recovery* rule (no obstacle margin decreases and all are restored by the
horizon's end).
"""

from __future__ import annotations

import dataclasses
import logging
import math
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.checks import check_vector
from asvtwin.control.backends import (
    Backend,
    RawSolution,
    available_backends,
    backend_lock,
    claim_backend,
    make_backend,
)
from asvtwin.control.backends.ocp import SMOOTH_ABS_EPS, OcpSpec
from asvtwin.control.certification import TERM_TOL, Certifier
from asvtwin.control.colreg import EncounterLimits, classify_encounters
from asvtwin.control.explain import describe_cause, describe_change, describe_obstacle
from asvtwin.control.fallback import (
    BackupPlan,
    Candidate,
    Fallback,
    Scored,
    candidate_inputs,
    damp_yaw,
    plan_tail,
    select_candidate,
)
from asvtwin.control.kernels import rollout, rollout_governed, rollout_lagged, warm_up
from asvtwin.control.obstacles import (
    Obstacles,
    obstacle_labels,
    stage_circles,
    stage_spread,
)
from asvtwin.control.result import (
    CS2_LENGTH_M,
    ActiveConstraint,
    FilterResult,
    PsfConfig,
    ResolvedPsfConfig,
)
from asvtwin.control.slots import SolverSlots
from asvtwin.control.terminal_set import TerminalSet, compute_terminal_set
from asvtwin.errors import ConfigError, SolverError, StateError
from asvtwin.vessel.kernels import hydrodynamic_force_abs
from asvtwin.vessel.params import VesselParams

__all__ = ["COMFORT_TOL", "ActiveConstraint", "FilterResult", "PsfConfig", "SafetyFilter"]

log = logging.getLogger(__name__)
COMFORT_TOL = 0.05  # a plan within 5 % of the yaw-rate bound ν_max,r counts as within it


def actuator_lag(params: VesselParams) -> tuple[float, float, float]:
    """The thrusters' time constants [s] a plan models: ``time_constant_s`` when all
    three are finite and > 0, else zeros (no lag: the thrust is the command)."""
    tc = tuple(float(t) for t in params.actuators.time_constant_s)
    if len(tc) == 3 and all(math.isfinite(t) and t > 0 for t in tc):
        return (tc[0], tc[1], tc[2])
    return (0.0, 0.0, 0.0)


class SafetyFilter:
    """Predictive safety filter for one vessel (build once per process, call every step).

    Parameters
    ----------
    params : VesselParams
        The vessel: the same coefficients as the simulator's (actuator lag is not
        modelled: the plan's stages are much longer than the thruster time constant).
        Its actuator bounds are the OCP's input bounds, astern thrust included.
    config : PsfConfig
        Settings; ``self.config`` holds them resolved (``dt_s`` a number).

    Raises
    ------
    ConfigError
        A horizon N·Δt shorter than the braking time from top speed into the terminal
        set (the plan could never end safe), unbounded actuators, an unknown backend.

    Examples
    --------
    >>> from asvtwin.control import SafetyFilter, PsfConfig, CircleObstacles
    >>> from asvtwin.vessel import cybership2
    >>> psf = SafetyFilter(cybership2(), config=PsfConfig(N=40, backend="casadi-ipopt"))
    >>> rock = CircleObstacles(centres=[[8.0, 0.0]], radii=[1.0])
    >>> res = psf.filter([0, 0, 0, 0.3, 0, 0], [2.0, 0, 0], rock, t_s=0.0)
    >>> res.fallback, res.intervened, "obstacle 0 ahead" in res.explanation
    ('none', True, True)
    """

    def __init__(self, params: VesselParams, *, config: PsfConfig | None = None) -> None:
        self.params = params
        cfg = config or PsfConfig()
        scale = params.length / CS2_LENGTH_M
        sq = math.sqrt(scale)
        # Froude similarity: times scale by √λ, so the horizon covers the same manoeuvre
        fields = {f.name: getattr(cfg, f.name) for f in dataclasses.fields(cfg)}
        fields["dt_s"] = cfg.dt_s if cfg.dt_s is not None else 0.5 * sq
        cfg = ResolvedPsfConfig(**fields)
        self.config: ResolvedPsfConfig = cfg
        self.d_safe_m = cfg.d_safe_m if cfg.d_safe_m is not None else params.length
        self.d_f_m = cfg.d_f_m if cfg.d_f_m is not None else 6.0 * params.length
        self.nu_max = np.asarray(cfg.nu_max if cfg.nu_max is not None
                                 else (2.0 * sq, 2.0 * sq, 0.15 / sq), dtype=float)
        self.certify_tol_m = (cfg.certify_tol_m if cfg.certify_tol_m is not None
                              else 0.02 * params.length)
        act = params.actuators
        self.u_lb = np.asarray(act.tau_min, dtype=float)
        self.u_ub = np.asarray(act.tau_max, dtype=float)
        if not (np.all(np.isfinite(self.u_lb)) and np.all(np.isfinite(self.u_ub))):
            raise ConfigError(f"the safety filter needs finite actuator bounds; vessel "
                              f"{params.name!r} has tau_min={act.tau_min}, "
                              f"tau_max={act.tau_max}")
        r_term = cfg.terminal_r_max if cfg.terminal_r_max is not None else 4 * self.nu_max[2]
        tau_r = min(abs(self.u_lb[2]), abs(self.u_ub[2]))
        k_r = tau_r / r_term if tau_r > 0 else 0.0
        self.terminal_set: TerminalSet = compute_terminal_set(
            params, d_f_m=self.d_f_m, nu_max=(self.nu_max[0], self.nu_max[1], r_term),
            k_r=k_r)
        self.u_range = self.u_ub - self.u_lb
        rng = self.u_range
        # eq. (W): W = diag(γ_i / (u_ub,i − u_lb,i)²); a fixed DOF (range 0) gets weight 0
        W = np.where(rng > 0, np.asarray(cfg.gamma) / np.where(rng > 0, rng, 1.0) ** 2, 0.0)
        self._W = W
        d = params.to_dict()
        d.pop("actuators")
        self.spec = OcpSpec(
            params=tuple(sorted(d.items())), N=cfg.N, dt_s=cfg.dt_s,
            n_circles=cfg.n_circles, n_segments=cfg.n_segments,
            u_lb=tuple(self.u_lb), u_ub=tuple(self.u_ub), nu_max=tuple(self.nu_max),
            W=(float(W[0]), float(W[1]), float(W[2])), later_weight=cfg.later_weight,
            slack_l1=cfg.slack_l1, slack_l2=cfg.slack_l2,
            yaw_slack_weight=cfg.yaw_slack_weight, P_f=tuple(self.terminal_set.P_f.ravel()),
            actuator_tc=actuator_lag(params) if cfg.model_actuator_lag else (0.0, 0.0, 0.0),
            clearance_slack_weight=cfg.clearance_slack_weight,
        )
        # constants of every call, computed once
        N, s = cfg.N, self.spec
        self._coef = np.ascontiguousarray(params.packed())  # the planning model's
        self._zero3 = np.zeros(3)
        self._tc = np.asarray(s.actuator_tc, dtype=float)  # (zeros: no lag modelled)
        self._tau_buf = np.empty((N + 1, 3))
        # the thrust the vessel produces at this call (lagged plans), and what the last
        # call applied: (t, thrust then, input applied)
        self._tau0: _F8 | None = None
        self._applied: tuple[float, _F8, _F8] | None = None
        self._cert = Certifier(N, self.d_safe_m, self.d_f_m, self.certify_tol_m,
                               self.terminal_set.P_f, float(self.u_range[0]))
        self._P_f = self._cert.P_f
        warm_up()
        self.braking_time_s = self._braking_time()
        horizon = N * cfg.dt_s
        if horizon < self.braking_time_s:
            raise ConfigError(
                f"PsfConfig: the horizon N·dt_s = {N} × {cfg.dt_s:g} s = {horizon:.1f} s is "
                f"shorter than the braking time of {params.name!r} from top speed into the "
                f"terminal set ({self.braking_time_s:.1f} s): no plan could end safe; raise N "
                f"or dt_s (default dt_s for this hull: {0.5 * sq:.2f} s)")
        self.backend = self._make_backend(cfg)
        self._slots = SolverSlots(s, params.length, self._cert)
        self._vel_tol = 0.01 * self.nu_max
        self._limits = EncounterLimits.for_length(params.length)
        self._plan: BackupPlan | None = None
        self._last: tuple[float, _F8, _F8] | None = None  # (t, x_pred, u_pred)
        self._solved_last = False  # the previous call ran the solver
        self._fallback_t: float | None = None  # time of the last call ended on a fallback
        self._t: float | None = None
        self._unsafe_t: float | None = None  # the last call at which u_L was not safe
        self._prefer_starboard = False  # COLREG expects starboard (per call)
        # the uncertified fallback manoeuvre applied at the last call (kind, detail)
        self._last_fallback: tuple[str, str] | None = None
        self._spread = np.zeros((self.config.N + 1, 0))  # stage_spread of the call
        self._token = object()  # this filter's claim on the shared solver (_own_backend)

    def _make_backend(self, cfg: PsfConfig) -> Backend:
        name = cfg.backend if cfg.backend != "auto" else available_backends()[0]
        opts: dict[str, object] = (
            {"rti_steps": cfg.rti_steps, "hpipm_mode": cfg.hpipm_mode, "qp_tol": cfg.qp_tol}
            if name == "acados" else {"max_iter": cfg.max_iter})
        try:
            return make_backend(name, self.spec, **opts)
        except SolverError as exc:
            if cfg.backend != "auto" or name == "casadi-ipopt":
                raise
            warnings.warn(
                f"safety filter: the acados backend cannot be built here ({exc}); using "
                "casadi-ipopt, ~30x slower per call. For the fast backend install gcc and "
                "make and the extra: pip install 'asvtwin[acados]'", RuntimeWarning,
                stacklevel=3)
            return make_backend("casadi-ipopt", self.spec, max_iter=cfg.max_iter)

    def _braking_time(self) -> float:
        """Time [s] from top speed (full ahead thrust, steady) to the terminal set by the
        braking backup (coasting, yaw damped), on the planning model."""
        dt = self.config.dt_s
        n = 400
        full = np.zeros((n, 3))
        full[:, 0] = self.u_ub[0]
        X = np.empty((n + 1, 6))
        rollout(np.zeros(6), full, self._zero3, self._coef, dt, 1, X)  # reach top speed
        x_top = np.zeros(6)
        x_top[3] = X[-1, 3]
        rollout(x_top, np.zeros((n, 3)), self._zero3, self._coef, dt, 1, X)
        V = np.einsum("ki,ij,kj->k", X[:, 3:], self._P_f, X[:, 3:])
        inside = np.flatnonzero(V <= 1.0)
        return float(inside[0] * dt) if inside.size else math.inf

    # --------------------------------------------------------------------- helpers
    def rollout(self, x0: ArrayLike, u: ArrayLike, d_hat: ArrayLike | None = None, *,
                tau0: ArrayLike | None = None) -> _F8:
        """States (N+1, 6) of the plan ``u`` (N, 3) from ``x0`` on the filter's model.

        The model is the solver's (eq. (a), RK4 per stage, smoothed |·|), evaluated by
        the compiled :func:`asvtwin.control.kernels.rollout`; with the thrusters' lag
        (``PsfConfig.model_actuator_lag``) by :func:`~asvtwin.control.kernels.
        rollout_lagged` from the thrust ``tau0`` [N, N, Nm] (default: the thrust of the
        current call, or ``u[0]`` outside a call).
        """
        N = self.config.N
        x0 = np.ascontiguousarray(x0, dtype=float)
        U = np.ascontiguousarray(u, dtype=float)
        if x0.shape != (6,) or U.shape != (N, 3):
            raise StateError(f"rollout needs x0 of shape (6,) and u of shape ({N}, 3), "
                             f"actually: {x0.shape} and {U.shape}")
        d = self._zero3 if d_hat is None else np.ascontiguousarray(d_hat, dtype=float)
        if d.shape != (3,):
            raise StateError(f"d_hat must have shape (3,), actually: {d.shape}")
        return self._roll(x0, U, d, tau0=None if tau0 is None
                          else np.asarray(tau0, dtype=float))

    def _roll(self, x0: _F8, U: _F8, d: _F8, *, tau0: _F8 | None = None,
              govern_to: int = 0) -> _F8:
        """:meth:`rollout` of checked, C-contiguous arrays; ``govern_to`` > 0 holds |r|
        at ν_max,r over the first stages (``U``'s yaw moments overwritten with those
        used, :func:`~asvtwin.control.kernels.rollout_governed`)."""
        X = np.empty((U.shape[0] + 1, 6))
        lag = self.spec.lag
        if not lag and govern_to == 0:
            rollout(x0, U, d, self._coef, self.config.dt_s, self.spec.rk4_substeps, X)
            return X
        t0 = tau0 if tau0 is not None else self._tau0
        t0 = np.ascontiguousarray(U[0] if t0 is None else t0, dtype=float)  # (outside a
        # call: no lag transient at the start)
        if govern_to == 0:
            rollout_lagged(x0, t0, U, d, self._coef, self.config.dt_s,
                           self.spec.rk4_substeps, self._tc, X, self._tau_buf)
        else:
            rollout_governed(x0, t0, U, d, self._coef, self.config.dt_s,
                             self.spec.rk4_substeps, self._tc, lag, float(self.nu_max[2]),
                             govern_to, X, self._tau_buf)
        return X

    def _own_backend(self) -> None:
        """Reset the shared solver when another filter solved on it last (call under the
        backend's lock; :func:`~asvtwin.control.backends.claim_backend`). Without it the
        scenario library's harbour approach reached its goal run alone and missed it after
        the ferry crossing had run in the same process (2026-12-01)."""
        if claim_backend(self.backend, self._token):
            self.backend.reset()

    def reset(self) -> None:
        """Forget the last plan and the solver's iterate (new episode)."""
        self._plan, self._last, self._t = None, None, None
        self._unsafe_t = None
        self._tau0, self._applied = None, None
        self._solved_last = False
        self._fallback_t = None
        self._last_fallback = None
        with backend_lock(self.backend):
            self.backend.reset()

    def _starboard_expected(self, x: _F8, centres: _F8, moving: NDArray[np.bool_],
                            ) -> tuple[bool, bool]:
        """Does a moving obstacle (classified from its predicted track) make COLREG
        expect an alteration to starboard: head-on (rule 14), crossing from starboard
        (15) or from port (17(c): not to port)? Returns (some vessel asks it: warm-start
        the solver to starboard; and besides, no vessel in sight is overtaking or being
        overtaken by geometry, whatever its CPA: rank the fallback candidates by side). Rule 13 leaves the side of an overtaking free; with
        the side forced, a path follower overtaking a slow vessel while meeting another
        was pushed round in circles (2 of 25 full-scale encounters missed their goal)."""
        if not (self.config.colreg and moving.any()) or centres.shape[0] < 2:
            return False, False
        idx = np.flatnonzero(moving)
        v = (centres[1, idx] - centres[0, idx]) / self.config.dt_s
        enc = classify_encounters(x, centres[0, idx], v, limits=self._limits)
        stb = bool(enc.starboard_expected.any())
        return stb, stb and not any(k in ("overtaking", "overtaken") for k in enc.geometry)

    def _colreg_guess(self, u_L: _F8) -> _F8:
        """A starboard-turn input guess (for a head-on or crossing vessel)."""
        N = self.config.N
        U = np.zeros((N, 3))
        U[:, 0] = u_L[0]
        U[: max(1, N // 3), 2] = self.u_ub[2]
        return U

    # ------------------------------------------------------------------------ filter
    def filter(self, x: ArrayLike, u_L: ArrayLike, obstacles: Obstacles | None = None,
               d_hat: ArrayLike | None = None, *, t_s: float | None = None,
               tau: ArrayLike | None = None) -> FilterResult:
        """The safe input for state ``x`` and learner input ``u_L``.

        Parameters
        ----------
        x : array_like, shape (6,)
            Own state ``[x, y, ψ, u, v, r]`` [m, m, rad, m/s, m/s, rad/s], NED.
        u_L : array_like, shape (3,)
            The learner's input [N, N, Nm]; clipped to the actuator range (said in the
            explanation).
        obstacles : CircleObstacles, MovingObstacles, CoastSegments or a sequence
            What to keep clear of (moving ones predicted over the N+1 stage times).
        d_hat : array_like, shape (3,), optional
            Disturbance estimate τ̂_d [N, N, Nm], body frame, held over the horizon.
        t_s : float, optional
            Time of ``x`` [s]; default: one stage after the previous call.
        tau : array_like, shape (3,), optional
            The thrust the vessel produces now [N, N, Nm], where the caller knows it.
            Default: what the filter's own last output has become by ``t_s`` through
            the thrusters' first-order lag (at the first call: the thrust that holds
            the present velocity); used only when
            the plans model the lag (``PsfConfig.model_actuator_lag``).

        Raises
        ------
        StateError
            Malformed input only: NaN/inf or wrong shapes in ``x``, ``u_L``, ``d_hat``
            or the obstacles, a non-positive radius. An obstacle that contains the own
            ship, or a solver that raises, still returns an input (recovery, fallback).
        """
        cfg, N, dt = self.config, self.config.N, self.config.dt_s
        x = check_vector(x, 6, "state x", ("x", "y", "psi", "u", "v", "r"))
        u_given = check_vector(u_L, 3, "learner input u_L", ("tau_u", "tau_v", "tau_r"))
        d = np.zeros(3) if d_hat is None else check_vector(d_hat, 3, "disturbance d_hat",
                                                        ("tau_u", "tau_v", "tau_r"))
        if t_s is None:
            t_s = 0.0 if self._t is None else self._t + dt
        elif not math.isfinite(t_s):
            raise StateError(f"t_s must be finite, actually: {t_s}")
        self._t = float(t_s)
        uL = np.clip(u_given, self.u_lb, self.u_ub)
        self._tau0 = self._thrust_now(t_s, x, tau)
        notes = []
        if not np.array_equal(uL, u_given):
            notes.append(f"u_L {np.round(u_given, 4).tolist()} outside the actuator range "
                         f"[{self.u_lb.tolist()}, {self.u_ub.tolist()}], clipped")
        centres, radii, segs = stage_circles(obstacles, N)
        self._spread = stage_spread(obstacles, radii)  # (for the fallback's ranking)
        labels, moving = obstacle_labels(obstacles)
        # static columns, and the braking credit (fading with the disturbance estimate)
        self._cert.start_call(moving, segs.shape[0], d)
        if moving.any():
            # eq. (f) asks d_safe + d_f at stage N so that braking stops short of a *static*
            # obstacle; a vessel's motion beyond the horizon is unknown, and keeping d_f
            # from its predicted end point traps the own ship alongside it: d_safe only
            radii[N, moving] -= self.d_f_m
        # 1. a plan starting with u_L: the shifted last plan, or coasting with yaw damped
        tries = self._learner_plans(x, uL, t_s)
        first = None
        # a plan that keeps u_L safely but turns faster than the comfort bound: kept
        # back while the solver looks for a gentler one, applied if it finds none
        brisk: tuple | None = None
        for U in tries:
            X = self.rollout(x, U, d)
            margins, low, term, finite = self._cert.margins(X, centres, radii, segs)
            m0 = margins[0]
            ok, why, path_low = self._cert.judge(margins, low, term, finite, m0, strict=True)
            if first is None:
                first = (X, margins, term, why)
            if (ok and cfg.comfort_pass_through and self._in_avoidance(t_s)
                    and not self._comfortable(X)):
                if brisk is None:
                    brisk = (U, X, margins, term)
                continue
            if ok:
                return self._pass_through(x, uL, u_given, U, X, margins, term, centres,
                                          radii, segs, labels, moving, first, notes, t_s)
        assert first is not None
        if brisk is None:  # no plan kept u_L safely: an avoidance (see _in_avoidance)
            self._unsafe_t = t_s
        X_L, margins_L, _, _ = first
        m0 = margins_L[0]
        # 2. the OCP, warm-started from the last solver plan (COLREG: from a starboard turn)
        xg, ug = self._guess(x, uL, d, t_s)
        warm_stb, self._prefer_starboard = self._starboard_expected(x, centres, moving)
        if warm_stb and ug[: max(1, N // 3), 2].sum() <= 0:
            cand = Candidate(Fallback.TURN_STARBOARD, "colreg", self._colreg_guess(uL),
                             max(1, N // 3))
            xg, ug = self._simulate(x, cand, d)
        P, _, _ = self._slots.fill(x, d, centres, radii, segs, [X_L[:, :2], xg[:, :2]],
                                     xg[-1, 3:], moving)
        # warm: 1 solve; after calls that kept u_L without a solve the iterate is stale: 2;
        # cold (no plan at all): cold_start_solves (RTI: one QP each)
        attempts = (1 if self._solved_last else min(2, cfg.cold_start_solves)
                    ) if self._last is not None else cfg.cold_start_solves
        iters, t_solve, status, solver_why = 0, 0.0, "", ""
        best: tuple | None = None  # (X, U, margins, term, certified, why, path_low)
        scored: list[tuple[str, str, float, bool]] = []
        rows: list[tuple] = []  # fallback candidates scored in this call
        chosen_kind, chosen_detail = Fallback.NONE, ""
        # a fallback streak: the previous call fell back too, within this plan's horizon.
        # This call's solve is warm-started from that call's plan (from its best
        # candidate when the solver's own plan cut into d_safe): it is that call's retry
        prev_fb = self._fallback_t
        in_streak = prev_fb is not None and 0.0 < t_s - prev_fb < N * dt
        retries = 0 if (in_streak and not cfg.retry_in_streak) else cfg.uncertified_retries

        def _certified(U: _F8) -> bool:
            X_ = self.rollout(x, U, d)
            mg, lo, tm, fin = self._cert.margins(X_, centres, radii, segs)
            return self._cert.judge(mg, lo, tm, fin, m0)[0]

        for rnd in range(1 + retries):
            for _ in range(attempts):
                self._slots.set_terminal(xg[-1, 3:])  # exact where the guess ends
                try:
                    with backend_lock(self.backend):  # shared per process: one at a time
                        self._own_backend()
                        raw = self._solve(x, uL, P, xg, ug, retry=rnd > 0,
                                          certified=_certified)
                    U = np.clip(raw.u, self.u_lb, self.u_ub)
                    status, ok = raw.status, raw.success
                    iters += raw.iterations
                    t_solve += raw.solve_time_s
                except Exception as exc:  # noqa: BLE001 - any solver failure ends in the fallback
                    U, status, ok = ug, f"solver error: {type(exc).__name__}: {exc}", False
                    raw = None
                X = self.rollout(x, U, d)  # certify on the model, not on the solver's claim
                margins, low, term, finite = self._cert.margins(X, centres, radii, segs)
                cert, why, path_low = self._cert.judge(margins, low, term, finite, m0)
                if not ok:
                    cert, why = False, f"solver failed ({status})"
                if raw is not None and ok and np.isfinite(raw.x).all():
                    self._last = (t_s, raw.x, U)  # the next warm start, certified or not
                    xg, ug = raw.x, U
                best = (X, U, margins, term, cert, why, path_low)
                solver_why = why
                if cert:
                    break
            self._solved_last = True
            if brisk is not None and not (best is not None and best[4]
                                          and self._comfortable(best[0])):
                # the solver found no gentler certified plan: keep u_L (certified)
                notes.append("the plan that keeps u_L turns faster than the comfort bound "
                             f"({float(np.max(np.abs(brisk[1][2:, 5]))):.3g} rad/s against "
                             f"{float(self.nu_max[2]):.3g}); no gentler certified plan found")
                U_b, X_b, m_b, term_b = brisk
                return self._pass_through(x, uL, u_given, U_b, X_b, m_b, term_b, centres,
                                          radii, segs, labels, moving, first, notes, t_s,
                                          solved=True, iters=iters, t_solve=t_solve)
            if best is not None and best[4]:
                chosen_kind = Fallback.NONE
                gentle = (self._gentler_tail(x, t_s, d, centres, radii, segs, m0, best[0])
                          if cfg.comfort_pass_through else None)
                if gentle is not None:  # safe, then comfortable, then minimal
                    note, best = gentle
                    notes.append(note)
                    self._last = (t_s, best[0], best[1])  # warm-start the next from it
                break
            # 3. checked fallback candidates, scored against the obstacles known now
            solver_u = best[1] if best is not None and np.all(np.isfinite(best[1])) else None
            solver_low = best[6] if best is not None else -math.inf
            pick, scored = self._choose(x, uL, t_s, d, centres, radii, segs, m0, solver_u,
                                        rows)
            chosen_kind, chosen_detail = pick[0], pick[1]
            best = tuple(pick[2:9])
            if solver_u is None or (solver_low < 0 <= best[6]):
                # the solver is in a bad basin (its plan cuts into d_safe, or failed):
                # re-initialise it from the best candidate; otherwise let SQP continue
                xg, ug = best[0], best[1]
                self._last = (t_s, xg, ug)
            if not ok and in_streak and not cfg.retry_failed_solves:
                break  # a QP that did not converge, within a streak: a retry rarely certifies
            attempts = 1
        assert best is not None
        X, U, margins, term, cert, why, _ = best
        if cert:
            self._plan = BackupPlan(u=U, x=X, t0_s=t_s, dt_s=dt)
        self._fallback_t = None if chosen_kind is Fallback.NONE else t_s
        reason = "" if chosen_kind is Fallback.NONE else f"solver: {solver_why}"
        self._last_fallback = (None if chosen_kind is Fallback.NONE or cert
                               else (chosen_kind.value, chosen_detail.split("; ")[0]))
        return self._result(x, uL, u_given, U[0].copy(), X, U, margins, term, centres,
                            radii, segs, labels, moving, cert, status, reason, iters,
                            t_solve, chosen_kind, first, tuple(scored), notes,
                            detail=chosen_detail)

    def _gentler_tail(self, x: _F8, t_s: float, d: _F8, centres: _F8, radii: _F8,
                      segs: _F8, m0: _F8, X_new: _F8) -> tuple | None:
        """The last certified plan's remainder, when the solver's new certified plan
        ``X_new`` turns faster than the comfort bound and the remainder, re-simulated
        and certified against the obstacles known now, does not: (note, best) or None.
        A certified plan, not a fallback (``fallback == "none"``); the note says so. An
        RTI step can jump from a plan that holds the bound to another local answer that
        turns at twice it; the plan it left is still safe."""
        r_ok = max(float(self.nu_max[2]) * (1.0 + COMFORT_TOL), abs(float(x[5])))
        if self._plan is None or float(np.max(np.abs(X_new[1:, 5]))) <= r_ok:
            return None
        tail = plan_tail(self._plan, t_s, self.config.N)
        if tail is None:
            return None
        X, U = self._simulate(x, tail, d)
        if float(np.max(np.abs(X[1:, 5]))) > r_ok:
            return None
        margins, low, term, finite = self._cert.margins(X, centres, radii, segs)
        cert, why, path_low = self._cert.judge(margins, low, term, finite, m0)
        if not cert:
            return None
        note = (f"the last certified plan kept (from t = {self._plan.t0_s:.1f} s): the "
                f"solver's new plan turns at {float(np.max(np.abs(X_new[1:, 5]))):.3g} "
                f"rad/s, faster than the comfort bound {float(self.nu_max[2]):.3g}")
        return note, (X, U, margins, term, cert, why, path_low)

    def _thrust_now(self, t_s: float, x: _F8, tau: ArrayLike | None) -> _F8 | None:
        """The thrust produced at ``t_s`` [N, N, Nm] (lagged plans; None otherwise): the
        caller's ``tau``, else the last call's output followed through the lag since
        then, else (a first call) the thrust that holds the present velocity ``x[3:6]``
        against the hull's damping and Coriolis forces (steady state), clipped to the
        actuators' range."""
        if not self.spec.lag:
            return None
        if tau is not None:
            return np.clip(check_vector(tau, 3, "thrust tau", ("tau_u", "tau_v", "tau_r")),
                           self.u_lb, self.u_ub)
        if self._applied is None:  # the thrust that holds the present velocity
            u, v, r = (float(z) for z in x[3:6])
            e = SMOOTH_ABS_EPS
            held = hydrodynamic_force_abs(u, v, r, math.sqrt(u * u + e), math.sqrt(v * v + e),
                                          math.sqrt(r * r + e), self._coef)
            return np.clip(np.asarray(held, dtype=float), self.u_lb, self.u_ub)
        t_a, tau_a, u_a = self._applied
        a = np.exp(-max(t_s - t_a, 0.0) / self._tc)
        return u_a + (tau_a - u_a) * a

    def _solve(self, x: _F8, uL: _F8, P: _F8, xg: _F8, ug: _F8, *, retry: bool,
               certified: Callable[[_F8], bool] | None = None) -> RawSolution:
        """One backend solve. A retry of an SQP-RTI backend runs the SQP towards
        convergence: up to ``retry_rti_steps`` single steps, until one changes the inputs
        by less than 0.1 % of their range (its single step from a plan that was not
        certified often overshoots the nonlinear terminal constraints, and the next
        call's step overshoots back). ``certified(U)`` judges each iterate: the last
        iterate is returned when it is certified, else the last certified one on the way
        (the SQP has no globalisation: its iterates need not improve monotonically), else
        the last."""
        b: Any = self.backend  # the acados backend's rti_steps is not in the protocol
        if self._tau0 is not None and hasattr(b, "set_thrust"):
            b.set_thrust(self._tau0)
        steps = getattr(b, "rti_steps", None)
        if not retry or steps is None or self.config.retry_rti_steps <= steps:
            return b.solve(x, uL, P, xg, ug)
        b.rti_steps = 1
        iters, t_solve = 0, 0.0
        kept: RawSolution | None = None  # the last certified iterate
        ok = False
        span = np.where(self.u_range > 0, self.u_range, 1.0)  # (no sway thruster: 0)
        try:
            for _ in range(self.config.retry_rti_steps):
                raw = b.solve(x, uL, P, xg, ug)
                iters += raw.iterations
                t_solve += raw.solve_time_s
                ok = False
                if not raw.success or not np.isfinite(raw.x).all():
                    break
                U = np.clip(raw.u, self.u_lb, self.u_ub)
                ok = certified is not None and certified(U)
                if ok:
                    kept = raw
                if float(np.max(np.abs(U - ug) / span)) < 1e-3:
                    break  # converged
                xg, ug = raw.x, U
        finally:
            b.rti_steps = steps
        if kept is not None and not ok:
            raw = kept
        return dataclasses.replace(raw, iterations=iters, solve_time_s=t_solve)

    def _pass_through(self, x: _F8, uL: _F8, u_given: _F8, U: _F8, X: _F8, margins: _F8,
                      term: float, centres: _F8, radii: _F8, segs: _F8, labels: list[str],
                      moving: NDArray[np.bool_], first: tuple, notes: list[str], t_s: float,
                      *, solved: bool = False, iters: int = 0,
                      t_solve: float = 0.0) -> FilterResult:
        """Apply u_L, certified by the plan ``U`` that starts with it."""
        self._plan = BackupPlan(u=U, x=X, t0_s=t_s, dt_s=self.config.dt_s)
        self._fallback_t = None
        self._last_fallback = None
        if not solved:
            self._last = (t_s, X, U)
        self._solved_last = solved
        return self._result(x, uL, u_given, uL.copy(), X, U, margins, term, centres, radii,
                            segs, labels, moving, True, "u_L certified", "", iters, t_solve,
                            Fallback.NONE, first, (), notes, passed=True)

    def _in_avoidance(self, t_s: float) -> bool:
        """Whether an avoidance is on: u_L was not safe at a call within the last
        horizon N·Δt. Only then does the comfort pass-through hold back a brisk but
        certified u_L (a learner turning faster than ν_max,r in open water is its own
        business: holding its yaw there is the intervention the filter must not make)."""
        if self._unsafe_t is None:
            return False
        return 0.0 <= t_s - self._unsafe_t < self.config.N * self.config.dt_s

    def _comfortable(self, X: _F8) -> bool:
        """Whether the plan after u_L's step turns no faster than the comfort bound
        ν_max,r (5 % tolerance), or than u_L's step left the ship turning."""
        if X.shape[0] < 3:
            return True
        r_ok = max(float(self.nu_max[2]) * (1.0 + COMFORT_TOL), abs(float(X[1, 5])))
        return float(np.max(np.abs(X[2:, 5]))) <= r_ok

    def _learner_plans(self, x: _F8, uL: _F8, t_s: float) -> list[_F8]:
        """Input sequences that start with u_L: u_L then the last plan's remainder, and
        u_L then coasting with the yaw rate damped."""
        N = self.config.N
        out = []
        if self._plan is not None:
            i = self._plan.index_at(t_s)
            if 0 <= i < N - 1:
                U = np.zeros((N, 3))
                rest = self._plan.u[i + 1:]
                U[1: 1 + len(rest)] = rest
                U[0] = uL
                out.append(U)
        U = np.zeros((N, 3))
        U[0] = uL
        out.append(U)
        return out

    def _simulate(self, x: _F8, c: Candidate, d: _F8) -> tuple[_F8, _F8]:
        """States and inputs of a candidate, its yaw damping filled in (two passes)."""
        U = c.u.copy()
        X = self._roll(x, U, d, govern_to=c.govern_to)
        if c.damp_from < U.shape[0]:
            k_r = self.terminal_set.k_r
            for _ in range(2):
                damp_yaw(U, X, k_r, self.u_lb[2], self.u_ub[2], c.damp_from)
                X = self.rollout(x, U, d)
        return X, U

    def _choose(self, x: _F8, uL: _F8, t_s: float, d: _F8, centres: _F8, radii: _F8,
                segs: _F8, m0: _F8, solver_u: _F8 | None, rows: list) -> tuple[tuple, list]:
        """Score every candidate and pick one (:func:`~asvtwin.control.fallback.
        select_candidate`). Returns (kind, detail, X, U, margins, term, certified, why,
        closest) and the scores (kind, detail, closest [m], certified). ``rows`` holds
        the candidates scored earlier in this call (a retry adds only its new solver
        plan)."""
        if rows:
            cands = [Candidate(Fallback.SOLVER_PLAN, "best effort after retry",
                               np.clip(solver_u, self.u_lb, self.u_ub), self.config.N)
                     ] if solver_u is not None else []
        else:
            cands = candidate_inputs(self.params, x, t_s, self.config.N, self._plan,
                                     solver_u, governed=self.config.comfort_pass_through)
        for c in cands:
            X, U = self._simulate(x, c, d)
            margins, low, term, finite = self._cert.margins(X, centres, radii, segs)
            cert, why, path_low = self._cert.judge(margins, low, term, finite, m0)
            dist = float(np.sum(self._W * (U[0] - uL) ** 2))
            rows.append(Scored(c.kind, c.detail, X, U, margins, term, cert, why, path_low,
                               dist))
        return select_candidate(
            rows, x, m0, self._cert, length_m=self.params.length,
            r_comfort=float(self.nu_max[2]) * (1.0 + COMFORT_TOL),
            prefer_starboard=self._prefer_starboard, previous=self._last_fallback,
            spread=self._spread)

    def _guess(self, x: _F8, u_L: _F8, d: _F8, t_s: float) -> tuple[_F8, _F8]:
        """Primal guess: the last plan shifted to ``t_s`` (its last stage repeated), or a
        coasting plan that starts with u_L."""
        N = self.config.N
        if self._last is not None:
            t0, X, U = self._last
            i = round((t_s - t0) / self.config.dt_s)
            if 0 <= i < N:
                Ug = np.empty((N, 3))
                Ug[: N - i] = U[i:]
                Ug[N - i:] = U[-1]
                Xg = np.empty((N + 1, 6))
                Xg[: N + 1 - i] = X[i:]
                Xg[N + 1 - i:] = X[-1]
                Xg[0] = x
                return Xg, Ug
        Ug = np.zeros((N, 3))
        Ug[0] = np.clip(u_L, self.u_lb, self.u_ub)
        Ug[1:, 2] = np.clip(-self.terminal_set.k_r * x[5], self.u_lb[2], self.u_ub[2])
        return self.rollout(x, Ug, d), Ug

    def _result(self, x: _F8, uL: _F8, u_given: _F8, u0: _F8, X: _F8, U: _F8, margins: _F8,
                term: float, centres: _F8, radii: _F8, segs: _F8, labels: list[str],
                moving: NDArray[np.bool_], certified: bool, status: str, reason: str,
                iters: int, t_solve: float, fb: Fallback, first: tuple,
                scored: tuple, notes: list[str], *, passed: bool = False,
                detail: str = "") -> FilterResult:
        N, dt = self.config.N, self.config.dt_s
        if self._tau0 is not None and self._t is not None:
            self._applied = (self._t, self._tau0, u0.copy())
        m = centres.shape[1]
        tol = 0.05 * self.params.length
        seg_label = "the coast"
        names = labels + [seg_label] * segs.shape[0]
        d_rel = np.abs(uL - u0)
        intervened = bool(np.any((self.u_range > 0) & (d_rel > 0.01 * self.u_range)))
        recovery = bool(margins.shape[1] and margins[0].min() < 0)
        active: list[ActiveConstraint] = []
        critical: list[tuple[float, float, float]] = []
        crit_stages: set[int] = set()
        if margins.shape[1]:
            ks, js = np.nonzero(margins[1:] <= tol)
            for k, j in zip((ks + 1).tolist(), js.tolist()):
                crit_stages.add(k)
                if intervened:
                    v = float(margins[k, j])
                    if j < m:
                        active.append(ActiveConstraint("circle", j, k, v, k * dt, names[j]))
                    else:
                        active.append(ActiveConstraint("segment", j - m, k, v, k * dt,
                                                       names[j]))
            # the binding circles at the stage where they bind (predicted positions)
            for j in sorted({j for j in js.tolist() if j < m}):
                k = int(np.argmin(margins[1:, j])) + 1
                critical.append((float(centres[k, j, 0]), float(centres[k, j, 1]),
                                 float(radii[k, j] + self.d_safe_m)))
        vel = self.nu_max - np.abs(X[:, 3:])
        if intervened:
            ks, js = np.nonzero(vel[1:] <= self._vel_tol)
            active.extend(ActiveConstraint("velocity", j, k + 1, float(vel[k + 1, j]),
                                           (k + 1) * dt) for k, j in zip(ks.tolist(),
                                                                         js.tolist()))
            if term <= 0.02:
                active.append(ActiveConstraint("terminal_set", 0, N, term, N * dt))
        obst = margins.min(axis=1) if margins.shape[1] else np.full(N + 1, np.inf)
        # the explanation: cause (from the plan that starts with u_L), change, what it keeps
        _, margins_L, term_L, _ = first
        keeps = (float(np.min(obst[1:-1] + self.d_safe_m)) if margins.shape[1] else math.inf)
        words: list[str] = []
        if passed or not intervened:
            if margins.shape[1]:
                j = int(np.argmin(margins[0]))
                near = describe_obstacle(j, x, labels, moving, centres, radii, segs, dt)
                words.append(f"no intervention; nearest: {near}")
            else:
                words.append("no intervention; no obstacle known")
        else:
            end_clear = self.d_safe_m + self._cert.terminal_requirement(first[0][-1, 3:])
            words.append(describe_cause(x, margins_L, term_L, labels, moving, centres, radii,
                                        segs, dt, self.d_safe_m, self.d_f_m, TERM_TOL,
                                        end_clear_m=end_clear))
            words.append(describe_change(uL, u0, self.u_lb, self.u_ub))
        if fb is not Fallback.NONE:
            best_alt = ", ".join(f"{k} {c:.1f} m" for k, _, c, _ in scored[:4])
            words.append(f"no certified plan ({reason}); fallback {fb.value} ({detail})"
                         f"{'' if certified else ', not certified'}; candidates: {best_alt}")
        if math.isfinite(keeps) and margins.shape[1]:
            words.append(f"the plan keeps ≥ {keeps:.1f} m")
        if recovery:
            words.append(f"inside d_safe now ({float(margins[0].min()) + self.d_safe_m:.1f} m "
                         "from an obstacle): recovering")
        words.extend(notes)
        return FilterResult(
            u0=u0, delta_u=u_given - u0, x_pred=X, u_pred=U, obstacle_margin_m=obst,
            velocity_margin=vel, terminal_margin=term, active=tuple(active),
            success=bool(certified and fb is Fallback.NONE), status=status,
            iterations=int(iters), solve_time_s=float(t_solve), fallback=fb.value,
            backend=self.backend.name, critical=tuple(critical),
            explanation="; ".join(words), reason=reason,
            critical_stages=tuple(sorted(crit_stages)), candidates=scored,
            recovery=recovery, passed_through=passed, u_L=uL, u_range=self.u_range,
        )
