"""Data association: Mahalanobis gating and global nearest neighbour (GNN).

For track ``i`` with predicted position covariance :math:`P_i` and measurement ``j`` with
covariance :math:`R_j`, the innovation covariance is :math:`S_{ij} = P_i + R_j` and

.. math::

    d^2_{ij} = (z_j - \\check p_i)^T S_{ij}^{-1} (z_j - \\check p_i), \\qquad
    c_{ij} = d^2_{ij} + \\ln \\det S_{ij} \\quad \\text{if } d^2_{ij} \\le \\gamma,

(the negative log-likelihood up to a constant, so a vague track does not win every
measurement); pairs outside the χ² gate :math:`\\gamma` are forbidden. The cost matrix is
filled by a numba kernel that skips a pair cheaply when
:math:`|z_j - \\check p_i|^2 > \\gamma\\, \\mathrm{tr}\\, S_{ij}` (then :math:`d^2 > \\gamma`
since :math:`\\lambda_{max} \\le \\mathrm{tr}`). GNN is the optimal one-to-one assignment
(``scipy.optimize.linear_sum_assignment``) on the rows and columns that have any gated
pair; forbidden pairs cost a large constant and are dropped from the result.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment
from scipy.stats import chi2

from asvtwin.checks import F8 as _F8
from asvtwin.errors import ParameterError, StateError

__all__ = ["FORBIDDEN", "gate_threshold", "gated_costs", "gnn_assign"]


#: Cost of a pair outside the gate.
FORBIDDEN = 1.0e12


def gate_threshold(probability: float, dof: int = 2) -> float:
    """χ² gate :math:`\\gamma` that keeps a true measurement with ``probability``.

    Parameters
    ----------
    probability : float
        Gate probability in (0, 1), e.g. 0.999.
    dof : int
        Measurement dimension.
    """
    if not 0.0 < probability < 1.0:
        raise ParameterError(f"gate probability must be in (0, 1), actually: {probability!r}")
    return float(chi2.ppf(probability, dof))


@njit(cache=True)
def _costs(p, Pp, z, R, gamma):  # type: ignore[no-untyped-def]
    n, k = p.shape[0], z.shape[0]
    cost = np.full((n, k), 1.0e12)
    d2 = np.full((n, k), np.inf)
    for i in range(n):
        for j in range(k):
            a = Pp[i, 0, 0] + R[j, 0, 0]
            b = Pp[i, 0, 1] + R[j, 0, 1]
            c = Pp[i, 1, 1] + R[j, 1, 1]
            dn, de = z[j, 0] - p[i, 0], z[j, 1] - p[i, 1]
            r2 = dn * dn + de * de
            if r2 > gamma * (a + c):
                continue
            det = a * c - b * b
            if not det > 0.0:
                continue
            m = (c * dn * dn - 2.0 * b * dn * de + a * de * de) / det
            d2[i, j] = m
            if m <= gamma:
                cost[i, j] = m + np.log(det)
    return cost, d2


def gated_costs(
    positions: ArrayLike, position_covs: ArrayLike, z: ArrayLike, R: ArrayLike, gamma: float
) -> tuple[_F8, _F8]:
    """Association costs of ``n`` tracks against ``k`` position measurements.

    Parameters
    ----------
    positions : array_like, shape (n, 2)
        Predicted track positions [m].
    position_covs : array_like, shape (n, 2, 2)
        Their covariances [m²].
    z : array_like, shape (k, 2)
        Measured positions [m].
    R : array_like, shape (k, 2, 2)
        Measurement covariances [m²].
    gamma : float
        χ² gate (see :func:`gate_threshold`).

    Returns
    -------
    cost : ndarray, shape (n, k)
        :math:`d^2 + \\ln\\det S` inside the gate, :data:`FORBIDDEN` outside.
    d2 : ndarray, shape (n, k)
        Squared Mahalanobis distances (``inf`` where skipped by the cheap bound).
    """
    p = np.ascontiguousarray(positions, dtype=np.float64).reshape(-1, 2)
    Pp = np.ascontiguousarray(position_covs, dtype=np.float64).reshape(-1, 2, 2)
    zz = np.ascontiguousarray(z, dtype=np.float64).reshape(-1, 2)
    RR = np.ascontiguousarray(R, dtype=np.float64).reshape(-1, 2, 2)
    if Pp.shape[0] != p.shape[0] or RR.shape[0] != zz.shape[0]:
        raise StateError(f"positions/covariances and z/R must pair up, actually: {p.shape}, {Pp.shape}, {zz.shape}, {RR.shape}")
    return _costs(p, Pp, zz, RR, float(gamma))


def gnn_assign(cost: ArrayLike) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Global nearest neighbour: optimal one-to-one pairs among the allowed ones.

    Parameters
    ----------
    cost : array_like, shape (n, k)
        Costs, :data:`FORBIDDEN` (or more) for forbidden pairs.

    Returns
    -------
    rows, cols : ndarray of int64
        Assigned (track, measurement) pairs, all allowed. Among the assignments with the
        most allowed pairs, the one of least total cost.
    """
    c = np.asarray(cost, dtype=np.float64)
    if c.ndim != 2:
        raise StateError(f"cost must be a 2-D matrix, actually: shape {c.shape}")
    r_idx, c_idx, sub = _allowed_block(np.ascontiguousarray(c), FORBIDDEN)
    if r_idx.size == 0:
        return np.empty(0, np.int64), np.empty(0, np.int64)
    rr, cc = linear_sum_assignment(sub)
    ok = sub[rr, cc] < FORBIDDEN
    return r_idx[rr[ok]], c_idx[cc[ok]]


@njit(cache=True)
def _allowed_block(c, forbidden):  # type: ignore[no-untyped-def]
    """The rows and columns of ``c`` with an allowed (``< forbidden``) entry, and the block
    of ``c`` on them with entries above ``forbidden`` lowered to it (``np.minimum``: NaN
    stays NaN)."""
    n, k = c.shape
    row_ok = np.zeros(n, np.bool_)
    col_ok = np.zeros(k, np.bool_)
    for i in range(n):
        for j in range(k):
            if c[i, j] < forbidden:
                row_ok[i] = True
                col_ok[j] = True
    r_idx = np.flatnonzero(row_ok)
    c_idx = np.flatnonzero(col_ok)
    sub = np.empty((r_idx.size, c_idx.size))
    for a in range(r_idx.size):
        for b in range(c_idx.size):
            v = c[r_idx[a], c_idx[b]]
            sub[a, b] = v if (v < forbidden or np.isnan(v)) else forbidden
    return r_idx.astype(np.int64), c_idx.astype(np.int64), sub
