"""Calibration of the fault detector's residual model on fault-free data.

The Kalman residual generator of :mod:`asvtwin.observer.faults` needs the process noise of
the momentum (q_p) and of the disturbance random walk (q_d); R comes from the sensor spec.
They are fitted here by maximum likelihood of the innovations over a log-spaced grid
(all candidates filtered at once, one compiled call per sample), and the matched filter's
variance inflation κ is measured for the detector's window: under the fitted model
A_m²/B_m is χ²₁ with mean 1, and κ_i = max over the onsets m of its sample mean (≥ 1).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from asvtwin.errors import StateError
from asvtwin.observer.faults import (
    DetectorConfig,
    FaultDetector,
    ResidualModel,
    _detector_step,
    default_window_s,
    steady_state_filter,
)
from asvtwin.vessel.params import VesselParams

__all__ = ["fit_residual_model"]


def _run_filters(params: VesselParams, K: NDArray[np.float64], S: NDArray[np.float64],
                 rho: NDArray[np.float64], Bc: NDArray[np.float64], nu: NDArray[np.float64],
                 tq: NDArray[np.float64], dt_s: float, burn: int, monitor: bool,
                 arm: int = 0) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Run g filters (one per row of K) over r runs (T, r, 3); return Σγ² (g, 3) and
    Σ A_m²/B_m (g, 3, W) after ``burn`` samples (vessel index = candidate·r + run)."""
    T, r, _ = nu.shape
    g = K.shape[0]
    n = g * r
    W = rho.shape[2]
    Kn = np.repeat(K, r, axis=0)
    Sn = np.repeat(S, r, axis=0)
    rhon = np.repeat(rho, r, axis=0)
    Bn = np.repeat(Bc, r, axis=0)
    s = np.zeros((n, 3, 2))
    A = np.zeros((n, 3, W))
    ring_g = np.zeros((n, 3, W))
    ring_t = np.zeros((n, 3, W))
    count = np.full(n, -1, dtype=np.int64)
    latched = np.zeros((n, 3), dtype=np.bool_)
    stat = np.zeros((n, 3))
    arg = np.zeros((n, 3), dtype=np.int64)
    mon = np.full(3, monitor)
    P, M = params.packed(), np.ascontiguousarray(params.M)
    Minv = np.ascontiguousarray(np.linalg.inv(M))
    g2 = np.zeros((n, 3))
    a2 = np.zeros((n, 3, W))
    head = 0
    for k in range(T):
        head = (head + 1) % W
        _detector_step(s, np.tile(nu[k], (g, 1)), np.tile(tq[k], (g, 1)), P, Minv, M, Kn,
                       dt_s, A, Bn, rhon, count, ring_g, ring_t, head, mon, latched,
                       stat, arg, Sn, arm)
        if k > burn:
            g2 += ring_g[:, :, head] ** 2
            if monitor and k > arm + W:
                a2 += A**2 / Bn
    return (g2.reshape(g, r, 3).sum(axis=1),
            a2.reshape(g, r, 3, W).sum(axis=1) / max(1, (T - arm - W - 1) * r))


def fit_residual_model(params: VesselParams, nu_meas: ArrayLike, tau: ArrayLike,
                       dt_s: float, sigma_nu: ArrayLike, *, window_s: float | None = None,
                       grid: int = 8) -> ResidualModel:
    """Fit q_p, q_d (maximum likelihood of the innovations) and κ on fault-free data.

    Parameters
    ----------
    params : VesselParams
    nu_meas, tau : array_like, (T, r, 3)
        r fault-free runs of T samples: measured ν and healthy-actuator thrust.
    dt_s : float
        Sampling step h [s].
    sigma_nu : array_like, (3,)
        Sensor noise std of ν [m/s, m/s, rad/s] (gives R).
    window_s : float
        The detector's window [s] (κ is measured for it).
    grid : int
        Candidates per log-spaced axis of (q_p / R, q_d h² / R).

    Returns
    -------
    ResidualModel
        q_p, q_d maximising the Gaussian innovation likelihood per DOF; κ_i the largest
        mean of A_m²/B_m (the normalised matched filter, χ²₁ under the model) over the
        window's onsets on the same data, at least 1.
    """
    nu = np.asarray(nu_meas, dtype=float)
    tq = np.asarray(tau, dtype=float)
    if nu.ndim != 3 or nu.shape[2] != 3 or tq.shape != nu.shape:
        raise StateError(f"calibration nu_meas and tau must both have shape (T, r, 3), "
                         f"actually: {nu.shape} and {tq.shape}")
    if not (np.all(np.isfinite(nu)) and np.all(np.isfinite(tq))):
        raise StateError("calibration data must be finite (no dropouts)")
    T = nu.shape[0]
    window_s = default_window_s(params, window_s)
    W = max(2, round(window_s / dt_s))
    burn = T // 4
    if T - burn < 2 * W:
        raise StateError(f"calibration needs at least {3 * W} samples "
                         f"({3 * W * dt_s:g} s), actually: {T}")
    R = np.asarray(ResidualModel.from_sensor_noise(params, sigma_nu, dt_s).R)
    cand = [(a, b) for a in np.logspace(-4, 2, grid) for b in np.logspace(-8, 0, grid)]
    K = np.zeros((len(cand), 3, 2))
    S = np.zeros((len(cand), 3))
    for c, (a, b) in enumerate(cand):
        for j in range(3):
            K[c, j], S[c, j], _ = steady_state_filter(dt_s, R[j], a * R[j],
                                                      b * R[j] / dt_s**2)
    dummy = np.ones((len(cand), 3, W))
    g2, _ = _run_filters(params, K, S, dummy, dummy, nu, tq, dt_s, burn, False)
    nobs = (T - burn - 1) * nu.shape[1]
    ll = -0.5 * (g2 / S + nobs * np.log(S))
    best = np.argmax(ll, axis=0)
    q_p = tuple(cand[best[j]][0] * R[j] for j in range(3))
    q_d = tuple(cand[best[j]][1] * R[j] / dt_s**2 for j in range(3))
    model = ResidualModel(dt_s, tuple(R), q_p, q_d)
    det = FaultDetector(params, 1, model, DetectorConfig(window_s=window_s, dofs=()))
    if T < det.arm_steps + 2 * W:
        raise StateError(f"calibration needs at least {det.arm_steps + 2 * W} samples "
                         f"to measure the matched filter, actually: {T}")
    _, a2 = _run_filters(params, det._K, det._S, det._rho, det._Bc, nu, tq, dt_s, burn,
                         True, det.arm_steps)
    kappa = np.maximum(1.0, a2[0].max(axis=1))
    return ResidualModel(dt_s, tuple(R), q_p, q_d, tuple(kappa))
