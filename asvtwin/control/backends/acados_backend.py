"""acados backend: SQP-RTI with HPIPM on the same OCP (optional extra ``acados``).

acados comes from the PyPI package ``comma-deps-acados`` (its shared libraries, the
``acados_template`` Python interface and the ``t_renderer`` template tool). The solver's
C code is generated and compiled with gcc once per problem (:meth:`OcpSpec.key`) into the
cache directory and loaded from there afterwards: never rebuilt in a loop.

Pitfalls handled here (met with comma-deps-acados 0.2.2 and acados 0.2): the environment variables acados needs are set from
the ``acados`` module's paths; its libraries (which have no RPATH) are preloaded with
``RTLD_LOCAL``, which satisfies the generated solver's dependencies by their soname
without putting BLASFEO's and HPIPM's symbols into the process's global namespace (with
``RTLD_GLOBAL``, a torch linear layer run after the filter crashed in the same process); one-sided constraints get moderate finite upper bounds, never 1e9; the
QP status is checked by us, since RTI reports success whatever the QP did; and, because
one RTI step is not a converged solve, the filter re-simulates every plan on the model
(:class:`asvtwin.control.psf.SafetyFilter` does this for every backend) and the backend
runs extra RTI steps while the step is still large.
"""

from __future__ import annotations

import contextlib
import ctypes
import fcntl
import hashlib
import io
import json
import logging
import os
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from asvtwin.control.backends.acados_io import AcadosIO
from asvtwin.control.backends.base import RawSolution
from asvtwin.control.backends.ocp import (
    OcpSpec,
    cache_dir,
    continuous_dynamics,
    discrete_lagged_dynamics,
    input_scale,
    lag_states,
    path_constraints,
    terminal_constraints,
    velocity_slack_scale,
)
from asvtwin.errors import MissingExtraError, SolverError

__all__ = ["AcadosBackend", "acados_available"]

log = logging.getLogger(__name__)

#: Finite upper bound of the one-sided obstacle constraints [m] (with ±1e9 as "no bound" every QP hit
#: its iteration limit while SQP-RTI still reported success).
_H_UPPER = 1e5

# acados' SQP-RTI prints "SQP_RTI: QP solver returned error status …" with C printf on every
# failed QP (compiled into libacados unless built with ACADOS_SILENT; print_level does not
# reach it): thousands of lines an hour in a twin among 50 vessels. The failure is not lost:
# the QP status is in every result (RawSolution.status, FilterResult.status, the twin's
# snapshot and summary). The C stdout (fd 1) goes to /dev/null during solves only.
_SILENCE_LOCK = threading.Lock()
_SILENCE_DEPTH = 0
_SILENCE_SAVED: int | None = None
_LIBC: Any = None


def _flush_c_stdout() -> None:
    global _LIBC
    if _LIBC is None:
        try:
            _LIBC = ctypes.CDLL(None)
        except OSError:  # pragma: no cover - no C library to load
            _LIBC = False
    if _LIBC:
        _LIBC.fflush(None)


@contextlib.contextmanager
def _c_stdout_silenced() -> Iterator[None]:
    """fd 1 to /dev/null for the block (nested and threaded use share one redirect, kept
    while any block is open). Python's own buffer is flushed before, and the C library's
    buffer (acados' lines when stdout is a pipe) into /dev/null before fd 1 comes back.
    Where fd 1 cannot be duplicated (closed), the block runs as it is."""
    global _SILENCE_DEPTH, _SILENCE_SAVED
    with _SILENCE_LOCK:
        if _SILENCE_DEPTH == 0:
            try:
                sys.stdout.flush()
            except (AttributeError, ValueError, OSError):
                pass
            try:
                saved = os.dup(1)
            except OSError:
                saved = None
            if saved is not None:
                null = os.open(os.devnull, os.O_WRONLY)
                os.dup2(null, 1)
                os.close(null)
            _SILENCE_SAVED = saved
        _SILENCE_DEPTH += 1
    try:
        yield
    finally:
        with _SILENCE_LOCK:
            _SILENCE_DEPTH -= 1
            if _SILENCE_DEPTH == 0 and _SILENCE_SAVED is not None:
                _flush_c_stdout()
                os.dup2(_SILENCE_SAVED, 1)
                os.close(_SILENCE_SAVED)
                _SILENCE_SAVED = None


def _setup_environment() -> Any:
    """Import acados, set its environment variables and preload its libraries."""
    try:
        import acados  # type: ignore[import-not-found]
    except ImportError as exc:  # pragma: no cover - depends on the extra
        raise MissingExtraError("comma-deps-acados", "acados") from exc
    os.environ.setdefault("ACADOS_SOURCE_DIR", acados.DIR)
    os.environ.setdefault("ACADOS_PYTHON_INTERFACE_PATH", acados.TEMPLATE_DIR)
    os.environ.setdefault("TERA_PATH", acados.TERA_PATH)
    for lib in ("libblasfeo.so", "libhpipm.so", "libqpOASES_e.so", "libacados.so"):
        path = os.path.join(acados.LIB_DIR, lib)
        if os.path.exists(path):
            ctypes.CDLL(path, mode=ctypes.RTLD_LOCAL)
    if not ca.has_nlpsol("ipopt"):
        raise SolverError(
            "the casadi in this environment has no IPOPT: comma-deps-acados's slim casadi "
            "replaced the official wheel's files; restore it with: "
            "pip install --force-reinstall --no-deps casadi==3.8.2 "
            "(or 'make test', which does this after installing the acados extra)"
        )
    return acados


def solver_cache_key(solver_options: dict[str, Any], version: str, source_dir: str,
                     scale: NDArray[np.float64]) -> str:
    """The options part of a generated solver's cache folder name (8 hex digits).

    The generated code depends on the problem (the folder's other part), the solver
    options, the acados version, and the acados installation it was built against
    (``source_dir``, what ``ACADOS_SOURCE_DIR`` names): its ``acados_ocp.json`` records
    that installation's library path, and a cached solver loads ``libacados.so`` from
    there. Without the installation in the key, a second
    environment (another virtualenv, a fresh checkout's ``.venv``) reused the first's
    build and failed to load once that environment was gone ("libacados.so: cannot open
    shared object file", seen 2026-12-07 when a clean clone's CI venv was deleted)."""
    return hashlib.sha256(json.dumps(
        [solver_options, version, "inputs scaled", np.asarray(scale).tolist(),
         os.path.realpath(source_dir)], sort_keys=True
    ).encode()).hexdigest()[:8]


def acados_available() -> bool:
    """True when the ``acados`` extra is importable and casadi is still the full wheel."""
    try:
        _setup_environment()
    except (MissingExtraError, SolverError, OSError):
        return False
    return True


class AcadosBackend:
    """SQP-RTI (HPIPM) on the safety filter's OCP.

    Parameters
    ----------
    spec : OcpSpec
        The problem.
    rti_steps : int
        Largest number of RTI steps per call (more are run only while the primal step
        is larger than ``step_tol``).
    step_tol : float
        Infinity norm of the SQP step in the inputs, as a fraction of each actuator's
        bound, below which no further RTI step is taken.
    hpipm_mode : str
        HPIPM's mode (``"BALANCE"``, acados' default, ``"SPEED"``, ``"SPEED_ABS"`` or
        ``"ROBUST"``). ``"SPEED"`` cost about 30 % less CPU per solve in the RL world
        (model scale) with the same encounter-set results there, but more fallbacks at
        full scale (docs/psf.md, speed): the filter's default stays ``"BALANCE"``.
    qp_tol : float or None
        HPIPM's stopping tolerance on all four residuals (None: the mode's own; in
        BALANCE an explicit 1e-8 behaved alike). See
        :attr:`~asvtwin.control.PsfConfig.qp_tol`.
    """

    def __init__(self, spec: OcpSpec, *, rti_steps: int = 1, step_tol: float = 1e-3,
                 hpipm_mode: str = "BALANCE", qp_tol: float | None = None) -> None:
        acados = _setup_environment()
        from acados.acados_template import (  # type: ignore[import-not-found]
            AcadosModel,
            AcadosOcp,
            AcadosOcpSolver,
        )

        self.spec = spec
        self.name = "acados-rti"
        self.rti_steps = int(rti_steps)
        self.step_tol = float(step_tol)
        s = spec
        vessel = s.vessel
        f = continuous_dynamics(vessel)
        # the solver's inputs are scaled to O(1) (u = S·u_s, S the larger actuator bound):
        # in newtons and newton-metres the cost weights 1/range² are ~1e-12 for an 88 m
        # hull, and the QP's Levenberg-Marquardt term (1e-4 per unit²) then outweighed
        # the whole cost: each RTI step moved u by a few N·m and the full-scale solver
        # stood still (its plans were its warm starts)
        self._S = input_scale(s.u_lb, s.u_ub)
        nx = s.nx
        x = ca.SX.sym("x", nx)
        u = ca.SX.sym("u", 3)
        p = ca.SX.sym("p", s.n_p)
        xdot = ca.SX.sym("xdot", nx)
        model = AcadosModel()
        model.name = f"asvtwin_psf_{s.key()}"
        model.x, model.u, model.p, model.xdot = x, u, p, xdot
        if s.lag:  # eq. (a) with the thrusters' lag (the thrust a state): discrete
            model.disc_dyn_expr = discrete_lagged_dynamics(
                vessel, s.dt_s, s.rk4_substeps, self._S, s.actuator_tc)(x, u, p[0:3])
        else:
            model.f_expl_expr = f(x, ca.DM(self._S) * u, p[0:3])  # eq. (a), d̂ as parameter
            model.f_impl_expr = xdot - model.f_expl_expr
        model.con_h_expr = path_constraints(s)(x[0:6], p)  # eq. (e)
        model.con_h_expr_e = terminal_constraints(s)(x[0:6], p)  # eq. (f), (g)

        ocp = AcadosOcp()
        ocp.model = model
        ocp.dims.N = s.N
        ocp.parameter_values = np.zeros(s.n_p)
        # cost ‖u_k − u_L‖²_W: stage 0 full weight, later stages ε (set after creation)
        ocp.cost.cost_type = "LINEAR_LS"
        ocp.cost.cost_type_e = "LINEAR_LS"
        ocp.cost.Vx = np.zeros((3, nx))
        ocp.cost.Vu = np.eye(3)
        ocp.cost.W = np.diag(np.asarray(s.W) * self._S ** 2) * s.later_weight
        ocp.cost.yref = np.zeros(3)
        ocp.cost.Vx_e = np.zeros((0, nx))
        ocp.cost.W_e = np.zeros((0, 0))
        ocp.cost.yref_e = np.zeros(0)
        # eq. (d): hard input bounds
        ocp.constraints.lbu = np.asarray(s.u_lb, dtype=float) / self._S
        ocp.constraints.ubu = np.asarray(s.u_ub, dtype=float) / self._S
        ocp.constraints.idxbu = np.arange(3)
        ocp.constraints.x0 = np.zeros(nx)  # eq. (b)
        # eq. (c): soft velocity bounds on stages 1..N
        nu_max = np.asarray(s.nu_max, dtype=float)
        for suffix in ("", "_e"):
            setattr(ocp.constraints, "idxbx" + suffix, np.array([3, 4, 5]))
            setattr(ocp.constraints, "lbx" + suffix, -nu_max)
            setattr(ocp.constraints, "ubx" + suffix, nu_max)
            setattr(ocp.constraints, "idxsbx" + suffix, np.arange(3))
        nh, nh_e = s.n_h, s.n_h + 1
        ocp.constraints.lh = np.zeros(nh)
        ocp.constraints.uh = np.full(nh, _H_UPPER)
        ocp.constraints.idxsh = np.arange(nh)
        ocp.constraints.lh_e = np.zeros(nh_e)
        ocp.constraints.uh_e = np.full(nh_e, _H_UPPER)
        ocp.constraints.idxsh_e = np.arange(nh_e)
        ns, ns_e = 3 + nh, 3 + nh_e
        # the velocity slacks come first (idxsbx), priced per model-scale unit as the
        # CasADi backend's (ocp.velocity_slack_scale)
        fv = velocity_slack_scale(s)
        for suffix, n in (("", ns), ("_e", ns_e)):
            per_unit = np.concatenate([fv, np.ones(n - 3)])
            # the obstacle margins' L1 price ×clearance_slack_weight (not the ellipsoid's)
            l1 = s.slack_l1 * per_unit
            l1[3: 3 + nh] *= s.clearance_slack_weight
            setattr(ocp.cost, "zl" + suffix, l1)
            setattr(ocp.cost, "zu" + suffix, l1)
            setattr(ocp.cost, "Zl" + suffix, 2 * s.slack_l2 * per_unit**2)
            setattr(ocp.cost, "Zu" + suffix, 2 * s.slack_l2 * per_unit**2)

        opts = ocp.solver_options
        opts.tf = s.N * s.dt_s
        solver_options = {
            "integrator_type": "ERK",
            "sim_method_num_stages": 4,  # classic RK4, as the CasADi backend
            "sim_method_num_steps": s.rk4_substeps,
            "nlp_solver_type": "SQP_RTI",
            "hessian_approx": "GAUSS_NEWTON",
            "qp_solver": "PARTIAL_CONDENSING_HPIPM",
            "qp_solver_cond_N": max(1, s.N // 5),
            "qp_solver_iter_max": 100,
            "qp_solver_warm_start": 1,
            "levenberg_marquardt": 1e-4,
            "print_level": 0,
        }
        if hpipm_mode != "BALANCE":
            # (only a non-default mode enters the options, so the cache key of the
            # default solver, built before this option existed, stays the same)
            solver_options["hpipm_mode"] = hpipm_mode
        if s.lag:  # the stage map is disc_dyn_expr (RK4 written out, the lag exact)
            solver_options["integrator_type"] = "DISCRETE"
            del solver_options["sim_method_num_stages"], solver_options["sim_method_num_steps"]
        if qp_tol is not None:  # (likewise: only a set tolerance enters the cache key)
            for name in ("qp_solver_tol_stat", "qp_solver_tol_eq", "qp_solver_tol_ineq",
                         "qp_solver_tol_comp"):
                solver_options[name] = float(qp_tol)
        for name, value in solver_options.items():
            setattr(opts, name, value)

        # (_setup_environment set ACADOS_SOURCE_DIR: the installation acados records)
        opt_key = solver_cache_key(solver_options, getattr(acados, "__version__", ""),
                                   os.environ["ACADOS_SOURCE_DIR"], self._S)
        root = cache_dir() / f"acados_{s.key()}_{opt_key}"
        root.mkdir(parents=True, exist_ok=True)
        ocp.code_export_directory = str(root / "c_generated_code")
        json_file = str(root / "acados_ocp.json")
        done = root / "BUILD_COMPLETE"
        cwd = os.getcwd()
        t0 = time.perf_counter()
        # one builder at a time per folder (parallel test workers, several twins): the
        # others wait on the lock, then load what it built; a build that died half-way
        # left no BUILD_COMPLETE marker and is redone
        with open(root / ".lock", "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            fresh = not done.exists()
            try:
                os.chdir(root)  # acados writes helper files into the working directory
                with contextlib.redirect_stdout(io.StringIO()):
                    self._solver = AcadosOcpSolver(ocp, json_file=json_file,
                                                   generate=fresh, build=fresh,
                                                   verbose=False)
            except Exception as exc:
                raise SolverError(
                    f"building the acados solver in {root} failed: {exc}") from exc
            finally:
                os.chdir(cwd)
            if fresh:
                done.write_text(f"built in {time.perf_counter() - t0:.1f} s\n")
        if fresh:
            log.info("acados solver generated and compiled in %.1f s (%s)",
                     time.perf_counter() - t0, root)
        self._bind_fast_access(model.name)
        W0 = np.diag(np.asarray(s.W) * self._S ** 2)
        self._solver.cost_set(0, "W", W0)
        for k in range(1, s.N):
            self._solver.cost_set(k, "W", W0 * s.later_weight)

    def _bind_fast_access(self, model_name: str) -> None:
        """Bind the C entry points once (acados_template re-declares ``argtypes`` on every
        get/set call) and compile the numba loops that drive them (:mod:`.acados_io`)."""
        s = self.spec
        self._io = AcadosIO(self._solver, model_name, s.N, s.n_p, s.nx)
        self._lb = np.asarray(s.u_lb, dtype=float)
        self._ub = np.asarray(s.u_ub, dtype=float)
        # inputs of a call, reused (the loops need C-contiguous float64 buffers)
        self._x0 = np.zeros(s.nx)
        self._tau0 = np.zeros(3)  # the thrust produced now, scaled (lagged plans)
        self._yref = np.zeros(3)
        self._P = np.zeros((s.N + 1, s.n_p))
        self._Xg = np.zeros((s.N + 1, s.nx))
        self._Ug = np.zeros((s.N, 3))
        # compile (or load from numba's cache) the loops now, not in the first call; the
        # values set here are overwritten by every solve
        self._io.read()
        self._io.load(self._x0, self._yref, self._P, self._Xg, self._Ug)

    def solve(self, x0: NDArray[np.float64], u_L: NDArray[np.float64],
              stage_params: NDArray[np.float64], x_guess: NDArray[np.float64],
              u_guess: NDArray[np.float64]) -> RawSolution:
        """Up to ``rti_steps`` SQP-RTI steps; see :class:`~.base.Backend`."""
        io = self._io
        s = self.spec
        self._x0[:6] = x0  # eq. (b)
        np.divide(u_L, self._S, out=self._yref)
        self._P[:] = stage_params
        self._Xg[:, :6] = x_guess[:, :6]
        np.clip(u_guess, self._lb, self._ub, out=self._Ug)
        self._Ug /= self._S
        if s.lag:
            self._x0[6:] = self._tau0
            self._Xg[:, 6:] = lag_states(self._tau0, self._Ug, s.dt_s, s.actuator_tc)
        io.load(self._x0, self._yref, self._P, self._Xg, self._Ug)
        t0 = time.perf_counter()
        status, qp_status, iters = 0, 0, 0
        prev_u = self._Ug.copy()
        with _c_stdout_silenced():
            for _ in range(self.rti_steps):
                status = io.solve()
                iters += 1
                qp_status = self._qp_status() if status == 0 else status
                if status != 0 or qp_status != 0 or self.rti_steps == 1:
                    break
                U = io.read_u().copy()  # scaled: a fraction of the actuator bound
                step = float(np.max(np.abs(U - prev_u)))
                prev_u = U
                if step < self.step_tol:
                    break
        dt = time.perf_counter() - t0
        X, U = io.read()
        X = X[:, :6]
        U = U * self._S
        ok = status == 0 and qp_status == 0 and bool(np.all(np.isfinite(U)))
        word = "ok" if ok else f"acados status {status}, QP status {qp_status}"
        if not ok:
            # a failed QP leaves poisoned multipliers in the solver's iterate: every later
            # RTI step (of every filter sharing this backend) would fail too
            self._solver.reset()
        # slacks are not read back: the filter certifies the plan by simulation instead
        return RawSolution(x=X, u=U, max_slack=float("nan"), success=ok, status=word,
                           iterations=iters, solve_time_s=dt)

    def set_thrust(self, tau: NDArray[np.float64]) -> None:
        """The thrust the vessel produces now [N, N, Nm] (the lagged plan's τ at stage 0;
        ignored when the plan does not model the lag)."""
        np.divide(tau, self._S, out=self._tau0)

    def reset(self) -> None:
        """Zero the solver's iterate and multipliers (a new episode, or after a failure)."""
        self._solver.reset()

    def _qp_status(self) -> int:
        """Status of the last QP (0 ok); RTI reports success even when the QP did not."""
        stat = np.atleast_2d(self._io.statistics())
        return int(stat[1, -1]) if stat.shape[0] > 1 else 0
