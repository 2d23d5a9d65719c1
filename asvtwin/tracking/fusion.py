"""Late fusion of LiDAR and AIS: the paper's product of Gaussians, Chen 2019, covariance intersection.

**Product of Gaussians** (paper eq. Sensor_fusion, the default). For each target the
posterior is the normalised product of the CV prediction and whichever measurements
arrived, the four cases

.. math::

    \\mathcal N(\\hat x, \\hat P) \\propto \\mathcal N(\\check x, \\check P)
        \\,[\\mathcal N(z_L, R_L)]^{\\,l}\\,[\\mathcal N(z_A, R_A)]^{\\,a},
    \\qquad l, a \\in \\{0, 1\\},

computed in information form, :math:`\\hat P^{-1} = \\check P^{-1} + l H_L^T R_L^{-1} H_L
+ a H_A^T R_A^{-1} H_A` and :math:`\\hat P^{-1}\\hat x = \\check P^{-1}\\check x
+ l H_L^T R_L^{-1} z_L + a H_A^T R_A^{-1} z_A`. It equals sequential Kalman updates and is
exact when the measurement errors are independent.

**Chen 2019 gain weighting** (paper eq. sensor_fusion_literature): two CV filters, one per
sensor; with their gains mapped to the state, :math:`G_i = K_i H_i` (so a position-only
LiDAR gain and a full AIS gain can be added),

.. math::

    W_{AIS} = G_L (G_A + G_L)^{-1}, \\quad W_L = G_A (G_A + G_L)^{-1}, \\quad
    x = W_{AIS} x_{AIS} + W_L x_L,

so :math:`W_{AIS} + W_L = I`. The paper gives no covariance; we use
:math:`P = W_A P_A W_A^T + W_L P_L W_L^T` (independent estimates).

**Covariance intersection** (Julier & Uhlmann): :math:`P^{-1} = \\omega P_A^{-1}
+ (1-\\omega) P_L^{-1}`, :math:`P^{-1}x = \\omega P_A^{-1} x_A + (1-\\omega) P_L^{-1} x_L`,
:math:`\\omega \\in [0, 1]` minimising :math:`\\det P`. Consistent for any unknown
correlation between the two estimates (two filters that share a process model are
correlated, which the product ignores); :math:`\\det P^{-1}(\\omega)` is a quartic in
:math:`\\omega`, so it is sampled at 5 points, interpolated exactly and maximised on a grid.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.errors import ParameterError, StateError
from asvtwin.tracking.kalman import H_FULL, H_POSITION
from asvtwin.tracking.smallmat import inv_into, inv_into_m

__all__ = ["FUSION_METHODS", "fuse_covariance_intersection", "fuse_gain_weighted", "fuse_product"]


#: Fusion methods understood by the tracker.
FUSION_METHODS = ("product", "gain_weighted", "covariance_intersection")


def _sym(P: NDArray[np.floating]) -> _F8:
    return 0.5 * (P + P.transpose(0, 2, 1))


@njit(cache=True)
def _add_information(Y, y, H, R, z, Ri, work):  # type: ignore[no-untyped-def]
    """Y += H^T R^-1 H ; y += H^T R^-1 z  (the information of N(z, R))."""
    m = H.shape[0]
    inv_into(R, Ri, work)
    for i in range(4):
        for j in range(m):
            hr = 0.0
            for a in range(m):
                hr += H[a, i] * Ri[a, j]
            y[i] += hr * z[j]
            for c in range(4):
                Y[i, c] += hr * H[j, c]


@njit(cache=True, inline="always")
def _prior_information(x, P, k, Y, y, w4):  # type: ignore[no-untyped-def]
    """Y = P_k^-1, y = Y x_k: target ``k``'s prior in information form."""
    inv_into_m(P[k], Y, w4, 4)
    for i in range(4):
        acc = 0.0
        for j in range(4):
            acc += Y[i, j] * x[k, j]
        y[i] = acc


@njit(cache=True, inline="always")
def _posterior(Y, y, Pn, w4, k, xo, Po):  # type: ignore[no-untyped-def]
    """``Po[k]`` = (sym Y)^-1 symmetrised, ``xo[k]`` = Po[k] y: back from information form."""
    for i in range(4):
        for j in range(i + 1, 4):
            v = 0.5 * (Y[i, j] + Y[j, i])
            Y[i, j] = v
            Y[j, i] = v
    inv_into_m(Y, Pn, w4, 4)
    for i in range(4):
        acc = 0.0
        for j in range(4):
            v = 0.5 * (Pn[i, j] + Pn[j, i])
            Po[k, i, j] = v
            acc += v * y[j]
        xo[k, i] = acc


@njit(cache=True)
def _product_row(x, P, zL, RL, hL, HL, zA, RA, hA, HA, k, xo, Po, Y, Pn, w4, y, RiL, wL, RiA, wA):  # type: ignore[no-untyped-def]
    """The product of target ``k``'s prior and its measurements into ``xo[k]``, ``Po[k]``
    (left alone when neither sensor measured it); the other arrays are scratch.
    :func:`_product_kernel` and the tracker's fused kernel share it."""
    if not (hL[k] or hA[k]):
        return  # case: neither sensor -> N(x, P)
    _prior_information(x, P, k, Y, y, w4)
    if hL[k]:
        _add_information(Y, y, HL, RL[k], zL[k], RiL, wL)
    if hA[k]:
        _add_information(Y, y, HA, RA[k], zA[k], RiA, wA)
    _posterior(Y, y, Pn, w4, k, xo, Po)


@njit(cache=True, inline="always")
def _add_information_h(Y, y, m, R, z, Ri, work):  # type: ignore[no-untyped-def]
    """:func:`_add_information` for ``H = [I_m 0]``: the same sums without the products by
    ``H``'s zeros and ones (equal bit for bit for finite inputs; ``0.0 + v`` as the
    generic sum starts)."""
    inv_into_m(R, Ri, work, m)
    for i in range(m):
        for j in range(m):
            hr = 0.0 + Ri[i, j]
            y[i] += hr * z[j]
            Y[i, j] += hr


@njit(cache=True, inline="always")
def _product_row_h(x, P, zL, RL, hL, zA, RA, hA, k, xo, Po, Y, Pn, w4, y, RiL, wL, RiA, wA):  # type: ignore[no-untyped-def]
    """:func:`_product_row` with ``H_L`` = :data:`H_POSITION`, ``H_A`` = :data:`H_FULL`
    (:func:`_add_information_h`) of a row at least one sensor measured: the caller skips
    the others (the tracker's fused kernel, its user, does; an early return here kept
    ~15 reference counts per row that numba could not prune)."""
    _prior_information(x, P, k, Y, y, w4)
    if hL[k]:
        _add_information_h(Y, y, 2, RL[k], zL[k], RiL, wL)
    if hA[k]:
        _add_information_h(Y, y, 4, RA[k], zA[k], RiA, wA)
    _posterior(Y, y, Pn, w4, k, xo, Po)


@njit(cache=True)
def _product_kernel(x, P, zL, RL, hL, HL, zA, RA, hA, HA):  # type: ignore[no-untyped-def]
    n = x.shape[0]
    xo = x.copy()
    Po = P.copy()
    Y = np.empty((4, 4))
    Pn = np.empty((4, 4))
    w4 = np.empty((4, 4))
    y = np.empty(4)
    RiL, wL = np.empty((HL.shape[0], HL.shape[0])), np.empty((HL.shape[0], HL.shape[0]))
    RiA, wA = np.empty((HA.shape[0], HA.shape[0])), np.empty((HA.shape[0], HA.shape[0]))
    for k in range(n):
        _product_row(x, P, zL, RL, hL, HL, zA, RA, hA, HA, k, xo, Po, Y, Pn, w4, y, RiL, wL, RiA, wA)
    return xo, Po


def fuse_product(
    x: ArrayLike,
    P: ArrayLike,
    *,
    z_lidar: ArrayLike | None = None,
    R_lidar: ArrayLike | None = None,
    has_lidar: ArrayLike | None = None,
    z_ais: ArrayLike | None = None,
    R_ais: ArrayLike | None = None,
    has_ais: ArrayLike | None = None,
    H_lidar: ArrayLike = H_POSITION,
    H_ais: ArrayLike = H_FULL,
) -> tuple[_F8, _F8]:
    """The paper's fusion cases as a product of Gaussians, batched over targets.

    Parameters
    ----------
    x, P : array_like, shapes (n, 4), (n, 4, 4)
        CV predictions :math:`\\check x, \\check P`.
    z_lidar, R_lidar : array_like, shapes (n, 2), (n, 2, 2), optional
        LiDAR position measurements; rows where ``has_lidar`` is False are ignored
        (may hold anything finite or NaN).
    has_lidar : array_like of bool, shape (n,), optional
        Which targets have a LiDAR measurement (default: all when ``z_lidar`` given).
    z_ais, R_ais : array_like, shapes (n, 4), (n, 4, 4), optional
        AIS measurements (position and velocity).
    has_ais : array_like of bool, shape (n,), optional
        Which targets have an AIS measurement.
    H_lidar, H_ais : array_like
        Measurement matrices (defaults: position for LiDAR, full state for AIS).

    Returns
    -------
    x_hat, P_hat : ndarray, shapes (n, 4), (n, 4, 4)
        Posterior; rows with neither measurement are the prediction unchanged (case 4).
    """
    xx = np.array(x, dtype=np.float64)
    PP = np.array(P, dtype=np.float64)
    n = xx.shape[0]
    if xx.shape != (n, 4) or PP.shape != (n, 4, 4):
        raise StateError(f"x must be (n, 4) and P (n, 4, 4), actually: {xx.shape}, {PP.shape}")
    parts = []
    for z, R, has, H, dim in ((z_lidar, R_lidar, has_lidar, H_lidar, "lidar"), (z_ais, R_ais, has_ais, H_ais, "ais")):
        HH = np.ascontiguousarray(H, dtype=np.float64)
        m = HH.shape[0]
        if z is None:
            parts += [np.zeros((n, m)), np.tile(np.eye(m), (n, 1, 1)), np.zeros(n, bool), HH]
            continue
        mask = np.ones(n, bool) if has is None else np.asarray(has, bool).copy()
        zz = np.array(z, dtype=np.float64).reshape(n, m)
        RR = np.array(R, dtype=np.float64).reshape(n, m, m)
        if not (np.isfinite(zz[mask]).all() and np.isfinite(RR[mask]).all()):
            raise StateError(f"{dim} measurements must be finite where present, actually: NaN or inf")
        zz[~mask], RR[~mask] = 0.0, np.eye(m)
        parts += [zz, RR, mask, HH]
    return _product_kernel(xx, PP, *parts)


def fuse_gain_weighted(
    x_ais: ArrayLike, P_ais: ArrayLike, G_ais: ArrayLike,
    x_lidar: ArrayLike, P_lidar: ArrayLike, G_lidar: ArrayLike,
    *, eps: float = 1e-9,
) -> tuple[_F8, _F8]:
    """Chen 2019 Kalman-gain weighting of an AIS and a LiDAR filter (paper eq. sensor_fusion_literature).

    Parameters
    ----------
    x_ais, P_ais : array_like, shapes (n, 4), (n, 4, 4)
        The AIS filter's estimate.
    G_ais : array_like, shape (n, 4, 4)
        Its last gain mapped to the state, :math:`K_{AIS} H_{AIS}`.
    x_lidar, P_lidar, G_lidar : array_like
        The same for the LiDAR filter.
    eps : float
        Ridge added to :math:`G_A + G_L` before inversion (a gain has zero columns for
        unmeasured states) [-].

    Returns
    -------
    x, P : ndarray, shapes (n, 4), (n, 4, 4)
    """
    xa, Pa, Ga = (np.asarray(a, dtype=np.float64) for a in (x_ais, P_ais, G_ais))
    xl, Pl, Gl = (np.asarray(a, dtype=np.float64) for a in (x_lidar, P_lidar, G_lidar))
    Sinv = np.linalg.inv(Ga + Gl + eps * np.eye(4))
    W_ais = Gl @ Sinv  # W_AIS = K_L (K_A + K_L)^-1
    W_lid = Ga @ Sinv  # W_L = K_A (K_A + K_L)^-1
    x = np.einsum("nij,nj->ni", W_ais, xa) + np.einsum("nij,nj->ni", W_lid, xl)
    P = W_ais @ Pa @ W_ais.transpose(0, 2, 1) + W_lid @ Pl @ W_lid.transpose(0, 2, 1)
    return x, _sym(P)


def fuse_covariance_intersection(
    x_a: ArrayLike, P_a: ArrayLike, x_b: ArrayLike, P_b: ArrayLike, *, n_grid: int = 101
) -> tuple[_F8, _F8, _F8]:
    """Covariance intersection of two estimates with unknown correlation (det-optimal ω).

    Parameters
    ----------
    x_a, P_a, x_b, P_b : array_like, shapes (n, d), (n, d, d)
        The two estimates.
    n_grid : int, default 101
        Grid points of ω in [0, 1] on which the interpolated quartic is maximised.

    Returns
    -------
    x, P : ndarray, shapes (n, d), (n, d, d)
        The fused estimate.
    omega : ndarray, shape (n,)
        Weight of estimate ``a``.
    """
    if n_grid < 5:
        raise ParameterError(f"n_grid must be >= 5, actually: {n_grid!r}")
    xa, Pa, xb, Pb = (np.asarray(a, dtype=np.float64) for a in (x_a, P_a, x_b, P_b))
    Ya, Yb = _sym(np.linalg.inv(Pa)), _sym(np.linalg.inv(Pb))
    nodes = np.linspace(0.0, 1.0, 5)
    dets = np.linalg.det(nodes[None, :, None, None] * Ya[:, None] + (1.0 - nodes)[None, :, None, None] * Yb[:, None])
    coef = np.linalg.solve(np.vander(nodes, 5), dets.T).T  # det Y(ω), exact quartic
    w = np.linspace(0.0, 1.0, int(n_grid))
    vals = coef @ np.vander(w, 5).T
    omega = w[np.argmax(vals, axis=1)]
    Y = omega[:, None, None] * Ya + (1.0 - omega)[:, None, None] * Yb
    P = _sym(np.linalg.inv(Y))
    y = omega[:, None] * np.einsum("nij,nj->ni", Ya, xa) + (1.0 - omega)[:, None] * np.einsum("nij,nj->ni", Yb, xb)
    return np.einsum("nij,nj->ni", P, y), P, omega
