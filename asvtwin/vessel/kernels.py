"""Compiled (numba) kernels of the vessel model: right-hand side, RK4, thruster dynamics.

The readable reference is :mod:`asvtwin.vessel.model`; tests hold these to it. Parameters
arrive packed (``VesselParams.packed()``, layout ``PACKED_FIELDS``) as a (k, 27) array with
k = 1 (all vessels share one set) or k = n (one set per vessel); actuators as (k, 4, 3)
(rows tau_min, tau_max, time constant, rate limit).

Kernels return the index of the first vessel whose result is not finite, or -1, so the
caller can raise an error naming it without a second pass over the data.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = [
    "actuator_batch",
    "hydrodynamic_force",
    "hydrodynamic_force_abs",
    "rhs_batch",
    "rk4_batch",
    "step_batch",
]


@njit(cache=True, inline="always")
def hydrodynamic_force(u, v, r, p):  # pragma: no cover - compiled
    """n(ν) = C(ν)ν + D(ν)ν from packed parameters (layout ``PACKED_FIELDS``)."""
    return hydrodynamic_force_abs(u, v, r, abs(u), abs(v), abs(r), p)


@njit(cache=True, inline="always")
def hydrodynamic_force_abs(u, v, r, au, av, ar, p):  # pragma: no cover - compiled
    """n(ν) with the magnitudes |u|, |v|, |r| given by the caller (the safety filter's
    planning model passes smoothed ones, √(z² + ε))."""
    M11 = p[9]
    M22 = p[10]
    M23 = p[11]
    # D(ν) entries (Skjetne, Smogeli and Fossen 2004): d11, d22, d23, d32, d33
    d11 = -p[12] - p[13] * au - p[14] * u * u
    d22 = -p[15] - p[16] * av - p[17] * ar
    d23 = -p[18] - p[19] * av - p[20] * ar
    d32 = -p[21] - p[22] * av - p[23] * ar
    d33 = -p[24] - p[25] * av - p[26] * ar
    # C(ν)ν with c13 = -(M22 v + M23 r), c23 = M11 u (skew-symmetric)
    c13 = -(M22 * v + M23 * r)
    c23 = M11 * u
    n0 = c13 * r + d11 * u
    n1 = c23 * r + d22 * v + d23 * r
    n2 = -c13 * u - c23 * v + d32 * v + d33 * r
    return n0, n1, n2


@njit(cache=True, inline="always")
def _rhs(x0, x1, psi, u, v, r, tu, tv, tr, p):  # pragma: no cover - compiled
    # eq. η̇ = R(ψ) ν
    c = math.cos(psi)
    s = math.sin(psi)
    dx = c * u - s * v
    dy = s * u + c * v
    dpsi = r
    # eq. (dynamics): M ν̇ = τ + τ_d − C(ν)ν − D(ν)ν
    n0, n1, n2 = hydrodynamic_force(u, v, r, p)
    f0 = tu - n0
    f1 = tv - n1
    f2 = tr - n2
    du = p[0] * f0 + p[1] * f1 + p[2] * f2
    dv = p[3] * f0 + p[4] * f1 + p[5] * f2
    dr = p[6] * f0 + p[7] * f1 + p[8] * f2
    return dx, dy, dpsi, du, dv, dr


@njit(cache=True)
def rhs_batch(x, tau, d, P, out):  # pragma: no cover - compiled
    """ẋ for n vessels into ``out`` (n, 6); returns first non-finite index or -1."""
    n = x.shape[0]
    shared = P.shape[0] == 1
    bad = -1
    for i in range(n):
        p = P[0] if shared else P[i]
        k = _rhs(x[i, 0], x[i, 1], x[i, 2], x[i, 3], x[i, 4], x[i, 5],
                 tau[i, 0] + d[i, 0], tau[i, 1] + d[i, 1], tau[i, 2] + d[i, 2], p)
        for j in range(6):
            out[i, j] = k[j]
            if bad < 0 and not math.isfinite(k[j]):
                bad = i
    return bad


@njit(cache=True, inline="always")
def _rk4_one(x, i, tu, tv, tr, p, dt, out):  # pragma: no cover - compiled
    a0, a1, a2, a3, a4, a5 = x[i, 0], x[i, 1], x[i, 2], x[i, 3], x[i, 4], x[i, 5]
    k1 = _rhs(a0, a1, a2, a3, a4, a5, tu, tv, tr, p)
    h = 0.5 * dt
    k2 = _rhs(a0 + h * k1[0], a1 + h * k1[1], a2 + h * k1[2], a3 + h * k1[3],
              a4 + h * k1[4], a5 + h * k1[5], tu, tv, tr, p)
    k3 = _rhs(a0 + h * k2[0], a1 + h * k2[1], a2 + h * k2[2], a3 + h * k2[3],
              a4 + h * k2[4], a5 + h * k2[5], tu, tv, tr, p)
    k4 = _rhs(a0 + dt * k3[0], a1 + dt * k3[1], a2 + dt * k3[2], a3 + dt * k3[3],
              a4 + dt * k3[4], a5 + dt * k3[5], tu, tv, tr, p)
    w = dt / 6.0
    ok = True
    for j in range(6):
        val = x[i, j] + w * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
        out[i, j] = val
        if not math.isfinite(val):
            ok = False
    return ok


@njit(cache=True)
def rk4_batch(x, tau, d, P, dt, out):  # pragma: no cover - compiled
    """One classic RK4 step of length ``dt`` for n vessels, τ and τ_d held (ZOH)."""
    n = x.shape[0]
    shared = P.shape[0] == 1
    bad = -1
    for i in range(n):
        p = P[0] if shared else P[i]
        ok = _rk4_one(x, i, tau[i, 0] + d[i, 0], tau[i, 1] + d[i, 1],
                      tau[i, 2] + d[i, 2], p, dt, out)
        if not ok and bad < 0:
            bad = i
    return bad


@njit(cache=True, inline="always")
def _actuator_one(tau_act, tau_cmd, i, a, dt, out):  # pragma: no cover - compiled
    for j in range(3):
        # saturation to [tau_min, tau_max]
        target = min(max(tau_cmd[i, j], a[0, j]), a[1, j])
        T = a[2, j]
        cur = tau_act[i, j]
        if T > 0.0:
            # exact first-order lag response to a held command over dt
            step = (target - cur) * (1.0 - math.exp(-dt / T))
        else:
            step = target - cur
        lim = a[3, j] * dt
        if step > lim:
            step = lim
        elif step < -lim:
            step = -lim
        out[i, j] = min(max(cur + step, a[0, j]), a[1, j])


@njit(cache=True)
def actuator_batch(tau_act, tau_cmd, A, dt, out):  # pragma: no cover - compiled
    """Thruster dynamics: commanded → actual thrust over ``dt`` for n vessels.

    Returns the first vessel with a non-finite command, or -1.
    """
    n = tau_act.shape[0]
    shared = A.shape[0] == 1
    bad = -1
    for i in range(n):
        if bad < 0:
            for j in range(3):
                if not math.isfinite(tau_cmd[i, j]):
                    bad = i
        _actuator_one(tau_act, tau_cmd, i, A[0] if shared else A[i], dt, out)
    return bad


@njit(cache=True)
def step_batch(x, tau_act, tau_cmd, d, P, A, F, dt, x_out, tau_out):  # pragma: no cover
    """Thrusters then RK4 for n vessels: the simulator's whole step in one call.

    The actuator state advances first; the thrust that reaches the hull is then
    ``F[0] * tau_act + F[1]`` per DOF (``F`` (k, 2, 3): gain and bias, the actuator-fault
    model: gain 1 and bias 0 when healthy, gain 0.5 for half thrust lost, gain 0 with a
    bias for a stuck actuator). The RK4 step holds that thrust and the disturbance
    constant over ``dt`` (zero-order hold). Returns -1, or the index of the first vessel
    with a non-finite input or result (its output is then undefined).
    """
    n = x.shape[0]
    sharedP = P.shape[0] == 1
    sharedA = A.shape[0] == 1
    sharedF = F.shape[0] == 1
    bad = -1
    for i in range(n):
        for j in range(3):
            if bad < 0 and not (math.isfinite(tau_cmd[i, j]) and math.isfinite(d[i, j])):
                bad = i
        _actuator_one(tau_act, tau_cmd, i, A[0] if sharedA else A[i], dt, tau_out)
        f = F[0] if sharedF else F[i]
        ok = _rk4_one(x, i, f[0, 0] * tau_out[i, 0] + f[1, 0] + d[i, 0],
                      f[0, 1] * tau_out[i, 1] + f[1, 1] + d[i, 1],
                      f[0, 2] * tau_out[i, 2] + f[1, 2] + d[i, 2],
                      P[0] if sharedP else P[i], dt, x_out)
        if not ok and bad < 0:
            bad = i
    return bad


def warm_up() -> None:
    """Compile (or load from cache) every kernel once, off the hot path."""
    x = np.zeros((1, 6))
    t = np.zeros((1, 3))
    P = np.zeros((1, 27))
    A = np.zeros((1, 4, 3))
    A[0, 3, :] = np.inf
    rhs_batch(x, t, t, P, np.empty_like(x))
    rk4_batch(x, t, t, P, 0.1, np.empty_like(x))
    actuator_batch(t, t, A, 0.1, np.empty_like(t))
    F = np.zeros((1, 2, 3))
    F[0, 0, :] = 1.0
    step_batch(x, t, t, t, P, A, F, 0.1, np.empty_like(x), np.empty_like(t))
