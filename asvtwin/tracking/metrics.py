"""Tracking metrics: RMSE, NEES with its χ² bounds, GOSPA, track breaks and false tracks.

- **NEES** :math:`\\epsilon = (x - \\hat x)^T \\hat P^{-1} (x - \\hat x)` is χ² with ``d``
  degrees of freedom for a consistent filter; the average over ``N`` independent samples
  lies, with probability ``1 - α``, in
  :math:`[\\chi^2_{Nd}(\\alpha/2)/N,\\ \\chi^2_{Nd}(1 - \\alpha/2)/N]` (Bar-Shalom et al.,
  *Estimation with Applications to Tracking and Navigation*, §5.4).
- **GOSPA** (Rahmathullah, García-Fernández, Svensson 2017) with :math:`\\alpha = 2`:

  .. math:: d = \\Big(\\min_\\gamma \\sum_{(i,j)\\in\\gamma} d(x_i, y_j)^p
            + \\tfrac{c^p}{2}(|X| + |Y| - 2|\\gamma|)\\Big)^{1/p},

  over assignments :math:`\\gamma` of pairs closer than ``c``; it splits into localisation,
  missed-target and false-target parts. Solved exactly by
  ``scipy.optimize.linear_sum_assignment`` on :math:`\\min(d, c)^p`.
- **Breaks and false tracks** from the per-step assignment of tracks to true targets.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment
from scipy.stats import chi2

from asvtwin.checks import F8 as _F8
from asvtwin.errors import ParameterError, StateError

__all__ = [
    "GospaResult",
    "assign_tracks",
    "effective_sample_size",
    "false_tracks",
    "gospa",
    "nees",
    "nees_bounds",
    "rmse",
    "track_breaks",
]



def rmse(estimates: ArrayLike, truths: ArrayLike) -> float:
    """Root mean square of the Euclidean error over all leading axes.

    Parameters
    ----------
    estimates, truths : array_like, shape (..., d)
        E.g. positions (T, 2) [m] or velocities [m/s]; rows with NaN are ignored.

    Returns
    -------
    float
        RMSE in the unit of the inputs (NaN when no valid row).
    """
    e = np.asarray(estimates, dtype=np.float64) - np.asarray(truths, dtype=np.float64)
    sq = (e**2).sum(axis=-1).reshape(-1)
    sq = sq[np.isfinite(sq)]
    return float(np.sqrt(sq.mean())) if sq.size else float("nan")


def nees(mean: ArrayLike, cov: ArrayLike, truth: ArrayLike) -> _F8:
    """Normalised estimation error squared of each estimate.

    Parameters
    ----------
    mean : array_like, shape (..., d)
    cov : array_like, shape (..., d, d)
    truth : array_like, shape (..., d)

    Returns
    -------
    ndarray, shape (...)
    """
    x = np.asarray(mean, dtype=np.float64)
    P = np.asarray(cov, dtype=np.float64)
    e = np.asarray(truth, dtype=np.float64) - x
    if P.shape != x.shape + x.shape[-1:] or e.shape != x.shape:
        raise StateError(f"mean (..., d), cov (..., d, d) and truth (..., d) must agree, actually: {x.shape}, {P.shape}, {e.shape}")
    return np.einsum("...i,...i->...", e, np.linalg.solve(P, e[..., None])[..., 0])


def nees_bounds(dof: int, n_samples: float, probability: float = 0.95) -> tuple[float, float]:
    """Two-sided χ² bounds of the average NEES of ``n_samples`` consistent estimates.

    Parameters
    ----------
    dof : int
        State dimension ``d``.
    n_samples : float
        Number of independent NEES values averaged (e.g. Monte Carlo runs), or an
        effective sample size (:func:`effective_sample_size`) for correlated ones.
    probability : float
        Coverage of the interval, e.g. 0.95.

    Returns
    -------
    (low, high) : tuple of float
    """
    if dof < 1 or n_samples < 1 or not 0.0 < probability < 1.0:
        raise ParameterError(f"need dof >= 1, n_samples >= 1, probability in (0, 1); actually: {dof}, {n_samples}, {probability}")
    a = 0.5 * (1.0 - probability)
    k = dof * n_samples
    return float(chi2.ppf(a, k) / n_samples), float(chi2.ppf(1.0 - a, k) / n_samples)


def effective_sample_size(series: Sequence[ArrayLike]) -> tuple[float, int]:
    """Effective number of independent samples in the mean of time-correlated series.

    Each series is one estimate's NEES (or any statistic) at regular steps, e.g. one track
    following one vessel; different series are independent. With the pooled mean and
    variance, the autocorrelation ``ρ(ℓ)`` is estimated from all series together and
    summed over lags by Geyer's initial positive sequence (pairs ``ρ(2m) + ρ(2m + 1)``
    while positive; Geyer 1992, "Practical Markov chain Monte Carlo"). Then
    ``Var(mean) = σ² Σᵢ [nᵢ + 2 Σ_ℓ (nᵢ − ℓ) ρ(ℓ)] / N²`` and ``n_eff = σ² / Var(mean)``,
    clipped to ``[1, N]``. With :func:`nees_bounds` this gives χ² bounds whose variance
    matches that of the correlated mean (a scaled χ², Satterthwaite's approximation).

    Returns
    -------
    (n_eff, n) : tuple of float and int
        The effective sample size and the number of samples ``N``.
    """
    xs = [np.asarray(x, dtype=np.float64).reshape(-1) for x in series]
    xs = [x for x in xs if x.size]
    if not xs or not all(np.isfinite(x).all() for x in xs):
        raise ParameterError("effective_sample_size needs non-empty finite series")
    lengths = np.array([x.size for x in xs])
    n = int(lengths.sum())
    allx = np.concatenate(xs)
    mu, var = float(allx.mean()), float(allx.var())
    if n < 2 or not var > 0.0:
        return float(n), n
    cs = [x - mu for x in xs]
    max_lag = int(lengths.max()) - 1

    def rho(lag: int) -> float:
        num = sum(float(c[:-lag] @ c[lag:]) for c in cs if c.size > lag)
        cnt = int(np.maximum(lengths - lag, 0).sum())
        return num / (var * cnt) if cnt else 0.0

    total = lengths.astype(np.float64)  # Σ_i n_i + 2 Σ_ℓ (n_i − ℓ) ρ(ℓ), per series
    m = 0
    while 2 * m + 1 <= max_lag:
        r0 = 1.0 if m == 0 else rho(2 * m)
        r1 = rho(2 * m + 1)
        if r0 + r1 <= 0.0:
            break
        if m > 0:
            total += 2.0 * np.maximum(lengths - 2 * m, 0) * r0
        total += 2.0 * np.maximum(lengths - (2 * m + 1), 0) * r1
        m += 1
    n_eff = n * n / float(total.sum())
    return float(min(max(n_eff, 1.0), n)), n


@dataclass(frozen=True)
class GospaResult:
    """GOSPA distance and its parts (α = 2).

    Attributes
    ----------
    distance : float
        The GOSPA metric [m].
    localisation : float
        :math:`\\sum d^p` over assigned pairs [m^p].
    missed : int
        True targets without an estimate.
    false : int
        Estimates without a true target.
    pairs : ndarray of int64, shape (k, 2)
        Assigned ``(estimate, truth)`` index pairs.
    """

    distance: float
    localisation: float
    missed: int
    false: int
    pairs: NDArray[np.int64]


def gospa(estimates: ArrayLike, truths: ArrayLike, *, c: float = 50.0, p: float = 2.0) -> GospaResult:
    """GOSPA between a set of estimated and a set of true positions.

    Parameters
    ----------
    estimates : array_like, shape (n, d)
    truths : array_like, shape (m, d)
    c : float, default 50.0
        Cut-off distance [m], > 0.
    p : float, default 2.0
        Order, >= 1.

    Returns
    -------
    GospaResult
    """
    if not (c > 0 and p >= 1):
        raise ParameterError(f"gospa needs c > 0 and p >= 1, actually: c={c!r}, p={p!r}")
    X = np.asarray(estimates, dtype=np.float64).reshape(-1, np.shape(truths)[-1] if np.size(truths) else 2)
    Y = np.asarray(truths, dtype=np.float64).reshape(-1, X.shape[1])
    n, m = len(X), len(Y)
    pairs = np.empty((0, 2), np.int64)
    loc = 0.0
    if n and m:
        D = np.minimum(np.linalg.norm(X[:, None, :] - Y[None, :, :], axis=-1), c) ** p
        r, k = linear_sum_assignment(D)
        ok = D[r, k] < c**p
        pairs = np.column_stack([r[ok], k[ok]]).astype(np.int64)
        loc = float(D[r[ok], k[ok]].sum())
    missed, false = m - len(pairs), n - len(pairs)
    dist = (loc + 0.5 * c**p * (missed + false)) ** (1.0 / p)
    return GospaResult(distance=float(dist), localisation=loc, missed=int(missed), false=int(false), pairs=pairs)


def assign_tracks(track_positions: ArrayLike, track_ids: ArrayLike, truth_positions: ArrayLike,
                  *, gate_m: float = 50.0) -> NDArray[np.int64]:
    """Which track follows each true target at one step (optimal, within ``gate_m``).

    Parameters
    ----------
    track_positions : array_like, shape (n, 2)
    track_ids : array_like of int, shape (n,)
    truth_positions : array_like, shape (m, 2)
    gate_m : float
        Largest distance of a valid pair [m].

    Returns
    -------
    ndarray of int64, shape (m,)
        Track id per true target, -1 where none.
    """
    g = gospa(track_positions, truth_positions, c=gate_m, p=2.0)
    out = np.full(len(np.asarray(truth_positions).reshape(-1, 2)), -1, np.int64)
    ids = np.asarray(track_ids, dtype=np.int64)
    out[g.pairs[:, 1]] = ids[g.pairs[:, 0]]
    return out


def track_breaks(assigned: ArrayLike) -> NDArray[np.int64]:
    """Track breaks per true target: changes of the following track id over time.

    Parameters
    ----------
    assigned : array_like of int, shape (T, m)
        :func:`assign_tracks` output per step (-1 = no track).

    Returns
    -------
    ndarray of int64, shape (m,)
        Number of times the target's track id changed to a different id (gaps with the
        same id on both sides are not breaks).
    """
    A = np.asarray(assigned, dtype=np.int64)
    if A.ndim != 2:
        raise StateError(f"assigned must be (T, m), actually: {A.shape}")
    out = np.zeros(A.shape[1], np.int64)
    for j in range(A.shape[1]):
        seq = A[:, j][A[:, j] >= 0]
        out[j] = int((seq[1:] != seq[:-1]).sum())
    return out


def false_tracks(confirmed_ids_per_step: list[ArrayLike], assigned: ArrayLike) -> set[int]:
    """Ids of confirmed tracks that never followed any true target.

    Parameters
    ----------
    confirmed_ids_per_step : list of array_like of int
        Confirmed track ids at each step.
    assigned : array_like of int, shape (T, m)
        :func:`assign_tracks` output per step.

    Returns
    -------
    set of int
    """
    seen = {int(i) for ids in confirmed_ids_per_step for i in np.asarray(ids).reshape(-1)}
    used = {int(i) for i in np.asarray(assigned).reshape(-1) if i >= 0}
    return seen - used
