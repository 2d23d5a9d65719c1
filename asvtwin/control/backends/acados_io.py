"""Fast data exchange with a compiled acados OCP solver (the acados backend's hot path).

acados 0.2's Python interface sets and gets one stage and one field per C call; at
N = 50 a filter call needs about 300 of them (x/u guesses, yref, stage parameters, the
plan), which cost ~0.3 ms through ``ctypes`` alone, as much as a tenth of the QP. Here the
same C functions of ``libacados`` and of the generated solver library are called from one
numba-compiled loop per direction: :func:`load_stages` (guess, reference, parameters, x₀)
and :func:`read_plan`. Nothing is reimplemented: these are the calls
``AcadosOcpSolver.set``/``get``/``set_params_sparse`` make, without the per-call
``argtypes`` declarations and Python loops.

Pointers travel as 64-bit integers: the C prototypes below declare them ``int64`` (the
same register class as a pointer on every 64-bit ABI acados supports), so numba can call
them with addresses taken from numpy arrays (``arr.ctypes.data``) and from
``ctypes.create_string_buffer`` field names kept alive by :class:`AcadosIO`.
"""

from __future__ import annotations

import ctypes
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from asvtwin.errors import SolverError

__all__ = ["AcadosIO", "load_stages", "read_plan"]

_I64, _INT = ctypes.c_int64, ctypes.c_int
#: void ocp_nlp_out_set/get(config, dims, out, int stage, const char *field, void *value)
_OUT_FN = ctypes.CFUNCTYPE(None, _I64, _I64, _I64, _INT, _I64, _I64)
#: int ocp_nlp_cost/constraints_model_set(config, dims, in, int stage, field, value)
_IN_FN = ctypes.CFUNCTYPE(_INT, _I64, _I64, _I64, _INT, _I64, _I64)
#: int <model>_acados_update_params(capsule, int stage, double *value, int np)
_PARAM_FN = ctypes.CFUNCTYPE(_INT, _I64, _INT, _I64, _INT)
#: void ocp_nlp_get(config, solver, const char *field, void *value)
_GET_FN = ctypes.CFUNCTYPE(None, _I64, _I64, _I64, _I64)
#: int <model>_acados_solve(capsule)
_SOLVE_FN = ctypes.CFUNCTYPE(_INT, _I64)


@njit(cache=True)
def load_stages(out_set, cost_set, con_set, upd_p, ptrs, fields, x0, yref, P, Xg,
                Ug):  # pragma: no cover - compiled
    """Set x₀ bounds (eq. (b)), yref = u_L and parameters of every stage, and the primal
    guess. ``ptrs`` = [config, dims, out, in, capsule]; ``fields`` = addresses of
    b"x", b"u", b"yref", b"lbx", b"ubx". Returns the number of C calls that reported
    an error (0 when all succeeded)."""
    cfg, dims, out, nin, cap = ptrs[0], ptrs[1], ptrs[2], ptrs[3], ptrs[4]
    fx, fu, fy, flb, fub = fields[0], fields[1], fields[2], fields[3], fields[4]
    N = Ug.shape[0]
    n_p = P.shape[1]
    errors = 0
    errors += con_set(cfg, dims, nin, 0, flb, x0.ctypes.data) != 0
    errors += con_set(cfg, dims, nin, 0, fub, x0.ctypes.data) != 0
    y = yref.ctypes.data
    pb, xb, ub = P.ctypes.data, Xg.ctypes.data, Ug.ctypes.data
    sx = 8 * Xg.shape[1]  # bytes per stage's state
    for k in range(N):
        errors += cost_set(cfg, dims, nin, k, fy, y) != 0
        errors += upd_p(cap, k, pb + 8 * n_p * k, n_p) != 0
        out_set(cfg, dims, out, k, fx, xb + sx * k)
        out_set(cfg, dims, out, k, fu, ub + 24 * k)
    errors += upd_p(cap, N, pb + 8 * n_p * N, n_p) != 0
    out_set(cfg, dims, out, N, fx, xb + sx * N)
    return errors


@njit(cache=True)
def read_plan(out_get, ptrs, fields, X, U):  # pragma: no cover - compiled
    """The solver's states into ``X`` (N+1, nx) and inputs into ``U`` (N, 3)."""
    cfg, dims, out = ptrs[0], ptrs[1], ptrs[2]
    xb, ub = X.ctypes.data, U.ctypes.data
    sx = 8 * X.shape[1]
    N = U.shape[0]
    for k in range(N):
        out_get(cfg, dims, out, k, fields[0], xb + sx * k)
        out_get(cfg, dims, out, k, fields[1], ub + 24 * k)
    out_get(cfg, dims, out, N, fields[0], xb + sx * N)


@njit(cache=True)
def read_statistics(nlp_get, cfg, solver, names, ibuf, buf):  # pragma: no cover - compiled
    """``ocp_nlp_get`` of sqp_iter, stat_m, stat_n and the statistics table into ``buf``
    (flat, large enough for (stat_n + 1) x stat_m); returns (rows, cols) of the table as
    ``AcadosOcpSolver.get_stats("statistics")`` shapes it, or (-1, size) when ``buf`` is
    too small."""
    got = np.zeros(3, dtype=np.int64)
    for i in range(3):
        ibuf[0] = 0
        nlp_get(cfg, solver, names[i], ibuf.ctypes.data)
        got[i] = ibuf[0]
    cols = min(got[1], got[0] + 1)
    rows = got[2] + 1
    if rows * cols > buf.size:
        return -1, rows * got[1]
    buf[: rows * cols] = 0.0
    nlp_get(cfg, solver, names[3], buf.ctypes.data)
    return rows, cols


def _address(fn: Any) -> int:
    return int(ctypes.cast(fn, ctypes.c_void_p).value or 0)


class AcadosIO:
    """The C entry points of one ``AcadosOcpSolver`` bound once, with the buffers the
    numba loops read from and write to.

    Parameters
    ----------
    solver : AcadosOcpSolver
        The built solver (its ``shared_lib``, ``capsule`` and ``nlp_*`` pointers).
    model_name : str
        The acados model name (prefix of the generated functions).
    N, n_p : int
        Stages and parameters per stage.
    nx : int
        States per stage (6, or 9 with the thrust states of a lagged plan).
    """

    def __init__(self, solver: Any, model_name: str, N: int, n_p: int, nx: int = 6
                 ) -> None:
        lib = solver.shared_lib
        self._keep = solver  # the pointers below live as long as the solver
        self.out_set = _OUT_FN(_address(lib.ocp_nlp_out_set))
        self.out_get = _OUT_FN(_address(lib.ocp_nlp_out_get))
        self.cost_set = _IN_FN(_address(lib.ocp_nlp_cost_model_set))
        self.con_set = _IN_FN(_address(lib.ocp_nlp_constraints_model_set))
        self.upd_p = _PARAM_FN(_address(getattr(lib, f"{model_name}_acados_update_params")))
        self.nlp_get = _GET_FN(_address(lib.ocp_nlp_get))
        self.solve_fn = _SOLVE_FN(_address(getattr(lib, f"{model_name}_acados_solve")))
        ptrs = (solver.nlp_config, solver.nlp_dims, solver.nlp_out, solver.nlp_in,
                solver.capsule, solver.nlp_solver)
        vals = [p if isinstance(p, int) else _address(p) for p in ptrs]
        if not all(vals):
            raise SolverError("the acados solver has a NULL config/dims/out/in/capsule/"
                              "solver pointer: it was not created")
        self.ptrs = np.asarray(vals[:5], dtype=np.int64)
        self.capsule, self.nlp_config, self.nlp_solver = vals[4], vals[0], vals[5]
        names = (b"x", b"u", b"yref", b"lbx", b"ubx", b"sqp_iter", b"stat_m", b"stat_n",
                 b"statistics")
        self._names = {n: ctypes.create_string_buffer(n) for n in names}
        self.fields = np.asarray([ctypes.addressof(self._names[n]) for n in names[:5]],
                                 dtype=np.int64)
        self.N, self.n_p = N, n_p
        self.X = np.zeros((N + 1, nx))
        self.U = np.zeros((N, 3))
        self._i64 = np.zeros(1, dtype=np.int64)
        self.stat_fields = np.asarray([ctypes.addressof(self._names[n])
                                       for n in names[5:]], dtype=np.int64)
        self._stats = np.zeros(1)

    def load(self, x0: NDArray[np.float64], yref: NDArray[np.float64],
             P: NDArray[np.float64], Xg: NDArray[np.float64], Ug: NDArray[np.float64]
             ) -> None:
        """Everything a call changes, in one compiled loop (arrays C-contiguous float64)."""
        errors = load_stages(self.out_set, self.cost_set, self.con_set, self.upd_p,
                             self.ptrs, self.fields, x0, yref, P, Xg, Ug)
        if errors:
            raise SolverError(f"acados rejected {errors} of the per-stage settings "
                              f"(yref, parameters or x0 bounds)")

    def solve(self) -> int:
        """One call of the generated ``acados_solve`` (one SQP-RTI step); its status."""
        return int(self.solve_fn(self.capsule))

    def read(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Fresh copies of the solver's states (N+1, nx) and inputs (N, 3)."""
        read_plan(self.out_get, self.ptrs, self.fields, self.X, self.U)
        return self.X.copy(), self.U.copy()

    def read_u(self) -> NDArray[np.float64]:
        """The solver's inputs (N, 3) (a view of an internal buffer: copy to keep)."""
        read_plan(self.out_get, self.ptrs, self.fields, self.X, self.U)
        return self.U

    def statistics(self) -> NDArray[np.float64]:
        """The ``statistics`` table of the last solve, as ``get_stats("statistics")``
        returns it: shape (stat_n + 1, min(stat_m, sqp_iter + 1))."""
        rows, cols = read_statistics(self.nlp_get, self.nlp_config, self.nlp_solver,
                                     self.stat_fields, self._i64, self._stats)
        if rows < 0:  # first call, or a table larger than expected: grow and repeat
            self._stats = np.zeros(cols)
            rows, cols = read_statistics(self.nlp_get, self.nlp_config, self.nlp_solver,
                                         self.stat_fields, self._i64, self._stats)
        return self._stats[: rows * cols].reshape(rows, cols)
