"""Compiled (numba) kernels of the safety filter's hot path: plan rollout and margins.

:func:`rollout` re-simulates a plan on *the solver's* model, the CasADi expression of
:func:`asvtwin.control.backends.ocp.continuous_dynamics` (RK4 per stage, |·| smoothed as
√(z² + ε), ε = :data:`~asvtwin.control.backends.ocp.SMOOTH_ABS_EPS`): the vessel kernel's
C(ν)ν + D(ν)ν given those smoothed magnitudes. The vessel's own simulation kernels (:mod:`asvtwin.vessel.kernels`) use the
exact |·|, so they are *not* the planning model and are not used for certification;
``tests/control/test_kernels.py`` holds this kernel to the CasADi function to 1e-12.
Coefficients arrive as ``VesselParams.packed()`` (layout ``PACKED_FIELDS``: M⁻¹ row-major,
M11, M22, M23s, then the 15 damping coefficients).

:func:`obstacle_margins` computes every stage's distance margin to every circle and
shore segment in one pass (the arithmetic of
:meth:`asvtwin.control.obstacles.CoastSegments.distances` and of the circle distances).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from asvtwin.control.backends.ocp import SMOOTH_ABS_EPS
from asvtwin.vessel.kernels import hydrodynamic_force_abs

__all__ = ["certify", "obstacle_margins", "rollout", "rollout_governed", "rollout_lagged"]

_EPS = SMOOTH_ABS_EPS


@njit(cache=True, inline="always")
def _f(psi, u, v, r, tu, tv, tr, p):  # pragma: no cover - compiled
    """ẋ of the planning model (eq. (a)): η̇ = R(ψ)ν, M ν̇ = τ + τ̂_d − C(ν)ν − D(ν)ν."""
    au = math.sqrt(u * u + _EPS)
    av = math.sqrt(v * v + _EPS)
    ar = math.sqrt(r * r + _EPS)
    # C(ν)ν + D(ν)ν of the vessel model, with |·| smoothed as in ocp.continuous_dynamics
    n0, n1, n2 = hydrodynamic_force_abs(u, v, r, au, av, ar, p)
    f0 = tu - n0
    f1 = tv - n1
    f2 = tr - n2
    c = math.cos(psi)
    s = math.sin(psi)
    return (c * u - s * v, s * u + c * v, r,
            p[0] * f0 + p[1] * f1 + p[2] * f2,
            p[3] * f0 + p[4] * f1 + p[5] * f2,
            p[6] * f0 + p[7] * f1 + p[8] * f2)


@njit(cache=True)
def rollout(x0, U, d, p, dt, substeps, out):  # pragma: no cover - compiled
    """States of plan ``U`` (N, 3) from ``x0`` (6,) under disturbance ``d`` (3,) into
    ``out`` (N+1, 6): ``substeps`` classic RK4 steps of ``dt / substeps`` per stage, input
    and disturbance held. Returns the first stage whose state is not finite, or -1."""
    n = U.shape[0]
    h = dt / substeps
    hh = 0.5 * h
    w = h / 6.0
    a = np.empty(6)
    for j in range(6):
        out[0, j] = x0[j]
        a[j] = x0[j]
    bad = -1
    for k in range(n):
        tu = U[k, 0] + d[0]
        tv = U[k, 1] + d[1]
        tr = U[k, 2] + d[2]
        for _ in range(substeps):
            k1 = _f(a[2], a[3], a[4], a[5], tu, tv, tr, p)
            k2 = _f(a[2] + hh * k1[2], a[3] + hh * k1[3], a[4] + hh * k1[4],
                    a[5] + hh * k1[5], tu, tv, tr, p)
            k3 = _f(a[2] + hh * k2[2], a[3] + hh * k2[3], a[4] + hh * k2[4],
                    a[5] + hh * k2[5], tu, tv, tr, p)
            k4 = _f(a[2] + h * k3[2], a[3] + h * k3[3], a[4] + h * k3[4],
                    a[5] + h * k3[5], tu, tv, tr, p)
            for j in range(6):
                a[j] = a[j] + w * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
        for j in range(6):
            out[k + 1, j] = a[j]
            if bad < 0 and not math.isfinite(a[j]):
                bad = k + 1
    return bad


@njit(cache=True)
def rollout_lagged(x0, tau0, U, d, p, dt, substeps, tc, out, out_tau):  # pragma: no cover
    """:func:`rollout` with the thrusters' first-order lag, as
    :func:`~asvtwin.control.backends.ocp.discrete_lagged_dynamics`: the thrust produced
    (from ``tau0`` (3,)) follows the held command ``U[k]`` as τ(t) = U[k] + (τ_k − U[k])
    e^{−t/T} (``tc`` (3,) [s], all > 0), exactly; the hull feels τ(t) + d at each RK4
    node's time. States into ``out`` (N+1, 6), the thrust at every stage into
    ``out_tau`` (N+1, 3). Returns the first stage whose state is not finite, or -1."""
    return rollout_governed(x0, tau0, U, d, p, dt, substeps, tc, True, math.inf, 0, out,
                            out_tau)

@njit(cache=True)
def _stage(a, ta, u0, u1, u2, d, p, h, substeps, eh, ef, lagged, out,
           out_t):  # pragma: no cover - compiled
    """One stage of :func:`rollout` (``lagged`` False) or :func:`rollout_lagged` from
    state ``a`` (6,) and thrust ``ta`` (3,) under the held command (u0, u1, u2), into
    ``out`` (6,) and ``out_t`` (3,); ``eh``, ``ef`` (3,) are the lag's decay over half
    and a whole RK4 step, e^{−h/2T} and e^{−h/T}."""
    hh = 0.5 * h
    w = h / 6.0
    for j in range(6):
        out[j] = a[j]
    for j in range(3):
        out_t[j] = ta[j]
    uu = (u0, u1, u2)
    for _ in range(substeps):
        if lagged:
            s0 = (out_t[0] + d[0], out_t[1] + d[1], out_t[2] + d[2])
            m = [0.0, 0.0, 0.0]
            for j in range(3):
                m[j] = uu[j] + (out_t[j] - uu[j]) * eh[j] + d[j]
                out_t[j] = uu[j] + (out_t[j] - uu[j]) * ef[j]
            sm = (m[0], m[1], m[2])
            se = (out_t[0] + d[0], out_t[1] + d[1], out_t[2] + d[2])
        else:
            s0 = (u0 + d[0], u1 + d[1], u2 + d[2])
            sm = s0
            se = s0
        k1 = _f(out[2], out[3], out[4], out[5], s0[0], s0[1], s0[2], p)
        k2 = _f(out[2] + hh * k1[2], out[3] + hh * k1[3], out[4] + hh * k1[4],
                out[5] + hh * k1[5], sm[0], sm[1], sm[2], p)
        k3 = _f(out[2] + hh * k2[2], out[3] + hh * k2[3], out[4] + hh * k2[4],
                out[5] + hh * k2[5], sm[0], sm[1], sm[2], p)
        k4 = _f(out[2] + h * k3[2], out[3] + h * k3[3], out[4] + h * k3[4],
                out[5] + h * k3[5], se[0], se[1], se[2], p)
        for j in range(6):
            out[j] = out[j] + w * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])


@njit(cache=True)
def rollout_governed(x0, tau0, U, d, p, dt, substeps, tc, lagged, r_cap, n_gov, out,
                     out_tau):  # pragma: no cover - compiled
    """:func:`rollout` (or, ``lagged``, :func:`rollout_lagged` from thrust ``tau0``, time
    constants ``tc``; unread otherwise) with the yaw moment of stages ``0..n_gov-1`` governed: ``U[k, 2]`` gives the turn's
    direction and its largest moment; where that moment would take the yaw rate past
    ``r_cap`` [rad/s] by the stage's end, the stage holds the moment in
    [−|U[k, 2]|, |U[k, 2]|] that ends it at ``r_cap`` (bisection, 20 halvings), or the
    full opposite moment if even that leaves it faster. ``U`` is overwritten with the
    moments used. Returns the first stage whose state is not finite, or -1."""
    n = U.shape[0]
    h = dt / substeps
    eh = np.ones(3)
    ef = np.ones(3)
    if lagged:
        for j in range(3):
            eh[j] = math.exp(-0.5 * h / tc[j])
            ef[j] = math.exp(-h / tc[j])
    a = np.empty(6)
    ta = np.empty(3)
    b = np.empty(6)
    tb = np.empty(3)
    for j in range(6):
        out[0, j] = x0[j]
        a[j] = x0[j]
    for j in range(3):
        out_tau[0, j] = tau0[j]
        ta[j] = tau0[j]
    bad = -1
    for k in range(n):
        top = U[k, 2]
        _stage(a, ta, U[k, 0], U[k, 1], top, d, p, h, substeps, eh, ef, lagged, b, tb)
        if k < n_gov and top != 0.0:
            side = 1.0 if top > 0 else -1.0
            if side * b[5] > r_cap:
                lo, hi = -top, top
                _stage(a, ta, U[k, 0], U[k, 1], lo, d, p, h, substeps, eh, ef, lagged, b,
                       tb)
                if side * b[5] < r_cap:
                    for _ in range(20):
                        mid = 0.5 * (lo + hi)
                        _stage(a, ta, U[k, 0], U[k, 1], mid, d, p, h, substeps, eh,
                               ef, lagged, b, tb)
                        if side * b[5] > r_cap:
                            hi = mid
                        else:
                            lo = mid
                U[k, 2] = lo
                _stage(a, ta, U[k, 0], U[k, 1], lo, d, p, h, substeps, eh, ef, lagged, b,
                       tb)
        for j in range(6):
            a[j] = b[j]
            out[k + 1, j] = a[j]
            if bad < 0 and not math.isfinite(a[j]):
                bad = k + 1
        for j in range(3):
            ta[j] = tb[j]
            out_tau[k + 1, j] = ta[j]
    return bad


@njit(cache=True)
def obstacle_margins(X, centres, radii, segs, clear, out):  # pragma: no cover - compiled
    """Margins ``out`` (N+1, m + k) [m] of positions ``X[:, :2]`` to circles ``centres``
    (N+1, m, 2) / ``radii`` (N+1, m) and shore segments ``segs`` (k, 4), minus the stage's
    clearance ``clear`` (N+1,); returns the smallest margin over stages 1..N (+inf when
    there are no obstacles)."""
    n = X.shape[0]
    m = centres.shape[1]
    ns = segs.shape[0]
    low = np.inf
    for k in range(n):
        px = X[k, 0]
        py = X[k, 1]
        for i in range(m):
            dx = px - centres[k, i, 0]
            dy = py - centres[k, i, 1]
            g = math.sqrt(dx * dx + dy * dy) - radii[k, i] - clear[k]
            out[k, i] = g
            if k > 0 and (g < low or math.isnan(g)):  # NaN wins, as in np.min
                low = g
        for j in range(ns):
            ax = segs[j, 0]
            ay = segs[j, 1]
            ex = segs[j, 2] - ax
            ey = segs[j, 3] - ay
            L2 = max(ex * ex + ey * ey, 1e-12)
            t = ((px - ax) * ex + (py - ay) * ey) / L2
            t = min(max(t, 0.0), 1.0)
            qx = px - (ax + t * ex)
            qy = py - (ay + t * ey)
            g = math.sqrt(qx * qx + qy * qy) - clear[k]
            out[k, m + j] = g
            if k > 0 and (g < low or math.isnan(g)):  # NaN wins, as in np.min
                low = g
    return low


@njit(cache=True)
def certify(X, centres, radii, segs, clear, P_f, out):  # pragma: no cover - compiled
    """Everything the filter checks on a re-simulated plan ``X`` (N+1, 6) in one pass:
    the margins into ``out`` (see :func:`obstacle_margins`) and returns (smallest margin
    over stages 1..N, terminal margin 1 − ν_Nᵀ P_f ν_N (eq. (g)), all states finite)."""
    low = obstacle_margins(X, centres, radii, segs, clear, out)
    n = X.shape[0] - 1
    q = 0.0
    for i in range(3):
        for j in range(3):
            q += X[n, 3 + i] * P_f[i, j] * X[n, 3 + j]
    finite = True
    for k in range(X.shape[0]):
        for j in range(6):
            if not math.isfinite(X[k, j]):
                finite = False
    return low, 1.0 - q, finite


def warm_up() -> None:
    """Compile (or load from numba's cache) the kernels with the filter's types."""
    p = np.zeros(27)
    p[[0, 4, 8]] = 1.0
    X = np.zeros((2, 6))
    rollout(np.zeros(6), np.zeros((1, 3)), np.zeros(3), p, 0.5, 1, X)
    rollout_lagged(np.zeros(6), np.zeros(3), np.zeros((1, 3)), np.zeros(3), p, 0.5, 1,
                   np.ones(3), X, np.empty((2, 3)))
    rollout_governed(np.zeros(6), np.zeros(3), np.ones((1, 3)), np.zeros(3), p, 0.5, 1,
                     np.ones(3), True, 0.1, 1, X, np.empty((2, 3)))
    certify(X, np.zeros((2, 1, 2)) + 5.0, np.ones((2, 1)), np.zeros((1, 4)), np.ones(2),
            np.eye(3), np.empty((2, 2)))

