"""The predictive safety filter: minimally correct any input so the vessel stays safe.

:class:`SafetyFilter` solves the paper's OCP (a)-(g) (see
:mod:`asvtwin.control.backends.ocp`) once per call: the learner's input ``u_L`` is kept
if some plan that starts with it keeps ≥ d_safe from every obstacle over the horizon and
ends in the terminal set (≥ d_safe + d_f from obstacles, velocity in the braking
ellipsoid P_f); otherwise the closest such input in the W-norm is returned.

Every plan a backend returns is *re-simulated* on the model from the current state and
certified on the simulated states before use: this covers SQP-RTI's one-QP answers and
any solver that claims more than it did. An uncertified call falls back to the tail of
the last certified plan, then to the braking backup (:mod:`asvtwin.control.fallback`);
the raw input is never passed through.
"""

from __future__ import annotations

import logging
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from asvtwin.control.backends import available_backends, make_backend
from asvtwin.control.backends.ocp import DUMMY_DISTANCE_FACTOR, OcpSpec
from asvtwin.control.fallback import BackupPlan, Fallback, backup_input
from asvtwin.control.kernels import certify, rollout, warm_up
from asvtwin.control.obstacles import CoastSegments, Obstacles, stage_circles
from asvtwin.control.result import CS2_LENGTH_M, ActiveConstraint, FilterResult, PsfConfig
from asvtwin.control.terminal_set import TerminalSet, compute_terminal_set
from asvtwin.errors import ConfigError, StateError
from asvtwin.vessel.params import VesselParams

__all__ = ["ActiveConstraint", "FilterResult", "PsfConfig", "SafetyFilter"]

log = logging.getLogger(__name__)
_F8 = NDArray[np.float64]


def _validate(a: ArrayLike | None, n: int, what: str, fields: tuple[str, ...]) -> _F8:
    arr = np.asarray(a, dtype=float)
    if arr.shape != (n,):
        raise StateError(f"{what} must have shape ({n},), actually: {arr.shape}")
    bad = ~np.isfinite(arr)
    if bad.any():
        j = int(np.argmax(bad))
        raise StateError(f"{what} has non-finite {fields[j]}: {arr[j]}")
    return arr


class SafetyFilter:
    """Predictive safety filter for one vessel (build once per process, call every step).

    Parameters
    ----------
    params : VesselParams
        The vessel: the same coefficients as the simulator's (actuator lag is not
        modelled: the plan's stages are much longer than the thruster time constant).
    config : PsfConfig
        Settings.

    Examples
    --------
    >>> from asvtwin.control import SafetyFilter, PsfConfig, CircleObstacles
    >>> from asvtwin.vessel import cybership2
    >>> psf = SafetyFilter(cybership2(), config=PsfConfig(N=20, backend="casadi-ipopt"))
    >>> rock = CircleObstacles(centres=[[12.0, 0.0]], radii=[1.0])
    >>> res = psf.filter([0, 0, 0, 0.3, 0, 0], [2.0, 0, 0], rock, t_s=0.0)
    >>> res.fallback, bool(res.u0[0] < 1.0), res.intervened  # thrust cut, turn started
    ('none', True, True)
    """

    def __init__(self, params: VesselParams, *, config: PsfConfig | None = None) -> None:
        self.params = params
        self.config = cfg = config or PsfConfig()
        scale = params.length / CS2_LENGTH_M
        sq = math.sqrt(scale)
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
        rng = self.u_ub - self.u_lb
        # eq. (W): W = diag(γ_i / (u_ub,i − u_lb,i)²); a fixed DOF (range 0) gets weight 0
        W = np.where(rng > 0, np.asarray(cfg.gamma) / np.where(rng > 0, rng, 1.0) ** 2, 0.0)
        d = params.to_dict()
        d.pop("actuators")
        self.spec = OcpSpec(
            params=tuple(sorted(d.items())), N=cfg.N, dt_s=cfg.dt_s,
            n_circles=cfg.n_circles, n_segments=cfg.n_segments,
            u_lb=tuple(self.u_lb), u_ub=tuple(self.u_ub), nu_max=tuple(self.nu_max),
            W=(float(W[0]), float(W[1]), float(W[2])), later_weight=cfg.later_weight,
            slack_l1=cfg.slack_l1, slack_l2=cfg.slack_l2,
            P_f=tuple(self.terminal_set.P_f.ravel()),
        )
        name = cfg.backend if cfg.backend != "auto" else available_backends()[0]
        opts: dict[str, object] = ({"rti_steps": cfg.rti_steps} if name == "acados"
                                   else {"max_iter": cfg.max_iter})
        self.backend = make_backend(name, self.spec, **opts)
        # constants of every call, computed once
        N, s = cfg.N, self.spec
        self._coef = np.ascontiguousarray(params.packed())  # the planning model's
        self._zero3 = np.zeros(3)
        self._clear = np.full(N + 1, self.d_safe_m)
        self._clear[N] += self.d_f_m  # eq. (f)
        self._P_f = np.ascontiguousarray(self.terminal_set.P_f)
        far = DUMMY_DISTANCE_FACTOR * params.length
        self._P = np.zeros((N + 1, s.n_p))  # stage parameters, rewritten every call
        self._P[:, 3] = self._clear
        self._circ = self._P[:, 4: 4 + 3 * s.n_circles].reshape(N + 1, s.n_circles, 3)
        if not np.shares_memory(self._circ, self._P):  # pragma: no cover - numpy layout
            raise AssertionError("the circle slots must be a view of the stage parameters")
        self._dummy_circle = np.stack([np.full(s.n_circles, far),
                                       far * (1 + 0.01 * np.arange(s.n_circles))], axis=1)
        self._dummy_segment = np.array([-far, -far, -far, -far + 1.0])
        self._vel_tol = 0.01 * self.nu_max
        warm_up()
        self._plan: BackupPlan | None = None
        self._last: tuple[float, _F8, _F8] | None = None  # (t, x_pred, u_pred)
        self._t: float | None = None
        self._dropped_logged = False

    # --------------------------------------------------------------------- helpers
    def rollout(self, x0: ArrayLike, u: ArrayLike, d_hat: ArrayLike | None = None) -> _F8:
        """States (N+1, 6) of the plan ``u`` (N, 3) from ``x0`` on the filter's model.

        The model is the solver's (eq. (a), RK4 per stage, smoothed |·|), evaluated by
        the compiled :func:`asvtwin.control.kernels.rollout`.
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
        X = np.empty((N + 1, 6))
        rollout(x0, U, d, self._coef, self.config.dt_s, self.spec.rk4_substeps, X)
        return X

    def reset(self) -> None:
        """Forget the last plan and the solver's iterate (new episode)."""
        self._plan, self._last, self._t = None, None, None
        self.backend.reset()

    def _stage_params(self, x: _F8, d_hat: _F8, centres: _F8, radii: _F8, segs: _F8,
                      ) -> tuple[_F8, NDArray[np.intp], NDArray[np.intp]]:
        """Stage parameters (N+1, n_p) (an internal buffer: backends copy it) and the
        indices of the circles and segments that got a slot."""
        s = self.spec
        m, k = centres.shape[1], segs.shape[0]
        ci = np.arange(m)
        if m > s.n_circles:  # keep the circles that come nearest over the horizon
            gap = np.linalg.norm(centres - x[None, None, :2], axis=2) - radii
            ci = np.sort(np.argsort(gap.min(axis=0))[: s.n_circles])
        si = np.arange(k)
        if k > s.n_segments:
            dist = CoastSegments(segs).distances(x[None, :2])[0]
            si = np.sort(np.argsort(dist)[: s.n_segments])
        if (m > s.n_circles or k > s.n_segments) and not self._dropped_logged:
            log.warning("safety filter: %d circles / %d segments given, using the nearest "
                        "%d / %d (raise PsfConfig.n_circles / n_segments)", m, k,
                        s.n_circles, s.n_segments)
            self._dropped_logged = True
        P = self._P  # column 3 (clearance, eq. (e)/(f)) is constant
        P[:, 0:3] = d_hat
        nc, used = s.n_circles, len(ci)
        circ = self._circ  # a view of P's circle slots
        if used < nc:  # far-away dummies in the unused slots
            circ[:, used:, 0:2] = self._dummy_circle[used:] + x[:2]
            circ[:, used:, 2] = self.params.length
        if used:
            sel = slice(None) if m <= nc else ci
            circ[:, :used, 0:2] = centres[:, sel]
            circ[:, :used, 2] = radii[:, sel]
        if s.n_segments:
            sg = np.empty((s.n_segments, 4))
            sg[len(si):] = self._dummy_segment + x[[0, 1, 0, 1]]
            sg[: len(si)] = segs[si]
            P[:, 4 + 3 * nc:] = sg.ravel()
        return P, ci, si

    def _certify(self, X: _F8, centres: _F8, radii: _F8, segs: _F8,
                 ) -> tuple[_F8, float, float, bool]:
        """Per-stage obstacle margins (N+1, m + k) [m] against the required clearance
        (d_safe; d_safe + d_f at N, eq. (e)/(f)), their minimum over stages 1..N (+inf
        without obstacles, NaN when a margin is NaN), the terminal margin
        1 − ν_Nᵀ P_f ν_N (eq. (g)) and whether every state is finite."""
        out = np.empty((X.shape[0], centres.shape[1] + segs.shape[0]))
        low, term, finite = certify(X, np.ascontiguousarray(centres),
                                    np.ascontiguousarray(radii), np.ascontiguousarray(segs),
                                    self._clear, self._P_f, out)
        return out, float(low), float(term), bool(finite)

    # ------------------------------------------------------------------------ filter
    def filter(self, x: ArrayLike, u_L: ArrayLike, obstacles: Obstacles | None = None,
               d_hat: ArrayLike | None = None, *, t_s: float | None = None) -> FilterResult:
        """The safe input for state ``x`` and learner input ``u_L``.

        Parameters
        ----------
        x : array_like, shape (6,)
            Own state ``[x, y, ψ, u, v, r]`` [m, m, rad, m/s, m/s, rad/s], NED.
        u_L : array_like, shape (3,)
            The learner's input [N, N, Nm].
        obstacles : CircleObstacles, MovingObstacles, CoastSegments or a sequence
            What to keep clear of (moving ones predicted over the N+1 stage times).
        d_hat : array_like, shape (3,), optional
            Disturbance estimate τ̂_d [N, N, Nm], body frame, held over the horizon.
        t_s : float, optional
            Time of ``x`` [s]; default: one stage after the previous call.

        Raises
        ------
        StateError
            NaN/inf in ``x``, ``u_L`` or ``d_hat``; a non-positive radius; an obstacle
            that contains the own ship's position.
        """
        cfg, N = self.config, self.config.N
        x = _validate(x, 6, "state x", ("x", "y", "psi", "u", "v", "r"))
        u_L = _validate(u_L, 3, "learner input u_L", ("tau_u", "tau_v", "tau_r"))
        d = np.zeros(3) if d_hat is None else _validate(d_hat, 3, "disturbance d_hat",
                                                        ("tau_u", "tau_v", "tau_r"))
        if t_s is None:
            t_s = 0.0 if self._t is None else self._t + cfg.dt_s
        elif not math.isfinite(t_s):
            raise StateError(f"t_s must be finite, actually: {t_s}")
        self._t = float(t_s)
        centres, radii, segs = stage_circles(obstacles, N)
        if centres.shape[1]:
            gap0 = np.linalg.norm(centres[0] - x[:2], axis=1) - radii[0]
            i = int(np.argmin(gap0))
            if gap0[i] < 0:
                raise StateError(
                    f"obstacle circle {i} (centre {centres[0, i].tolist()} m, radius "
                    f"{radii[0, i]:.3f} m) contains the own ship at {x[:2].tolist()}: "
                    f"distance to its edge {gap0[i]:.3f} m, expected >= 0")
        P, ci, si = self._stage_params(x, d, centres, radii, segs)
        xg, ug = self._guess(x, u_L, d, t_s)
        # a cold start (no previous plan) gets a few solves to converge (RTI: one QP each)
        attempts = 1 if self._last is not None else cfg.cold_start_solves
        iters, t_solve = 0, 0.0
        for _ in range(attempts):
            try:
                raw = self.backend.solve(x, u_L, P, xg, ug)
                U = np.clip(raw.u, self.u_lb, self.u_ub)
                status, ok = raw.status, raw.success
                iters += raw.iterations
                t_solve += raw.solve_time_s
            except RuntimeError as exc:  # a solver crash is a failed solve, not a crash
                U, status, ok = ug, f"solver error: {exc}", False
            X = self.rollout(x, U, d)  # certify on the model, not on the solver's claim
            margins, low, term, finite = self._certify(X, centres, radii, segs)
            obst_ok = low >= -self.certify_tol_m  # False for NaN, True without obstacles
            certified = ok and obst_ok and term >= -0.05 and finite
            if ok and np.isfinite(raw.x).all():
                self._last = (t_s, raw.x, U)  # the next warm start, certified or not
                xg, ug = raw.x, U
            if certified:
                break
        if certified:
            u0, fb = U[0].copy(), Fallback.NONE
            self._plan = BackupPlan(u=U, x=X, t0_s=t_s, dt_s=cfg.dt_s)
        else:
            why = ("solver failed" if not ok else "plan violates obstacle clearance"
                   if not obst_ok else "plan ends outside the terminal set")
            status = f"{status}; not certified: {why}"
            u0, fb = backup_input(self.params, x, t_s, self._plan, self.terminal_set.k_r)
            if fb is Fallback.PLAN_TAIL and self._plan is not None:
                _, ut = self._plan.tail(t_s)
                U = np.zeros((N, 3))  # the tail, then no input
                U[: len(ut)] = ut
            else:
                U = np.empty((N, 3))
                U[:] = u0
            X = self.rollout(x, U, d)
            margins, _, term, _ = self._certify(X, centres, radii, segs)
        return self._result(x, u_L, u0, X, U, margins, term, ci, si, centres, radii,
                            certified, status, iters, t_solve, fb)

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

    def _result(self, x: _F8, u_L: _F8, u0: _F8, X: _F8, U: _F8, margins: _F8, term: float,
                ci: NDArray[np.intp], si: NDArray[np.intp], centres: _F8, radii: _F8,
                certified: bool, status: str, iters: int, t_solve: float, fb: Fallback,
                ) -> FilterResult:
        N = self.config.N
        m = centres.shape[1]
        tol = 0.05 * self.params.length
        active: list[ActiveConstraint] = []
        hit: set[int] = set()
        if margins.shape[1]:
            ks, js = np.nonzero(margins[1:] <= tol)
            if ks.size:
                vals = margins[1:][ks, js].tolist()
                for k, j, v in zip(ks.tolist(), js.tolist(), vals):
                    if j < m:
                        active.append(ActiveConstraint("circle", j, k + 1, v))
                        hit.add(j)
                    else:
                        active.append(ActiveConstraint("segment", j - m, k + 1, v))
        vel = self.nu_max - np.abs(X[:, 3:])
        ks, js = np.nonzero(vel[1:] <= self._vel_tol)
        if ks.size:
            vals = vel[1:][ks, js].tolist()
            active.extend(ActiveConstraint("velocity", j, k + 1, v)
                          for k, j, v in zip(ks.tolist(), js.tolist(), vals))
        if term <= 0.02:
            active.append(ActiveConstraint("terminal_set", 0, N, term))
        obst = margins.min(axis=1) if margins.shape[1] else np.full(N + 1, np.inf)
        critical = tuple((float(centres[0, j, 0]), float(centres[0, j, 1]),
                          float(radii[0, j] + self.d_safe_m)) for j in sorted(hit))
        return FilterResult(
            u0=u0, delta_u=u_L - u0, x_pred=X, u_pred=U, obstacle_margin_m=obst,
            velocity_margin=vel, terminal_margin=term, active=tuple(active),
            success=certified, status=status, iterations=int(iters),
            solve_time_s=float(t_solve), fallback=fb.value, backend=self.backend.name,
            critical=critical,
        )
