"""The terminal velocity ellipsoid P_f of the safety filter, from a semidefinite program.

Constraint (g) of the paper's OCP asks ν_Nᵀ P_f ν_N ≤ 1 for an invariant set of the
velocity dynamics. Centred on cruise speed and sized only by the velocity bounds, the
published ellipsoid (Vaaler et al. 2023, hard-coded diag(0.25, 0.29, 24.5) around
cruise speed) says nothing about space. Here it is tied to the
terminal distance d_f of constraint (f): from every velocity in the ellipsoid, the
*braking backup* (no thrust, yaw rate damped by τ_r = −k_r r) keeps the velocity inside
the ellipsoid and the vessel comes to rest within d_f. So x_N in the terminal set plus
(f) d(p_N, O) ≥ d_safe + d_f keeps the vessel ≥ d_safe from static obstacles forever.

The SDP (Boyd et al. 1994, ch. 5): the braking velocity dynamics are a linear
differential inclusion ν̇ ∈ co{A_i ν}, A(θ) = −M⁻¹(C(ν) + D(ν) + K) with the Coriolis and
damping coefficients θ = (u, v, r, |u|, u², |v|, |r|) ranging over a box; with Q = P_f⁻¹

.. math::

    \\max \\log\\det Q \\;\\text{s.t.}\\; A_i Q + Q A_i^\\top + 2\\alpha Q \\preceq 0 \\;\\forall i,
    \\quad S Q S^\\top \\preceq (\\alpha d_f)^2 I, \\quad e_j^\\top Q e_j \\le \\bar\\nu_j^2,
    \\quad k_r^2 Q_{33} \\le \\tau_{r,max}^2

so V = νᵀP_fν decays at rate 2α and the horizontal speed ‖(u, v)‖ ≤ α d_f √V, whence the
braking distance ∫‖(u, v)‖dt ≤ d_f. α is chosen on a grid for the largest volume.
:func:`verify_invariance` checks the result on the nonlinear model by simulation from the
ellipsoid's boundary. Results are cached per vessel in the cache directory.
"""

from __future__ import annotations

import hashlib
import json
import logging
from dataclasses import dataclass
from itertools import product

import cvxpy as cp
import numpy as np
from numpy.typing import NDArray

from asvtwin.control.backends.ocp import cache_dir
from asvtwin.errors import ParameterError, SolverError
from asvtwin.vessel.model import rhs
from asvtwin.vessel.params import VesselParams

__all__ = ["TerminalSet", "braking_input", "compute_terminal_set", "verify_invariance"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TerminalSet:
    """The terminal ellipsoid {ν : νᵀ P_f ν ≤ 1} and the backup that keeps it invariant.

    Attributes
    ----------
    P_f : ndarray, shape (3, 3)
        Symmetric positive definite, in (u [m/s], v [m/s], r [rad/s]).
    alpha : float
        Guaranteed decay rate of √(νᵀP_fν) under the braking backup [1/s].
    d_f_m : float
        Braking distance bound [m] (constraint (f)'s d_f).
    k_r : float
        Yaw-rate feedback gain of the braking backup [Nm s/rad].
    semi_axes : ndarray, shape (3,)
        Largest |u|, |v| [m/s], |r| [rad/s] in the ellipsoid.
    """

    P_f: NDArray[np.float64]
    alpha: float
    d_f_m: float
    k_r: float
    semi_axes: NDArray[np.float64]

    def contains(self, nu: NDArray[np.float64], *, tol: float = 0.0) -> NDArray[np.bool_]:
        """νᵀ P_f ν ≤ 1 + tol for each row of ``nu`` (n, 3)."""
        nu = np.atleast_2d(nu)
        return np.einsum("ni,ij,nj->n", nu, self.P_f, nu) <= 1.0 + tol


def braking_input(params: VesselParams, x: NDArray[np.float64], k_r: float
                  ) -> NDArray[np.float64]:
    """The braking backup τ = [0, 0, −k_r r] (clipped to the yaw-moment bounds), (3,).

    No reverse thrust exists on the RL vessel (F_u ≥ 0), so braking means coasting with
    the yaw rate damped out.
    """
    act = params.actuators
    tau = np.array([0.0, 0.0, -k_r * float(x[5])])
    return np.clip(tau, np.maximum(act.tau_min, -1e300), np.minimum(act.tau_max, 1e300))


def _vertex_matrices(params: VesselParams, box: NDArray[np.float64], k_r: float
                     ) -> list[NDArray[np.float64]]:
    """A_i = −M⁻¹(C + D + K) at the 2⁷ vertices of the coefficient box."""
    p = params
    M = p.M
    Minv = np.linalg.inv(M)
    M23 = 0.5 * (M[1, 2] + M[2, 1])
    ub, vb, rb = box
    out = []
    ranges = [(-ub, ub), (-vb, vb), (-rb, rb), (0, ub), (0, ub * ub), (0, vb), (0, rb)]
    for u, v, r, au, uu, av, ar in product(*ranges):
        D = np.array([
            [-p.X_u - p.X_uu * au - p.X_uuu * uu, 0.0, 0.0],
            [0.0, -p.Y_v - p.Y_vv * av - p.Y_rv * ar, -p.Y_r - p.Y_vr * av - p.Y_rr * ar],
            [0.0, -p.N_v - p.N_vv * av - p.N_rv * ar, -p.N_r - p.N_vr * av - p.N_rr * ar],
        ])
        c13, c23 = -(M[1, 1] * v + M23 * r), M[0, 0] * u
        C = np.array([[0.0, 0.0, c13], [0.0, 0.0, c23], [-c13, -c23, 0.0]])
        K = np.diag([0.0, 0.0, k_r])
        out.append(-Minv @ (C + D + K))
    return out


def _solve_sdp(A_list: list[NDArray[np.float64]], alpha: float, d_f: float,
               box: NDArray[np.float64], tau_r_max: float, k_r: float
               ) -> NDArray[np.float64] | None:
    # scaled variable Q = T Q̃ T with T = diag(box): keeps every entry O(1) for Clarabel
    T = np.diag(box)
    Ti = np.diag(1.0 / box)
    Qs = cp.Variable((3, 3), symmetric=True)
    cons = []
    for A in A_list:
        At = Ti @ A @ T
        L = At @ Qs + Qs @ At.T + 2 * alpha * Qs
        cons.append(0.5 * (L + L.T) << 0)
    S = np.array([[1.0, 0, 0], [0, 1.0, 0]]) @ T
    cons.append(S @ Qs @ S.T << (alpha * d_f) ** 2 * np.eye(2))
    cons += [Qs[j, j] <= 1.0 for j in range(3)]
    if k_r > 0 and np.isfinite(tau_r_max):
        cons.append((k_r * box[2]) ** 2 * Qs[2, 2] <= tau_r_max**2)
    prob = cp.Problem(cp.Maximize(cp.log_det(Qs)), cons)
    try:
        prob.solve(solver=cp.CLARABEL)
    except cp.error.SolverError:
        return None  # numerically hard α: skipped, the grid has others
    if prob.status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) or Qs.value is None:
        return None
    Q = T @ Qs.value @ T
    return np.asarray(Q)


def compute_terminal_set(params: VesselParams, *, d_f_m: float,
                         nu_max: tuple[float, float, float], k_r: float | None = None,
                         use_cache: bool = True) -> TerminalSet:
    """Solve the SDP for P_f (cached per vessel and settings).

    Parameters
    ----------
    params : VesselParams
        The vessel (mass, damping, yaw-moment limit).
    d_f_m : float
        Terminal distance d_f of constraint (f) [m], > 0: the braking distance bound.
    nu_max : tuple of 3 floats
        Velocity bounds |u|, |v| [m/s], |r| [rad/s] the ellipsoid must lie inside.
    k_r : float, optional
        Yaw damping gain of the backup [Nm s/rad]; default −N_r (doubles yaw damping).
    use_cache : bool
        Read and write the result in the cache directory.
    """
    if not (np.isfinite(d_f_m) and d_f_m > 0):
        raise ParameterError(f"terminal set: d_f_m must be finite and > 0, actually: {d_f_m}")
    nu_max_a = np.asarray(nu_max, dtype=float)
    if nu_max_a.shape != (3,) or not np.all(nu_max_a > 0):
        raise ParameterError(f"terminal set: nu_max must be 3 values > 0, actually: {nu_max}")
    k_r = -params.N_r if k_r is None else float(k_r)
    tau_r_max = min(abs(params.actuators.tau_min[2]), abs(params.actuators.tau_max[2]))
    key_src = json.dumps([params.to_dict(), d_f_m, list(nu_max_a), k_r], sort_keys=True,
                         default=float)
    key = hashlib.sha256(key_src.encode()).hexdigest()[:16]
    path = cache_dir() / f"terminal_set_{params.name}_{key}.json"
    if use_cache and path.exists():
        d = json.loads(path.read_text())
        return TerminalSet(P_f=np.asarray(d["P_f"]), alpha=d["alpha"], d_f_m=d["d_f_m"],
                           k_r=d["k_r"], semi_axes=np.asarray(d["semi_axes"]))
    # slowest decay any vertex allows bounds α; the speed box follows from α_max d_f
    A0 = _vertex_matrices(params, np.zeros(3), k_r)[0]
    alpha_max = float(-np.max(np.linalg.eigvals(A0).real))
    if alpha_max <= 0:
        raise ParameterError(f"terminal set: braking dynamics of {params.name!r} are not "
                             f"stable at rest (largest eigenvalue {-alpha_max:.3g})")
    box = np.array([min(nu_max_a[0], alpha_max * d_f_m), min(nu_max_a[1], alpha_max * d_f_m),
                    nu_max_a[2]])
    best: tuple[float, float, NDArray[np.float64]] | None = None
    # Fixed-point on the coefficient box: a smaller ellipsoid needs a smaller box, whose
    # weaker Coriolis / N_|v|v coupling allows faster decay and so a larger ellipsoid.
    for _ in range(3):
        A_list = _vertex_matrices(params, box, k_r)
        round_best = None
        for frac in (0.5, 0.7, 0.85, 0.95):
            alpha = frac * alpha_max
            Q = _solve_sdp(A_list, alpha, d_f_m, box, tau_r_max, k_r)
            if Q is None:
                continue
            ld = float(np.linalg.slogdet(Q)[1])
            if round_best is None or ld > round_best[0]:
                round_best = (ld, alpha, Q)
        if round_best is None:
            break
        if best is None or round_best[0] > best[0] + 1e-6:
            best = round_best
        new_box = np.sqrt(np.diag(round_best[2])) * 1.0001
        if np.allclose(new_box, box, rtol=1e-3):
            break
        box = new_box
    if best is None:
        raise SolverError(f"terminal set SDP infeasible for {params.name!r} with "
                          f"d_f={d_f_m} m, nu_max={list(nu_max_a)}")
    _, alpha, Q = best
    Q = 0.5 * (Q + Q.T)
    P_f = np.linalg.inv(Q)
    P_f = 0.5 * (P_f + P_f.T)
    ts = TerminalSet(P_f=P_f, alpha=alpha, d_f_m=float(d_f_m), k_r=k_r,
                     semi_axes=np.sqrt(np.diag(Q)))
    if use_cache:
        path.write_text(json.dumps({"P_f": P_f.tolist(), "alpha": alpha, "d_f_m": d_f_m,
                                    "k_r": k_r, "semi_axes": ts.semi_axes.tolist()}))
    log.info("terminal set for %s: semi-axes %s, alpha %.4f", params.name,
             np.round(ts.semi_axes, 4).tolist(), alpha)
    return ts


def verify_invariance(params: VesselParams, ts: TerminalSet, *, n_directions: int = 64,
                      horizon_s: float = 200.0, dt_s: float = 0.05,
                      rng: np.random.Generator | None = None
                      ) -> tuple[float, float]:
    """Simulate the braking backup on the nonlinear model from the ellipsoid's boundary.

    Returns ``(max_V, max_distance_m)``: the largest νᵀP_fν reached after the start (≤ 1
    means invariant) and the longest distance travelled (≤ d_f means the bound holds).
    Integrates :func:`asvtwin.vessel.model.rhs` (the simulator's reference model, plain
    |·|) with RK4 over all directions at once.
    """
    rng = np.random.default_rng(0) if rng is None else rng
    z = rng.normal(size=(n_directions, 3))
    z /= np.linalg.norm(z, axis=1, keepdims=True)
    Lc = np.linalg.cholesky(np.linalg.inv(ts.P_f))  # ν = L z on the boundary
    nu0 = z @ Lc.T
    x = np.zeros((n_directions, 6))
    x[:, 3:] = nu0
    max_V = 0.0
    ideal = params.replace(actuators=params.actuators.ideal())

    def tau_of(xx: NDArray[np.float64]) -> NDArray[np.float64]:
        t = np.zeros((xx.shape[0], 3))
        t[:, 2] = np.clip(-ts.k_r * xx[:, 5], ideal.actuators.tau_min[2],
                          ideal.actuators.tau_max[2])
        return t

    for _ in range(int(horizon_s / dt_s)):
        k1 = rhs(ideal, x, tau_of(x))
        k2 = rhs(ideal, x + 0.5 * dt_s * k1, tau_of(x + 0.5 * dt_s * k1))
        k3 = rhs(ideal, x + 0.5 * dt_s * k2, tau_of(x + 0.5 * dt_s * k2))
        k4 = rhs(ideal, x + dt_s * k3, tau_of(x + dt_s * k3))
        x = x + dt_s / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        V = np.einsum("ni,ij,nj->n", x[:, 3:], ts.P_f, x[:, 3:])
        max_V = max(max_V, float(V.max()))
    dist = float(np.max(np.hypot(x[:, 0], x[:, 1])))
    return max_V, dist
