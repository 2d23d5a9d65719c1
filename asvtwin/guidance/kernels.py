"""numba kernels of the LOS guidance and the autopilot (one loop over the craft each).

The numpy forms in :mod:`asvtwin.guidance.los` and :mod:`asvtwin.guidance.autopilot` are
the reference; these are the same equations per craft, so a call for one vessel costs a
few microseconds instead of a few dozen small numpy operations.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["autopilot_kernel", "los_kernel"]


@njit(cache=True)
def los_kernel(p, w, origin, k, lookahead, R, chi, cte, cot_max=0.0,
               switch_cte=math.inf):  # pragma: no cover - numba
    """Switch legs and steer each craft; updates ``k`` in place, fills ``chi`` and ``cte``.

    p (n, 2) positions; w (kw, 2) waypoints; origin (n, 2) leg start for waypoint 0;
    k (n,) index of the waypoint steered to; lookahead Δ and radius R [m]; ``cot_max``
    = 1 / tan(χ_max) bounds the intercept angle (Δ(e) = max(Δ, |e| cot χ_max); 0: constant
    Δ); the along-track switch only while |e| < ``switch_cte`` [m] (inf: always) or while
    the next leg (as a segment) is no farther than |e|. Returns
    False (and changes nothing) if a position is NaN or infinite.
    """
    n = p.shape[0]
    kw = w.shape[0]
    for i in range(n):  # refuse non-finite positions before touching the leg indices
        if not (math.isfinite(p[i, 0]) and math.isfinite(p[i, 1])):
            return False
    for i in range(n):
        px, py = p[i, 0], p[i, 1]
        # switch while inside the acceptance circle, or past (leg - R) along track while
        # near the leg (|e| < switch_cte) or at least as near the next leg (a segment)
        while k[i] < kw:
            kk = k[i]
            if kk == 0:
                ax, ay = origin[i, 0], origin[i, 1]
            else:
                ax, ay = w[kk - 1, 0], w[kk - 1, 1]
            dx, dy = w[kk, 0] - ax, w[kk, 1] - ay
            pi_p = math.atan2(dy, dx)
            along = (px - ax) * math.cos(pi_p) + (py - ay) * math.sin(pi_p)
            e_k = -(px - ax) * math.sin(pi_p) + (py - ay) * math.cos(pi_p)
            dist = math.hypot(w[kk, 0] - px, w[kk, 1] - py)
            near = abs(e_k) < switch_cte
            if not near and kk + 1 < kw:  # distance to the next leg, a segment
                bx, by = w[kk + 1, 0] - w[kk, 0], w[kk + 1, 1] - w[kk, 1]
                bb = bx * bx + by * by
                t = 0.0 if bb == 0.0 else ((px - w[kk, 0]) * bx + (py - w[kk, 1]) * by) / bb
                t = min(max(t, 0.0), 1.0)
                near = math.hypot(px - w[kk, 0] - t * bx, py - w[kk, 1] - t * by) <= abs(e_k)
            if dist <= R or (along >= math.hypot(dx, dy) - R and near):
                k[i] += 1
            else:
                break
        kk = min(k[i], kw - 1)
        if kk == 0:
            ax, ay = origin[i, 0], origin[i, 1]
        else:
            ax, ay = w[kk - 1, 0], w[kk - 1, 1]
        dx, dy = w[kk, 0] - ax, w[kk, 1] - ay
        pi_p = math.atan2(dy, dx)
        e = -(px - ax) * math.sin(pi_p) + (py - ay) * math.cos(pi_p)
        cte[i] = e
        if k[i] >= kw:
            chi[i] = pi_p  # done: hold the last leg's course
        else:
            delta = max(lookahead, abs(e) * cot_max)  # Δ(e): intercept angle <= χ_max
            c = pi_p + math.atan(-e / delta)  # χ_d = π_p + arctan(-e/Δ)
            chi[i] = math.atan2(math.sin(c), math.cos(c))
    return True


@njit(cache=True)
def autopilot_kernel(x, chi_d, u_d, g, crab, X, Nr, lo, hi, iu, ipsi, h, out):  # pragma: no cover
    """τ = [τ_u, 0, τ_r] per vessel, saturated; integrators updated in place when h > 0.

    Returns False (and changes nothing) if any input is NaN or infinite.

    g (m_g, 8) gains rows [k_psi, r_max, k_r, k_i_psi, f_r, k_u, k_i_u, f_u] (m_g in {1, n});
    X (m, 3) surge damping [X_u, X_|u|u, X_uuu], Nr (m,), lo/hi (m, 3) limits (m in {1, n}).
    """
    n = x.shape[0]
    for i in range(n):  # refuse non-finite input before touching the integrators
        if not (math.isfinite(chi_d[i]) and math.isfinite(u_d[i])):
            return False
        for j in range(6):
            if not math.isfinite(x[i, j]):
                return False
    for i in range(n):
        gi = i if g.shape[0] > 1 else 0
        pi = i if X.shape[0] > 1 else 0
        k_psi, r_max, k_r, k_i_psi = g[gi, 0], g[gi, 1], g[gi, 2], g[gi, 3]
        f_r, k_u, k_i_u, f_u = g[gi, 4], g[gi, 5], g[gi, 6], g[gi, 7]
        psi, u, v, r = x[i, 2], x[i, 3], x[i, 4], x[i, 5]
        psi_d = chi_d[i]
        if crab and u > 0.0 and math.hypot(u, v) > 1e-3:
            psi_d = chi_d[i] - math.atan2(v, u)  # ψ_d = χ_d − β
        e = psi_d - psi
        e_psi = e - 2.0 * math.pi * math.floor((e + math.pi) / (2.0 * math.pi))  # wrap
        r_d = min(max(k_psi * e_psi, -r_max), r_max)
        ud = u_d[i]
        e_u = ud - u
        tau_r = k_r * (r_d - r) + k_i_psi * ipsi[i] - f_r * Nr[pi] * r_d
        d_u = -(X[pi, 0] * ud + X[pi, 1] * abs(ud) * ud + X[pi, 2] * ud * ud * ud)
        tau_u = f_u * d_u + k_u * e_u + k_i_u * iu[i]
        if h > 0.0:
            # conditional integration: only while the channel is inside its range
            if lo[pi, 0] < tau_u < hi[pi, 0]:
                iu[i] += h * e_u
            if lo[pi, 2] < tau_r < hi[pi, 2]:
                ipsi[i] += h * e_psi
        out[i, 0] = min(max(tau_u, lo[pi, 0]), hi[pi, 0])
        out[i, 1] = 0.0
        out[i, 2] = min(max(tau_r, lo[pi, 2]), hi[pi, 2])
    return True


def warm_up() -> None:
    """Compile (or load) both kernels."""
    z = np.zeros((1, 2))
    los_kernel(z, np.ones((1, 2)), z, np.zeros(1, dtype=np.int64), 1.0, 0.5, np.zeros(1),
               np.zeros(1), 0.0, math.inf)
    autopilot_kernel(np.zeros((1, 6)), np.zeros(1), np.zeros(1), np.ones((1, 8)), True,
                     np.zeros((1, 3)), np.zeros(1), -np.ones((1, 3)), np.ones((1, 3)),
                     np.zeros(1), np.zeros(1), 0.0, np.zeros((1, 3)))
