"""Batched constant-velocity Kalman filter (paper section "Kalman Filter").

State of ``n`` targets: ``x`` (n, 4) = ``[north_m, east_m, v_north_m_s, v_east_m_s]`` and
covariance ``P`` (n, 4, 4). Every function works on all targets at once; each target may
have its own time step (irregular sampling: AIS every 2–180 s, LiDAR every scan).

Model (paper eq. "constant velocity model", :math:`x_{k+1} = A x_k + w_k`):

.. math::

    A(\\Delta t) = \\begin{bmatrix} I & \\Delta t I \\\\ 0 & I \\end{bmatrix}, \\qquad
    Q(\\Delta t) = q \\begin{bmatrix} \\Delta t^3/3\\, I & \\Delta t^2/2\\, I \\\\
                                       \\Delta t^2/2\\, I & \\Delta t\\, I \\end{bmatrix},

the discretised continuous white-noise acceleration model with spectral density ``q``
[m²/s³], exact for any :math:`\\Delta t` (so two steps of 1 s equal one of 2 s).

Update (paper's correction step), in Joseph form so ``P`` stays symmetric positive
definite under rounding:

.. math::

    \\tilde y = z - H \\check x, \\quad S = H \\check P H^T + R, \\quad
    K = \\check P H^T S^{-1}, \\quad \\hat x = \\check x + K \\tilde y, \\quad
    \\hat P = (I - K H) \\check P (I - K H)^T + K R K^T.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from asvtwin.checks import F8 as _F8
from asvtwin.errors import ParameterError, StateError
from asvtwin.tracking.smallmat import inv_into, inv_into_m

__all__ = [
    "H_FULL",
    "H_POSITION",
    "KalmanUpdate",
    "cv_predict",
    "cv_process_noise",
    "cv_transition",
    "kalman_update",
]


#: Measurement matrix of a position fix (LiDAR centre, AIS position), shape (2, 4).
H_POSITION = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
H_POSITION.flags.writeable = False
#: Measurement matrix of position and velocity (AIS with SOG/COG), shape (4, 4).
H_FULL = np.eye(4)
H_FULL.flags.writeable = False


@njit(cache=True)
def _predict_row(x, P, k, h, qk, xo, Po, o):  # type: ignore[no-untyped-def]
    """CV prediction of target ``k`` of ``x``/``P`` by ``h`` seconds (noise ``qk``) into
    row ``o`` of ``xo``/``Po``. :func:`_predict_kernel` and the tracker's in-place
    prediction share it."""
    for i in range(4):
        xo[o, i] = x[k, i]
    # x = A x
    xo[o, 0] += h * x[k, 2]
    xo[o, 1] += h * x[k, 3]
    # P = A P A^T + Q, by 2x2 blocks [[Pp, Ppv], [Pvp, Pv]]
    for i in range(2):
        for j in range(2):
            Po[o, i, j] = (P[k, i, j] + h * (P[k, i, j + 2] + P[k, i + 2, j])
                           + h * h * P[k, i + 2, j + 2])
            Po[o, i, j + 2] = P[k, i, j + 2] + h * P[k, i + 2, j + 2]
            Po[o, i + 2, j] = P[k, i + 2, j] + h * P[k, i + 2, j + 2]
            Po[o, i + 2, j + 2] = P[k, i + 2, j + 2]
    for i in range(2):
        Po[o, i, i] += qk * h * h * h / 3.0
        Po[o, i, i + 2] += qk * h * h / 2.0
        Po[o, i + 2, i] += qk * h * h / 2.0
        Po[o, i + 2, i + 2] += qk * h
    for i in range(4):
        for j in range(i + 1, 4):
            v = 0.5 * (Po[o, i, j] + Po[o, j, i])
            Po[o, i, j] = v
            Po[o, j, i] = v


@njit(cache=True)
def _predict_kernel(x, P, dt, q):  # type: ignore[no-untyped-def]
    n = x.shape[0]
    xo = np.empty_like(x)
    Po = np.empty_like(P)
    for k in range(n):
        _predict_row(x, P, k, dt[k], q[k], xo, Po, k)
    return xo, Po


@njit(cache=True)
def _predict_in_place(x, P, h, qk):  # type: ignore[no-untyped-def]
    """:func:`_predict_kernel` of all rows by one step ``h``, written back into ``x``, ``P``."""
    xs, Ps = np.empty((1, 4)), np.empty((1, 4, 4))
    for k in range(x.shape[0]):
        _predict_row(x, P, k, h, qk, xs, Ps, 0)
        for i in range(4):
            x[k, i] = xs[0, i]
            for j in range(4):
                P[k, i, j] = Ps[0, i, j]


@njit(cache=True, inline="always")
def _joseph(A, P, k, R, m, K, Po, o, B):  # type: ignore[no-untyped-def]
    """``Po[o]`` = A P_k Aᵀ + K[o] R_k K[o]ᵀ (Joseph form, upper triangle mirrored), ``A``
    = I − K H given; ``B`` (4, 4) scratch. Shared by the generic and the H-specialised row."""
    for i in range(4):  # B = A P
        for j in range(4):
            acc = 0.0
            for l in range(4):
                acc += A[i, l] * P[k, l, j]
            B[i, j] = acc
    for i in range(4):
        for j in range(i, 4):
            acc = 0.0
            for l in range(4):
                acc += B[i, l] * A[j, l]
            for a in range(m):
                kr = 0.0
                for b in range(m):
                    kr += R[k, a, b] * K[o, j, b]
                acc += K[o, i, a] * kr
            Po[o, i, j] = acc
            Po[o, j, i] = acc


@njit(cache=True)
def _update_row(x, P, z, R, H, k, xo, Po, Ko, So, yo, o, PHt, Si, work, A, B):  # type: ignore[no-untyped-def]
    """Joseph-form update of target ``k`` of ``x``/``P``/``z``/``R`` into row ``o`` of
    ``xo``/``Po``/``Ko``/``So``/``yo`` (``PHt`` (4, m), ``Si``, ``work`` (m, m), ``A``,
    ``B`` (4, 4) are scratch); returns the NIS. :func:`_update_kernel` and the tracker's
    fused kernels share it, so their arithmetic is one."""
    m = H.shape[0]
    # y = z - H x
    for i in range(m):
        acc = z[k, i]
        for j in range(4):
            acc -= H[i, j] * x[k, j]
        yo[o, i] = acc
    # S = H P H^T + R
    for i in range(4):
        for j in range(m):
            acc = 0.0
            for l in range(4):
                acc += P[k, i, l] * H[j, l]
            PHt[i, j] = acc
    for i in range(m):
        for j in range(m):
            acc = 0.5 * (R[k, i, j] + R[k, j, i])
            for l in range(4):
                acc += 0.5 * (H[i, l] * PHt[l, j] + H[j, l] * PHt[l, i])
            So[o, i, j] = acc
    # K = P H^T S^-1
    inv_into(So[o], Si, work)
    for i in range(4):
        for j in range(m):
            acc = 0.0
            for l in range(m):
                acc += PHt[i, l] * Si[l, j]
            Ko[o, i, j] = acc
    # x = x + K y
    for i in range(4):
        acc = x[k, i]
        for j in range(m):
            acc += Ko[o, i, j] * yo[o, j]
        xo[o, i] = acc
    # P = (I - K H) P (I - K H)^T + K R K^T   (Joseph form); A = I - K H
    for i in range(4):
        for j in range(4):
            acc = 1.0 if i == j else 0.0
            for l in range(m):
                acc -= Ko[o, i, l] * H[l, j]
            A[i, j] = acc
    _joseph(A, P, k, R, m, Ko, Po, o, B)
    acc = 0.0
    for i in range(m):
        for j in range(m):
            acc += yo[o, i] * Si[i, j] * yo[o, j]
    return acc


@njit(cache=True, inline="always")
def _update_row_h(x, P, z, R, m, k, xo, Po, K, S, Si, work, A, B):  # type: ignore[no-untyped-def]
    """:func:`_update_row` for ``H = [I_m 0]`` (``m`` = 2: :data:`H_POSITION`, 4:
    :data:`H_FULL`) into ``xo[0]``, ``Po[0]``, ``K[0]`` (``S``, ``Si``, ``work``: (m, m),
    ``A``, ``B``: (4, 4) scratch); returns the NIS.

    The same operations in the same order as the generic row without the products by
    the zeros and ones of ``H``: adding ``0 * v`` or multiplying by 1 leaves a finite
    value unchanged, so the results are equal bit for bit (up to the sign of a zero) for
    finite inputs; the tracker deletes a track with a non-finite estimate anyway. Inlined
    (numba IR) into its callers, which pass ``m`` as a constant: the loops unroll, ~2-3×
    faster than the generic row.
    """
    y0 = z[k, 0] - x[k, 0]
    y1 = z[k, 1] - x[k, 1]
    y2 = z[k, 2] - x[k, 2] if m == 4 else 0.0
    y3 = z[k, 3] - x[k, 3] if m == 4 else 0.0
    # S = 0.5 (R + Rᵀ) + Σ_l 0.5 (H[i, l] PHᵀ[l, j] + H[j, l] PHᵀ[l, i]), PHᵀ[l, j] = P[l, j]
    for i in range(m):
        for j in range(m):
            acc = 0.5 * (R[k, i, j] + R[k, j, i])
            if i == j:
                acc += 0.5 * (P[k, i, i] + P[k, i, i])
            elif i < j:
                acc += 0.5 * P[k, i, j]
                acc += 0.5 * P[k, j, i]
            else:
                acc += 0.5 * P[k, j, i]
                acc += 0.5 * P[k, i, j]
            S[i, j] = acc
    inv_into_m(S, Si, work, m)
    for i in range(4):  # K = P Hᵀ S⁻¹
        for j in range(m):
            acc = 0.0
            for l in range(m):
                acc += P[k, i, l] * Si[l, j]
            K[0, i, j] = acc
    for i in range(4):
        acc = x[k, i] + K[0, i, 0] * y0
        acc += K[0, i, 1] * y1
        if m == 4:
            acc += K[0, i, 2] * y2
            acc += K[0, i, 3] * y3
        xo[0, i] = acc
    for i in range(4):  # A = I - K H
        for j in range(4):
            acc = 1.0 if i == j else 0.0
            if j < m:
                acc -= K[0, i, j]
            A[i, j] = acc
    _joseph(A, P, k, R, m, K, Po, 0, B)
    yy = (y0, y1, y2, y3)
    acc = 0.0
    for i in range(m):
        for j in range(m):
            acc += yy[i] * Si[i, j] * yy[j]
    return acc


@njit(cache=True)
def _update_kernel(x, P, z, R, H):  # type: ignore[no-untyped-def]
    n, m = x.shape[0], H.shape[0]
    xo = np.empty_like(x)
    Po = np.empty_like(P)
    Ko = np.empty((n, 4, m))
    So = np.empty((n, m, m))
    yo = np.empty((n, m))
    nis = np.empty(n)
    PHt = np.empty((4, m))
    Si = np.empty((m, m))
    work = np.empty((m, m))
    A = np.empty((4, 4))
    B = np.empty((4, 4))
    for k in range(n):
        nis[k] = _update_row(x, P, z, R, H, k, xo, Po, Ko, So, yo, k, PHt, Si, work, A, B)
    return xo, Po, Ko, So, yo, nis


def _dt(dt_s: ArrayLike, n: int) -> _F8:
    dt = np.broadcast_to(np.asarray(dt_s, dtype=np.float64), (n,))
    if not (np.isfinite(dt) & (dt >= 0.0)).all():
        i = int(np.flatnonzero(~(np.isfinite(dt) & (dt >= 0.0)))[0])
        raise StateError(f"dt_s must be finite and >= 0 s, actually: dt_s[{i}] = {dt[i]!r}")
    return dt


def cv_transition(dt_s: ArrayLike) -> _F8:
    """Transition matrices :math:`A(\\Delta t)` of the CV model, shape (n, 4, 4).

    Parameters
    ----------
    dt_s : array_like, shape (n,)
        Time steps [s], >= 0.
    """
    dt = _dt(dt_s, np.size(dt_s))
    F = np.broadcast_to(np.eye(4), (dt.size, 4, 4)).copy()
    F[:, 0, 2] = dt
    F[:, 1, 3] = dt
    return F


def cv_process_noise(dt_s: ArrayLike, q: ArrayLike) -> _F8:
    """Process noise :math:`Q(\\Delta t)` of white acceleration, shape (n, 4, 4).

    Parameters
    ----------
    dt_s : array_like, shape (n,)
        Time steps [s], >= 0.
    q : array_like, shape (n,) or scalar
        Spectral density of the acceleration noise [m²/s³], >= 0 (per axis).
    """
    dt = _dt(dt_s, np.size(dt_s))
    qq = np.broadcast_to(np.asarray(q, dtype=np.float64), dt.shape)
    if not (np.isfinite(qq) & (qq >= 0.0)).all():
        raise ParameterError(f"q must be finite and >= 0 m²/s³, actually: {np.asarray(q)!r}")
    Q = np.zeros((dt.size, 4, 4))
    q3, q2, q1 = qq * dt**3 / 3.0, qq * dt**2 / 2.0, qq * dt
    for i in (0, 1):
        Q[:, i, i] = q3
        Q[:, i, i + 2] = q2
        Q[:, i + 2, i] = q2
        Q[:, i + 2, i + 2] = q1
    return Q


def _check_xP(x: ArrayLike, P: ArrayLike) -> tuple[_F8, _F8]:
    xx = np.asarray(x, dtype=np.float64)
    PP = np.asarray(P, dtype=np.float64)
    if xx.ndim != 2 or xx.shape[1] != 4 or PP.shape != (xx.shape[0], 4, 4):
        raise StateError(f"x must be (n, 4) and P (n, 4, 4), actually: {xx.shape} and {PP.shape}")
    return xx, PP


def cv_predict(x: ArrayLike, P: ArrayLike, dt_s: ArrayLike, q: ArrayLike) -> tuple[_F8, _F8]:
    """Predict all targets ``dt_s`` ahead with the CV model.

    Parameters
    ----------
    x : array_like, shape (n, 4)
        Means ``[north_m, east_m, v_north_m_s, v_east_m_s]``.
    P : array_like, shape (n, 4, 4)
        Covariances [m², m²/s, m²/s²].
    dt_s : array_like, shape (n,) or scalar
        Time steps [s], >= 0 (0 leaves the state unchanged).
    q : array_like, shape (n,) or scalar
        Acceleration noise spectral density [m²/s³].

    Returns
    -------
    x_pred : ndarray, shape (n, 4)
    P_pred : ndarray, shape (n, 4, 4)
    """
    xx, PP = _check_xP(x, P)
    n = xx.shape[0]
    dt = np.ascontiguousarray(_dt(dt_s, n))
    qq = np.ascontiguousarray(np.broadcast_to(np.asarray(q, dtype=np.float64), (n,)))
    if not (np.isfinite(qq) & (qq >= 0.0)).all():
        raise ParameterError(f"q must be finite and >= 0 m²/s³, actually: {np.asarray(q)!r}")
    # x = A x ; P = A P A^T + Q   (numba kernel, same algebra as cv_transition/cv_process_noise)
    return _predict_kernel(np.ascontiguousarray(xx), np.ascontiguousarray(PP), dt, qq)


@dataclass(frozen=True)
class KalmanUpdate:
    """Result of a batched update.

    Attributes
    ----------
    x, P : ndarray, shapes (n, 4), (n, 4, 4)
        Posterior means and covariances.
    K : ndarray, shape (n, 4, m)
        Kalman gains.
    S : ndarray, shape (n, m, m)
        Innovation covariances.
    innovation : ndarray, shape (n, m)
        Residuals :math:`z - H \\check x`.
    nis : ndarray, shape (n,)
        Normalised innovation squared :math:`\\tilde y^T S^{-1} \\tilde y` (χ² with m dof).
    """

    x: _F8
    P: _F8
    K: _F8
    S: _F8
    innovation: _F8
    nis: _F8


def kalman_update(x: ArrayLike, P: ArrayLike, z: ArrayLike, R: ArrayLike, H: ArrayLike = H_POSITION) -> KalmanUpdate:
    """Correct all targets with one measurement each (Joseph form).

    Parameters
    ----------
    x, P : array_like, shapes (n, 4), (n, 4, 4)
        Prior means and covariances.
    z : array_like, shape (n, m)
        Measurements (NED position [m], and velocity [m/s] when m = 4).
    R : array_like, shape (n, m, m)
        Measurement covariances, symmetric positive definite.
    H : array_like, shape (m, 4)
        Measurement matrix (:data:`H_POSITION` or :data:`H_FULL`).

    Returns
    -------
    KalmanUpdate
    """
    xx, PP = _check_xP(x, P)
    HH = np.asarray(H, dtype=np.float64)
    zz = np.asarray(z, dtype=np.float64)
    RR = np.asarray(R, dtype=np.float64)
    m = HH.shape[0]
    n = xx.shape[0]
    if HH.shape != (m, 4) or zz.shape != (n, m) or RR.shape != (n, m, m):
        raise StateError(f"z must be (n, m), R (n, m, m), H (m, 4); actually: {zz.shape}, {RR.shape}, {HH.shape}")
    if not (np.isfinite(zz).all() and np.isfinite(RR).all()):
        raise StateError("z and R must be finite, actually: NaN or inf present")
    xn, Pn, K, S, y, nis = _update_kernel(np.ascontiguousarray(xx), np.ascontiguousarray(PP),
                                          np.ascontiguousarray(zz), np.ascontiguousarray(RR), np.ascontiguousarray(HH))
    return KalmanUpdate(x=xn, P=Pn, K=K, S=S, innovation=y, nis=nis)
