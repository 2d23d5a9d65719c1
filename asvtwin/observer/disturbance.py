"""Nonlinear disturbance observer (NDO) for the 3-DOF vessel model, batched over vessels.

The model (paper, eq. (dynamics)) is M ν̇ + C(ν)ν + D(ν)ν = τ + τ_d. The classic NDO
(Chen 2000, the form used by Menges & Rasheed 2023 for ASVs) estimates τ_d as

.. math::

    \\hat{\\boldsymbol d} = \\boldsymbol z + \\boldsymbol p(\\boldsymbol\\nu), \\qquad
    \\dot{\\boldsymbol z} = -\\mathbf L\\boldsymbol z
        - \\mathbf L\\big(\\boldsymbol p(\\boldsymbol\\nu) + \\boldsymbol\\tau
        - \\mathbf C(\\boldsymbol\\nu)\\boldsymbol\\nu
        - \\mathbf D(\\boldsymbol\\nu)\\boldsymbol\\nu\\big), \\qquad
    \\mathbf L = \\frac{\\partial\\boldsymbol p}{\\partial\\boldsymbol\\nu}\\mathbf M^{-1}.

Choice made here: p(ν) = K M ν with K = diag(k_u, k_v, k_r) > 0, so L = K is constant.
The estimation error e = τ_d − d̂ then obeys, whatever ν does,

.. math:: \\dot{\\boldsymbol e} = -\\mathbf K\\boldsymbol e + \\dot{\\boldsymbol\\tau}_d,

decoupled per DOF: e → 0 exponentially with time constant T_i = 1/k_i for a constant
τ_d (90 % of a step in ln 10 · T_i ≈ 2.30 T_i), and |e_i| ≤ T_i · sup|τ̇_d,i| for a
slowly varying one (a sinusoid of angular frequency ω: |e| = A ωT/√(1+ω²T²)). The only
convergence condition is k_i > 0; no bound on ν or on C, D is needed because the
nonlinear terms are cancelled exactly by the measured ν.

Discrete time. With the simulator's zero-order hold (τ, τ_d constant over a step of
length h) the z-dynamics are integrated exactly for held input, with the discrete gain
k_d = (1 − e^{−k h}) / h in p(ν) = K_d M ν so that d̂ is unbiased at the sampling instants:

.. math::

    \\hat d_{k+1} = \\alpha\\hat d_k + (1-\\alpha)\\Big[\\mathbf M\\frac{\\nu_{k+1}
    - \\nu_k}{h} + \\bar n_k - \\tau_k\\Big],\\quad \\alpha = e^{-K h},

where n(ν) = C(ν)ν + D(ν)ν and n̄_k is its trapezoidal mean over the step. This is the
same observer written for the state z = d̂ − K_d M ν (kept internally), and it is
stable for any k > 0 and any step.

Sensor dropouts: a vessel whose measured ν or τ holds a NaN/inf keeps its estimate, is
flagged (``valid[i] = False``, ``stale_steps[i]`` counts the steps held) and re-anchors
on the next good sample (the momentum difference across a gap is not used).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from asvtwin.errors import ParameterError, StateError
from asvtwin.vessel.kernels import hydrodynamic_force as _n_nu
from asvtwin.vessel.params import VesselParams, cybership2

__all__ = [
    "GAIN_MIN",
    "DisturbanceObserver",
    "ObserverGains",
    "default_gains",
    "gain_range",
]

_log = logging.getLogger(__name__)
_DOF = ("surge", "sway", "yaw")

#: Smallest accepted observer gain [1/s] (time constant ≈ 28 h: no estimator at all).
GAIN_MIN = 1e-5

#: The predecessor code's model-scale gains Γ = diag(0.1, 0.1, 0.08) [1/s] (CyberShip II).
_MODEL_SCALE_GAINS = (0.1, 0.1, 0.08)


def gain_range(dt_s: float) -> tuple[float, float]:
    """Allowed gains [1/s]: from :data:`GAIN_MIN` to ``1 / dt_s``.

    Above 1/h the time constant is shorter than one sample: the estimate becomes the raw,
    differentiated measurement noise, which no user wants.
    """
    return GAIN_MIN, 1.0 / dt_s


@dataclass(frozen=True, slots=True)
class ObserverGains:
    """Observer gain K = diag(k_u, k_v, k_r) [1/s]; time constants T_i = 1/k_i [s].

    Parameters
    ----------
    k : tuple of 3 floats
        Gains for surge, sway and yaw [1/s], > 0 (checked against the step in
        :class:`DisturbanceObserver`).
    """

    k: tuple[float, float, float]

    def __post_init__(self) -> None:
        if len(self.k) != 3:
            raise ParameterError(f"observer gains k must have 3 entries (surge, sway, yaw),"
                                 f" actually: {len(self.k)}")
        object.__setattr__(self, "k", tuple(float(v) for v in self.k))
        for i, v in enumerate(self.k):
            if not (math.isfinite(v) and v > 0.0):
                raise ParameterError(f"observer gain k[{i}] ({_DOF[i]}) must be finite and "
                                     f"> 0 [1/s], actually: {v}")

    @property
    def time_constant_s(self) -> tuple[float, float, float]:
        """T_i = 1/k_i [s]: the error of a constant τ_d falls by e in T_i."""
        return tuple(1.0 / v for v in self.k)  # type: ignore[return-value]

    @property
    def convergence_90_s(self) -> tuple[float, float, float]:
        """Time for 90 % convergence to a step in τ_d: ln(10)·T_i [s]."""
        return tuple(math.log(10.0) / v for v in self.k)  # type: ignore[return-value]

    @classmethod
    def from_time_constants(cls, T_s: Sequence[float]) -> ObserverGains:
        """Gains from time constants T_i [s] (> 0)."""
        T = tuple(float(t) for t in T_s)
        for i, t in enumerate(T):
            if not (math.isfinite(t) and t > 0.0):
                raise ParameterError(f"observer time constant T[{i}] ({_DOF[i]}) must be "
                                     f"finite and > 0 [s], actually: {t}")
        return cls(tuple(1.0 / t for t in T))  # type: ignore[arg-type]


def default_gains(params: VesselParams) -> ObserverGains:
    """Default gains: the predecessor's model-scale Γ = diag(0.1, 0.1, 0.08) 1/s,
    Froude-scaled to the vessel's length (k ∝ 1/√L).

    Why: T = 10 s (12.5 s in yaw) at model scale is ≈ 28 √(L/g), slower than the
    vessel's own surge/sway time constants M/D (≈ 20-40 s at model scale is the slowest
    one, but the momentum is measured, so speed is not limited by them) and fast enough
    to follow the environment (current and wave-drift variations of 70-600 s at model
    scale after Froude scaling of minutes to an hour at full scale). The measurement
    noise reaches d̂ with gain ≈ k M (white ν noise σ gives std(d̂) ≈ k M σ): these gains
    keep it at about 1 % of full thrust for the sensor noise of :mod:`.report` (see
    docs/observer.md). Full scale (×70) gives T ≈ 84 s (105 s in yaw).
    """
    s = math.sqrt(cybership2().length / params.length)
    return ObserverGains(tuple(k * s for k in _MODEL_SCALE_GAINS))  # type: ignore[arg-type]


@njit(cache=True)
def ndo_step(d_hat, nu_prev, anchored, stale, nu, tau, P, M, alpha, dt):  # pragma: no cover
    """One observer update for n vessels, in place.

    d̂_{k+1} = α d̂_k + (1−α)[M(ν_{k+1} − ν_k)/h + ½(n(ν_k) + n(ν_{k+1})) − τ_k]
    (the exact-hold discretisation of ż = −Kz − K(p(ν) + τ − n(ν)), d̂ = z + K_d M ν).
    A vessel with a non-finite ν or τ keeps d̂, counts a stale step and loses its anchor;
    an unanchored vessel only anchors. Returns the number of vessels held this step.
    """
    n = d_hat.shape[0]
    shared = P.shape[0] == 1
    held = 0
    for i in range(n):
        ok = True
        for j in range(3):
            if not (math.isfinite(nu[i, j]) and math.isfinite(tau[i, j])):
                ok = False
        if not ok:
            anchored[i] = False
            stale[i] += 1
            held += 1
            continue
        if anchored[i]:
            p = P[0] if shared else P[i]
            Mi = M[0] if shared else M[i]
            a0, a1, a2 = _n_nu(nu_prev[i, 0], nu_prev[i, 1], nu_prev[i, 2], p)
            b0, b1, b2 = _n_nu(nu[i, 0], nu[i, 1], nu[i, 2], p)
            dn0 = (nu[i, 0] - nu_prev[i, 0]) / dt
            dn1 = (nu[i, 1] - nu_prev[i, 1]) / dt
            dn2 = (nu[i, 2] - nu_prev[i, 2]) / dt
            # momentum rate M Δν/h + trapezoidal n̄ − τ: the instantaneous τ_d
            y0 = Mi[0, 0] * dn0 + Mi[0, 1] * dn1 + Mi[0, 2] * dn2 + 0.5 * (a0 + b0) - tau[i, 0]
            y1 = Mi[1, 0] * dn0 + Mi[1, 1] * dn1 + Mi[1, 2] * dn2 + 0.5 * (a1 + b1) - tau[i, 1]
            y2 = Mi[2, 0] * dn0 + Mi[2, 1] * dn1 + Mi[2, 2] * dn2 + 0.5 * (a2 + b2) - tau[i, 2]
            d_hat[i, 0] = alpha[0] * d_hat[i, 0] + (1.0 - alpha[0]) * y0
            d_hat[i, 1] = alpha[1] * d_hat[i, 1] + (1.0 - alpha[1]) * y1
            d_hat[i, 2] = alpha[2] * d_hat[i, 2] + (1.0 - alpha[2]) * y2
            stale[i] = 0
        else:
            anchored[i] = True
        for j in range(3):
            nu_prev[i, j] = nu[i, j]
    return held


class DisturbanceObserver:
    """Batched nonlinear disturbance observer: d̂ of τ_d for n vessels.

    Parameters
    ----------
    params : VesselParams or sequence of VesselParams
        One parameter set shared by all vessels, or one per vessel.
    n_vessels : int
        Number of vessels n.
    dt_s : float
        Sampling step h [s] of the measurements, > 0.
    gains : ObserverGains or sequence of 3 floats, optional
        K = diag(k_u, k_v, k_r) [1/s], each in :func:`gain_range` (``dt_s``);
        :func:`default_gains` of the (first) parameter set by default.
    d0 : array_like, (n, 3) or (3,), optional
        Initial estimate [N, N, Nm]; zero by default.

    Notes
    -----
    Feed it every step with :meth:`update` (measured ν after the step, thrust τ applied
    over the step). The first good sample only anchors ν (``valid`` is False until the
    first real update).

    Examples
    --------
    >>> import numpy as np
    >>> from asvtwin.vessel import cybership2
    >>> obs = DisturbanceObserver(cybership2(), 2, dt_s=0.1)
    >>> obs.update(np.zeros((2, 3)), np.zeros((2, 3))).shape
    (2, 3)
    """

    def __init__(self, params: VesselParams | Sequence[VesselParams], n_vessels: int = 1,
                 *, dt_s: float, gains: ObserverGains | Sequence[float] | None = None,
                 d0: ArrayLike | None = None) -> None:
        if not (math.isfinite(dt_s) and dt_s > 0):
            raise ParameterError(f"observer dt_s must be finite and > 0 [s], "
                                 f"actually: {dt_s}")
        n = int(n_vessels)
        if n < 1:
            raise ParameterError(f"observer n_vessels must be >= 1, actually: {n_vessels}")
        plist = (params,) if isinstance(params, VesselParams) else tuple(params)
        if len(plist) not in (1, n):
            raise ParameterError(f"observer needs 1 or {n} parameter sets, "
                                 f"actually: {len(plist)}")
        if gains is None:
            gains = default_gains(plist[0])
        elif not isinstance(gains, ObserverGains):
            gains = ObserverGains(tuple(gains))  # type: ignore[arg-type]
        lo, hi = gain_range(dt_s)
        for i, k in enumerate(gains.k):
            if not lo <= k <= hi:
                raise ParameterError(
                    f"observer gain k[{i}] ({_DOF[i]}) must be in [{lo:g}, {hi:g}] 1/s "
                    f"(time constant between dt_s={dt_s:g} s and {1 / lo / 3600:.0f} h), "
                    f"actually: {k:g}")
        self.params = plist
        self.gains = gains
        self.dt_s = float(dt_s)
        self.n = n
        self._P = np.ascontiguousarray(np.stack([p.packed() for p in plist]))
        self._M = np.ascontiguousarray(np.stack([p.M for p in plist]))
        self._alpha = np.exp(-np.asarray(gains.k) * dt_s)
        self._d = np.zeros((n, 3))
        self._nu_prev = np.zeros((n, 3))
        self._anchored = np.zeros(n, dtype=np.bool_)
        self._stale = np.zeros(n, dtype=np.int64)
        self.dropouts = 0
        self._logged = False
        self.reset(d0)

    # ---------------------------------------------------------------- state, plain values
    @property
    def estimate(self) -> NDArray[np.float64]:
        """d̂ (n, 3) [N, N, Nm], body frame (a copy)."""
        return self._d.copy()

    @property
    def valid(self) -> NDArray[np.bool_]:
        """(n,) True where the last update used a good measurement and a prior one."""
        return self._anchored & (self._stale == 0) & self._updated

    @property
    def stale_steps(self) -> NDArray[np.int64]:
        """(n,) consecutive steps each vessel's estimate has been held (dropouts)."""
        return self._stale.copy()

    def reset(self, d0: ArrayLike | None = None) -> None:
        """Forget the measurement history; set d̂ to ``d0`` (zero by default)."""
        if d0 is None:
            self._d[:] = 0.0
        else:
            arr = np.asarray(d0, dtype=float)
            if arr.shape not in ((3,), (self.n, 3)) or not np.all(np.isfinite(arr)):
                raise StateError(f"observer d0 must be finite with shape (3,) or "
                                 f"({self.n}, 3), actually: shape {arr.shape}")
            self._d[:] = arr
        self._anchored[:] = False
        self._stale[:] = 0
        self._updated = np.zeros(self.n, dtype=np.bool_)

    def update(self, nu_meas: ArrayLike, tau: ArrayLike) -> NDArray[np.float64]:
        """Take one sample; return d̂ (n, 3) [N, N, Nm] (a copy).

        Parameters
        ----------
        nu_meas : array_like, (n, 3) or (3,)
            Measured body velocities [u, v, r] [m/s, m/s, rad/s] at the end of the step;
            NaN (or inf) marks a dropout of that vessel.
        tau : array_like, (n, 3) or (3,)
            Thrust [N, N, Nm] applied over the step (commanded, or the actuators'
            actual thrust when known); NaN marks it missing.
        """
        nu = self._rows(nu_meas, "nu_meas")
        tq = self._rows(tau, "tau")
        was = self._anchored.copy()
        held = ndo_step(self._d, self._nu_prev, self._anchored, self._stale, nu, tq,
                        self._P, self._M, self._alpha, self.dt_s)
        self._updated = was & self._anchored
        if held:
            self.dropouts += int(held)
            if not self._logged:
                bad = int(np.flatnonzero(self._stale > 0)[0])
                _log.warning("observer: missing/NaN measurement of vessel %d; holding its "
                             "estimate (further dropouts are counted, not logged)", bad)
                self._logged = True
        return self._d.copy()

    def _rows(self, a: ArrayLike, what: str) -> NDArray[np.float64]:
        arr = np.asarray(a, dtype=np.float64)
        if arr.shape == (3,):
            arr = np.broadcast_to(arr, (self.n, 3))
        if arr.shape != (self.n, 3):
            raise StateError(f"observer {what} must have shape (3,) or ({self.n}, 3), "
                             f"actually: {arr.shape}")
        return np.ascontiguousarray(arr)
