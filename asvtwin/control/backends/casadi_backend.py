"""CasADi backend: the OCP as one multiple-shooting NLP, solved by IPOPT or fatrop.

Always available (casadi is a core dependency). The NLP is built once per
:class:`CasadiBackend`; every call only changes the bounds (x₀) and the parameter vector
(u_L and the stage parameters), and warm-starts the primal (and for IPOPT the dual)
variables from the caller's shifted guess. With ``codegen=True`` the NLP's functions are
generated as C, compiled once with gcc into the cache directory and loaded from there on
every later build (a few seconds the first time, milliseconds after).

Decision vector, stage by stage: ``[x_0, u_0, x_1, s_1, u_1, ..., x_N, s_N]`` with slacks
``s_k = [s_obstacles, s_velocity (3), (s_ellipsoid at N)]``.
"""

from __future__ import annotations

import logging
import shutil
import subprocess
import time
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from asvtwin.control.backends.base import RawSolution
from asvtwin.control.backends.ocp import (
    OcpSpec,
    cache_dir,
    discrete_dynamics,
    discrete_lagged_dynamics,
    input_scale,
    lag_states,
    path_constraints,
    terminal_constraints,
    velocity_slack_scale,
)
from asvtwin.errors import SolverError

__all__ = ["CasadiBackend"]

log = logging.getLogger(__name__)

_SOLVERS = ("ipopt", "fatrop")


class CasadiBackend:
    """IPOPT (or fatrop) on the safety filter's OCP.

    Parameters
    ----------
    spec : OcpSpec
        The problem.
    solver : {"ipopt", "fatrop"}
        The NLP solver of the official casadi wheel.
    codegen : bool
        Compile the NLP functions with gcc once and cache them on disk.
    max_iter : int
        Iteration limit.
    """

    def __init__(self, spec: OcpSpec, *, solver: str = "ipopt", codegen: bool = False,
                 max_iter: int = 200) -> None:
        if solver not in _SOLVERS:
            raise SolverError(f"casadi solver must be one of {_SOLVERS}, actually: {solver!r}")
        if not ca.has_nlpsol(solver):
            raise SolverError(
                f"casadi {ca.CasadiMeta.version()} has no NLP solver {solver!r} (a slim casadi, e.g. "
                "the one comma-deps-acados carries, may have replaced the official wheel: "
                "reinstall with pip install --force-reinstall casadi==3.8.2)"
            )
        self.spec = spec
        self.name = f"casadi-{solver}"
        self._solver_name = solver
        self._build(codegen, max_iter)
        self._tau0 = np.zeros(3)
        self._lam_x: NDArray[np.float64] | None = None
        self._lam_g: NDArray[np.float64] | None = None

    # ----------------------------------------------------------------------- building
    def _build(self, codegen: bool, max_iter: int) -> None:
        s = self.spec
        N, nh = s.N, s.n_h
        vessel = s.vessel
        nx = s.nx
        self._S = input_scale(s.u_lb, s.u_ub)
        F = (discrete_lagged_dynamics(vessel, s.dt_s, s.rk4_substeps, self._S,
                                      s.actuator_tc) if s.lag
             else discrete_dynamics(vessel, s.dt_s, s.rk4_substeps))
        H = path_constraints(s)
        HN = terminal_constraints(s)
        W = ca.DM(np.diag(s.W))
        nu_max = ca.DM(s.nu_max)
        fv = ca.DM(velocity_slack_scale(s))
        # inputs scaled to O(1), u = S·u_s (as the acados backend): in newtons and
        # newton-metres an 88 m hull's cost gradient is ~1e-6, below IPOPT's tolerances
        S = ca.DM(self._S)

        P = ca.SX.sym("P", 9 + (N + 1) * s.n_p)
        uL = P[6:9]  # P[0:6] holds x0 for the record; x0 is fixed through the bounds

        def pk(k: int) -> ca.SX:
            a = 9 + k * s.n_p
            return P[a:a + s.n_p]

        w, lbw, ubw = [], [], []
        g, lbg, ubg = [], [], []
        J: ca.SX = ca.SX(0)
        self._ix: list[slice] = []
        self._iu: list[slice] = []
        self._is: list[slice] = []
        off = 0

        def var(name: str, n: int, lb: list[float], ub: list[float]) -> tuple[ca.SX, slice]:
            nonlocal off
            v = ca.SX.sym(name, n)
            w.append(v)
            lbw.extend(lb)
            ubw.extend(ub)
            sl = slice(off, off + n)
            off += n
            return v, sl

        inf = np.inf
        Xs, Ss, Us = [], [], []
        for k in range(N + 1):
            Xk, sl = var(f"x{k}", nx, [-inf] * nx, [inf] * nx)  # x_0 fixed per call, eq. (b)
            Xs.append(Xk)
            self._ix.append(sl)
            if k >= 1:
                ns = nh + 3 + (1 if k == N else 0)
                Sk, sl = var(f"s{k}", ns, [0.0] * ns, [inf] * ns)
                Ss.append(Sk)
                self._is.append(sl)
                # L1 on every slack, the obstacle margins' (the first nh) priced
                # ×clearance_slack_weight; a small L2 for conditioning
                J += (s.slack_l1 * (ca.sum1(Sk) + (s.clearance_slack_weight - 1.0)
                                    * ca.sum1(Sk[0:nh])) + s.slack_l2 * ca.sumsqr(Sk))
            if k < N:
                Uk_s, sl = var(f"u{k}", 3, list(np.asarray(s.u_lb) / self._S),
                               list(np.asarray(s.u_ub) / self._S))  # eq. (d), hard
                Uk = S * Uk_s  # the physical input
                Us.append(Uk_s if s.lag else Uk)  # (the lagged model takes the scaled one)
                self._iu.append(sl)
                du = Uk - uL
                J += (1.0 if k == 0 else s.later_weight) * ca.mtimes([du.T, W, du])
        # Constraints stage by stage, dynamics first (the order fatrop's detection needs).
        for k in range(N + 1):
            if k < N:
                # eq. (a): multiple-shooting continuity
                g.append(Xs[k + 1] - F(Xs[k], Us[k], pk(k)[0:3]))
                lbg.extend([0.0] * nx)
                ubg.extend([0.0] * nx)
            if k >= 1:
                Sk = Ss[k - 1]
                if k == N:
                    hk = HN(Xs[k][0:6], pk(k)) + ca.vertcat(Sk[0:nh], Sk[-1])  # eq. (f), (g)
                else:
                    hk = H(Xs[k][0:6], pk(k)) + Sk[0:nh]  # eq. (e)
                g.append(hk)
                lbg.extend([0.0] * hk.shape[0])
                ubg.extend([inf] * hk.shape[0])
                sv = Sk[nh:nh + 3]
                nu = Xs[k][3:6]
                # eq. (c), soft, its slack in model-scale units
                g.append(ca.vertcat((nu_max - nu) * fv + sv, (nu_max + nu) * fv + sv))
                lbg.extend([0.0] * 6)
                ubg.extend([inf] * 6)
        nlp = {"x": ca.vertcat(*w), "f": J, "g": ca.vertcat(*g), "p": P}
        self._lbw = np.asarray(lbw, dtype=float)
        self._ubw = np.asarray(ubw, dtype=float)
        self._lbg = np.asarray(lbg, dtype=float)
        self._ubg = np.asarray(ubg, dtype=float)
        self._nw = off
        opts: dict[str, Any] = self._options(max_iter)
        if self._solver_name == "fatrop":
            opts["equality"] = [bool(a == b) for a, b in zip(lbg, ubg)]
        if codegen and self._solver_name == "ipopt" and shutil.which("gcc"):
            lib = self._compiled(nlp)
            self._solver = ca.nlpsol("psf", self._solver_name, str(lib), opts)  # type: ignore[arg-type]
        else:
            self._solver = ca.nlpsol("psf", self._solver_name, nlp, opts)  # type: ignore[arg-type]

    def _options(self, max_iter: int) -> dict[str, Any]:
        if self._solver_name == "ipopt":
            return {
                "print_time": False,
                "ipopt.print_level": 0,
                "ipopt.sb": "yes",
                "ipopt.max_iter": max_iter,
                "ipopt.tol": 1e-6,
                "ipopt.acceptable_tol": 1e-4,
                "ipopt.acceptable_iter": 5,
                "ipopt.mu_strategy": "adaptive",
                "ipopt.linear_solver": "mumps",
            }
        return {
            "print_time": False,
            "structure_detection": "auto",
            "fatrop.print_level": 0,
            "fatrop.max_iter": max_iter,
            "fatrop.tol": 1e-6,
            "fatrop.tol_acceptable": 1e-4,
        }

    def _compiled(self, nlp: dict) -> Path:
        """Generate the NLP's functions as C and compile them once (cached by spec hash)."""
        root = cache_dir() / f"casadi_{self._solver_name}_{self.spec.key()}_scaled"
        lib = root / "psf_nlp.so"
        if lib.exists():
            return lib
        root.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        gen = ca.nlpsol("psf_gen", "ipopt", nlp, {"print_time": False})
        src = root / "psf_nlp.c"
        gen.generate_dependencies("psf_nlp.c", {"with_header": False})
        Path("psf_nlp.c").replace(src)
        tmp = root / f"psf_nlp.{id(self)}.so"
        cmd = ["gcc", "-O1", "-fPIC", "-shared", str(src), "-o", str(tmp), "-lm"]
        try:
            subprocess.run(cmd, check=True, capture_output=True, timeout=600)
        except (subprocess.CalledProcessError, subprocess.TimeoutExpired) as exc:
            raise SolverError(f"compiling the safety filter NLP failed: {exc}") from exc
        tmp.replace(lib)  # atomic: concurrent builders never see a half-written library
        log.info("compiled %s in %.1f s", lib, time.perf_counter() - t0)
        return lib

    # ------------------------------------------------------------------------ solving
    def set_thrust(self, tau: NDArray[np.float64]) -> None:
        """The thrust the vessel produces now [N, N, Nm] (the lagged plan's τ at stage 0;
        ignored when the plan does not model the lag)."""
        self._tau0 = np.asarray(tau, dtype=float) / self._S

    def reset(self) -> None:
        """Nothing to forget: every solve starts from the primal guess it is given."""

    def solve(self, x0: NDArray[np.float64], u_L: NDArray[np.float64],
              stage_params: NDArray[np.float64], x_guess: NDArray[np.float64],
              u_guess: NDArray[np.float64]) -> RawSolution:
        """Solve once; see :class:`asvtwin.control.backends.base.Backend`."""
        s = self.spec
        lbw, ubw = self._lbw.copy(), self._ubw.copy()
        x0_full = np.concatenate([x0[:6], self._tau0]) if s.lag else x0
        lbw[self._ix[0]] = x0_full
        ubw[self._ix[0]] = x0_full
        w0 = np.zeros(self._nw)
        if s.lag:
            ug_s = np.clip(u_guess, s.u_lb, s.u_ub) / self._S
            x_guess = np.hstack([x_guess[:, :6],
                                 lag_states(self._tau0, ug_s, s.dt_s, s.actuator_tc)])
        for k in range(s.N + 1):
            w0[self._ix[k]] = x_guess[k]
        for k in range(s.N):
            w0[self._iu[k]] = np.clip(u_guess[k], s.u_lb, s.u_ub) / self._S
        p = np.concatenate([x0, u_L, stage_params.ravel()])
        args = {"x0": w0, "p": p, "lbx": lbw, "ubx": ubw, "lbg": self._lbg, "ubg": self._ubg}
        t0 = time.perf_counter()
        sol = self._solver(**args)
        dt = time.perf_counter() - t0
        stats = self._solver.stats()
        wopt = np.asarray(sol["x"]).ravel()
        X = np.stack([wopt[self._ix[k]][:6] for k in range(s.N + 1)])
        U = np.stack([wopt[self._iu[k]] for k in range(s.N)]) * self._S
        slack = max(float(np.max(wopt[sl])) for sl in self._is)
        status = str(stats.get("return_status", "unknown"))
        success = bool(stats.get("success", False)) or status in (
            "Solved_To_Acceptable_Level",
        )
        finite = bool(np.all(np.isfinite(wopt)))
        return RawSolution(
            x=X, u=U, max_slack=slack, success=success and finite, status=status,
            iterations=int(stats.get("iter_count", -1)), solve_time_s=dt,
        )
