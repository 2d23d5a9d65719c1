"""Actuator fault diagnosis from motion residuals: loss of thrust, stuck actuator, bias.

Residual generator
    Per DOF i, the momentum p_i = (M ν)_i obeys exactly (paper, eq. (dynamics))

    .. math:: \\dot p_i = \\tau_i + \\tau_{d,i} + f_i - n_i(\\nu), \\qquad
              n(\\nu) = C(\\nu)\\nu + D(\\nu)\\nu,

    with f_i the force an actuator fault adds (thrust reaching the hull = g·τ + b, so
    f = (g − 1)τ + b). A steady-state Kalman filter on s = [p_i, τ_d,i] (τ_d a random
    walk with intensity q_d, p with process noise q_p for unmodelled fast forces), fed
    the measured momentum M ν̃ (noise variance R_i = (M Σ_ν Mᵀ)_ii) and the healthy
    actuators' thrust τ, gives innovations γ that are white N(0, S_i) while no fault acts.

Detector
    An abrupt fault force f from sample θ on adds a known signature ρ_{k−θ}·f to the
    innovations (ρ from the filter's error dynamics). The generalised likelihood ratio
    over a sliding window of W candidate onsets (Willsky & Jones 1976)

    .. math:: \\ell_k = \\max_{k-W < \\theta \\le k}
              \\frac{\\big(\\sum_{j=\\theta}^{k} \\rho_{j-\\theta}\\gamma_j/S\\big)^2}
                    {\\kappa\\sum_{j=\\theta}^{k} \\rho_{j-\\theta}^2/S}

    is χ²(1) for each θ under no fault. The threshold is DERIVED from a target false-alarm
    rate λ [1/h] by a Bonferroni bound over the W onsets and the monitored DOFs per
    sample of length h: P(ℓ_k > γ_th) ≤ λ·h/3600, i.e. γ_th = χ²₁⁻¹(1 − λh/(3600·W·m)).
    κ ≥ 1 is the variance inflation of the windowed matched filter measured on
    fault-free calibration data (it absorbs the colour of real disturbances); q_p and q_d
    are fitted there by maximum likelihood
    (:func:`asvtwin.observer.calibration.fit_residual_model`). Nothing is tuned
    to a test: the calibration runs use their own seeds.

Isolation and kind
    The DOF whose statistic crosses is the faulty actuator. At the alarm, three one-
    parameter fault models are fitted to that DOF's innovations since the onset θ̂:
    bias f = b, loss of thrust f = −c τ (0 < c ≤ 1), stuck f = s − τ (s within the
    actuator's range); the kind is the best fit and the confidence its Akaike weight
    exp(−½RSS)/Σ. With constant thrust the three are indistinguishable and the confidence
    says so (≈ 1/3 each); thrust variation after the fault separates them.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import solve_discrete_are
from scipy.stats import chi2

from asvtwin.errors import ParameterError, StateError
from asvtwin.vessel.kernels import hydrodynamic_force as _n_nu
from asvtwin.vessel.params import VesselParams

__all__ = [
    "DetectorConfig",
    "FaultDetector",
    "FaultEvent",
    "FaultKind",
    "ResidualModel",
    "default_window_s",
    "steady_state_filter",
]

FaultKind = Literal["loss_of_thrust", "stuck", "bias"]
_KINDS: tuple[FaultKind, ...] = ("bias", "loss_of_thrust", "stuck")
_DOF = ("surge", "sway", "yaw")


@dataclass(frozen=True, slots=True)
class FaultEvent:
    """A detected actuator fault (frozen).

    t_s : detection time [s]; onset_t_s : estimated onset [s]; vessel, dof : index
    (0 surge, 1 sway, 2 yaw); kind : ``"loss_of_thrust"``, ``"stuck"`` or ``"bias"``;
    confidence : Akaike weight of that kind in [0, 1]; force : estimated fault force at
    detection [N or Nm]; parameter : the kind's fitted parameter (c = fraction of thrust
    lost, s = stuck thrust, b = bias); statistic : the GLR value at detection.
    """

    t_s: float
    onset_t_s: float
    vessel: int
    dof: int
    kind: FaultKind
    confidence: float
    force: float
    parameter: float
    statistic: float

    @property
    def dof_name(self) -> str:
        return _DOF[self.dof]


@dataclass(frozen=True, slots=True)
class ResidualModel:
    """Noise model of the residual generator, per DOF (surge, sway, yaw).

    R : measurement variance of the momentum (M ν̃)_i [(N s)²]; q_p, q_d : process noise
    variances per step of the momentum [(N s)²] and of the disturbance random walk [N²];
    kappa : variance inflation of the matched filter (≥ 1) from calibration.
    """

    dt_s: float
    R: tuple[float, float, float]
    q_p: tuple[float, float, float]
    q_d: tuple[float, float, float]
    kappa: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.dt_s) and self.dt_s > 0):
            raise ParameterError(f"residual model dt_s must be > 0 [s], actually: {self.dt_s}")
        for name in ("R", "q_p", "q_d", "kappa"):
            vals = tuple(float(v) for v in getattr(self, name))
            object.__setattr__(self, name, vals)
            for i, v in enumerate(vals):
                lo = 1.0 if name == "kappa" else 0.0
                if not (math.isfinite(v) and (v > lo if name == "R" else v >= lo)):
                    raise ParameterError(f"residual model {name}[{i}] ({_DOF[i]}) must be "
                                         f"finite and {'>' if name == 'R' else '>='} {lo}, "
                                         f"actually: {v}")

    @classmethod
    def from_sensor_noise(cls, params: VesselParams, sigma_nu: ArrayLike, dt_s: float, *,
                          q_p: ArrayLike = (0.0, 0.0, 0.0), q_d: ArrayLike | None = None
                          ) -> ResidualModel:
        """R from white ν noise of std ``sigma_nu`` [m/s, m/s, rad/s]: diag(M Σ Mᵀ)."""
        s = np.asarray(sigma_nu, dtype=float)
        if s.shape != (3,) or np.any(~np.isfinite(s)) or np.any(s <= 0):
            raise ParameterError(f"sigma_nu must be 3 finite values > 0, actually: {s}")
        M = params.M
        R = np.diag(M @ np.diag(s**2) @ M.T)
        if q_d is None:
            q_d = 1e-6 * R / dt_s**2
        return cls(dt_s, tuple(R), tuple(np.asarray(q_p, float)), tuple(np.asarray(q_d, float)))


def steady_state_filter(dt_s: float, R: float, q_p: float, q_d: float
                        ) -> tuple[NDArray[np.float64], float, NDArray[np.float64]]:
    """Steady-state gain K (2,), innovation variance S and Φ = F(I − K H) (2, 2).

    Model s = [p, d]: s_{k+1} = F s_k + [h u_k, 0], F = [[1, h], [0, 1]], y = p + e.
    """
    F = np.array([[1.0, dt_s], [0.0, 1.0]])
    H = np.array([[1.0, 0.0]])
    Q = np.diag([max(q_p, 1e-12 * R), max(q_d, 1e-12 * R / dt_s**2)])
    P = solve_discrete_are(F.T, H.T, Q, np.array([[R]]))
    S = float(P[0, 0] + R)
    K = P[:, 0] / S
    Phi = F @ (np.eye(2) - np.outer(K, H[0]))
    return K, S, Phi


def default_window_s(params: VesselParams, window_s: float | None = None) -> float:
    """The GLR window [s]: ``window_s``, or 60 s · √(L / 87.85 m) (Froude-scaled)."""
    return float(window_s) if window_s is not None else 60.0 * math.sqrt(params.length / 87.85)


def settle_steps(Phi: NDArray[np.float64]) -> int:
    """Steps for the slowest filter error mode (spectral radius of Φ) to decay to 1 %."""
    rad = max(float(np.max(np.abs(np.linalg.eigvals(P)))) for P in np.reshape(Phi, (-1, 2, 2)))
    rad = min(max(rad, 1e-9), 1.0 - 1e-9)
    return math.ceil(math.log(0.01) / math.log(rad))


def _innovation_response(Phi: NDArray[np.float64], dt_s: float, force: NDArray[np.float64]
                         ) -> NDArray[np.float64]:
    """Innovations caused by a force sequence f_j acting over the steps ending at each
    sample j = 0..m−1 (linear error dynamics e⁻_{j+1} = Φ e⁻_j + [h f_{j+1}, 0])."""
    out = np.empty(force.shape[0])
    e = np.zeros(2)
    for j in range(force.shape[0]):
        e = Phi @ e if j else e
        e[0] += dt_s * force[j]
        out[j] = e[0]
    return out


@dataclass(frozen=True, slots=True)
class DetectorConfig:
    """Design of the detector.

    false_alarms_per_hour : target λ [1/h] the threshold is derived from (> 0).
    window_s : length of the onset search window [s] (> 0); None: 60 s for an 88 m
    ship, Froude-scaled (60 s · √(L / 87.85 m), 7.2 s for CyberShip II).
    dofs : monitored DOFs; None means the actuated ones (tau_max > tau_min).
    """

    false_alarms_per_hour: float = 0.1
    window_s: float | None = None
    dofs: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.false_alarms_per_hour) and
                0 < self.false_alarms_per_hour <= 3600):
            raise ParameterError(f"false_alarms_per_hour must be in (0, 3600], actually: "
                                 f"{self.false_alarms_per_hour}")
        if self.window_s is not None and not (math.isfinite(self.window_s)
                                              and self.window_s > 0):
            raise ParameterError(f"window_s must be > 0 [s], actually: {self.window_s}")


@njit(cache=True)
def _detector_step(s, nu_meas, tau, P, Minv, M, K, h, A, Bc, rho, count, ring_g,
                   ring_t, head, mon, latched, stat, arg, S, arm):  # pragma: no cover
    """Kalman predict/update per vessel and DOF, then the GLR update; in place.

    s (n,3,2) filter states [p̂, d̂]; K (g,3,2); S (g,3); rho, Bc (g,3,W); A (n,3,W)
    matched-filter sums; ring_* (n,3,W) last W innovations and thrusts.
    """
    n = s.shape[0]
    W = A.shape[2]
    sg = K.shape[0] == 1
    for i in range(n):
        ok = True
        for j in range(3):
            if not (math.isfinite(nu_meas[i, j]) and math.isfinite(tau[i, j])):
                ok = False
        g = 0 if sg else i
        # filtered velocity ν̂ = M⁻¹ p̂ and its midpoint prediction for n(ν)
        p0, p1, p2 = s[i, 0, 0], s[i, 1, 0], s[i, 2, 0]
        u = Minv[0, 0] * p0 + Minv[0, 1] * p1 + Minv[0, 2] * p2
        v = Minv[1, 0] * p0 + Minv[1, 1] * p1 + Minv[1, 2] * p2
        r = Minv[2, 0] * p0 + Minv[2, 1] * p1 + Minv[2, 2] * p2
        n0, n1, n2 = _n_nu(u, v, r, P)
        t0 = tau[i, 0] if math.isfinite(tau[i, 0]) else 0.0
        t1 = tau[i, 1] if math.isfinite(tau[i, 1]) else 0.0
        t2 = tau[i, 2] if math.isfinite(tau[i, 2]) else 0.0
        tq = (t0, t1, t2)
        f0 = t0 + s[i, 0, 1] - n0
        f1 = t1 + s[i, 1, 1] - n1
        f2 = t2 + s[i, 2, 1] - n2
        hh = 0.5 * h
        um = u + hh * (Minv[0, 0] * f0 + Minv[0, 1] * f1 + Minv[0, 2] * f2)
        vm = v + hh * (Minv[1, 0] * f0 + Minv[1, 1] * f1 + Minv[1, 2] * f2)
        rm = r + hh * (Minv[2, 0] * f0 + Minv[2, 1] * f1 + Minv[2, 2] * f2)
        m0, m1, m2 = _n_nu(um, vm, rm, P)
        nm = (m0, m1, m2)
        for j in range(3):
            # predict: p⁻ = p̂ + h(τ + d̂ − n(ν̂_mid)), d⁻ = d̂
            s[i, j, 0] = s[i, j, 0] + h * (tq[j] + s[i, j, 1] - nm[j])
        if not ok:
            for j in range(3):
                for m in range(W):
                    A[i, j, m] = 0.0
                count[i] = 0
                stat[i, j] = 0.0
            continue
        if count[i] < 0:  # first sample: initialise p̂ at the measurement
            for j in range(3):
                s[i, j, 0] = M[j, 0] * nu_meas[i, 0] + M[j, 1] * nu_meas[i, 1] \
                    + M[j, 2] * nu_meas[i, 2]
            count[i] = 0
            continue
        for j in range(3):
            y = M[j, 0] * nu_meas[i, 0] + M[j, 1] * nu_meas[i, 1] + M[j, 2] * nu_meas[i, 2]
            gam = y - s[i, j, 0]
            # update: s⁺ = s⁻ + K γ
            s[i, j, 0] += K[g, j, 0] * gam
            s[i, j, 1] += K[g, j, 1] * gam
            ring_g[i, j, head] = gam
            ring_t[i, j, head] = tq[j]
            if not mon[j] or latched[i, j]:
                stat[i, j] = 0.0
                continue
            # matched filter sums A_m = Σ ρ_{j−θ} γ_j / S for onsets m samples back
            w = gam / S[g, j]
            for m in range(W - 1, 0, -1):
                A[i, j, m] = A[i, j, m - 1] + rho[g, j, m] * w
            A[i, j, 0] = rho[g, j, 0] * w
            best = 0.0
            bm = 0
            if count[i] < arm:  # filter still settling from its initial state
                stat[i, j] = 0.0
                continue
            top = min(count[i] - arm + 1, W)
            for m in range(top):
                val = A[i, j, m] * A[i, j, m] / Bc[g, j, m]
                if val > best:
                    best = val
                    bm = m
            stat[i, j] = best
            arg[i, j] = bm
        count[i] += 1
    return 0


class FaultDetector:
    """Residual-based actuator fault detection, isolation and classification, batched.

    Parameters
    ----------
    params : VesselParams
        The (healthy) vessel model, shared by the n vessels.
    n_vessels : int
    model : ResidualModel
        Noise model (``model.dt_s`` is the sampling step h).
    config : DetectorConfig, optional

    Notes
    -----
    Call :meth:`update` every step with the time after the step, the measured ν and the
    thrust the healthy actuators deliver (the simulator's ``thrust``, or the command
    passed through the actuator model). Each fault is reported once (the DOF latches
    until :meth:`clear`).
    """

    def __init__(self, params: VesselParams, n_vessels: int, model: ResidualModel,
                 config: DetectorConfig | None = None) -> None:
        self.params = params
        self.model = model
        self.config = config or DetectorConfig()
        n = int(n_vessels)
        if n < 1:
            raise ParameterError(f"detector n_vessels must be >= 1, actually: {n_vessels}")
        self.n = n
        h = model.dt_s
        self.W = W = max(2, round(default_window_s(params, self.config.window_s) / h))
        act = params.actuators
        dofs = self.config.dofs
        if dofs is None:
            dofs = tuple(j for j in range(3) if act.tau_max[j] > act.tau_min[j])
        for j in dofs:
            if j not in (0, 1, 2):
                raise ParameterError(f"detector dofs must be in (0, 1, 2), actually: {dofs}")
        self.dofs = tuple(dofs)
        self._mon = np.array([j in self.dofs for j in range(3)])
        self._K = np.zeros((1, 3, 2))
        self._S = np.zeros((1, 3))
        self._rho = np.zeros((1, 3, W))
        self._Phi = np.zeros((3, 2, 2))
        for j in range(3):
            K, S, Phi = steady_state_filter(h, model.R[j], model.q_p[j], model.q_d[j])
            self._K[0, j], self._S[0, j], self._Phi[j] = K, S, Phi
            self._rho[0, j] = _innovation_response(Phi, h, np.ones(W))
        #: Samples after start (or a dropout) before the GLR is armed: the filter's
        #: settling time, when its initial error has decayed to 1 %.
        self.arm_steps = settle_steps(self._Phi)
        self._Bc = np.cumsum(self._rho**2 / self._S[:, :, None], axis=2) \
            * np.asarray(model.kappa)[None, :, None]
        m = max(1, len(self.dofs))
        p_step = self.config.false_alarms_per_hour * h / 3600.0
        #: GLR threshold derived from the false-alarm target (Bonferroni, see module doc).
        self.threshold = float(chi2.isf(p_step / (W * m), 1))
        self._P = params.packed()
        self._M = np.ascontiguousarray(params.M)
        self._Minv = np.ascontiguousarray(np.linalg.inv(params.M))
        self.reset()

    def reset(self) -> None:
        """Forget all history and latched faults."""
        n, W = self.n, self.W
        self._s = np.zeros((n, 3, 2))
        self._A = np.zeros((n, 3, W))
        self._ring_g = np.zeros((n, 3, W))
        self._ring_t = np.zeros((n, 3, W))
        self._count = np.full(n, -1, dtype=np.int64)
        self._latched = np.zeros((n, 3), dtype=np.bool_)
        self._stat = np.zeros((n, 3))
        self._arg = np.zeros((n, 3), dtype=np.int64)
        self._head = 0
        self._k = 0
        self._onsets: dict[tuple[int, int], tuple[int, float]] = {}

    @property
    def statistic(self) -> NDArray[np.float64]:
        """(n, 3) current GLR statistic ℓ_k per vessel and DOF."""
        return self._stat.copy()

    @property
    def latched(self) -> NDArray[np.bool_]:
        """(n, 3) True where a fault has been reported and not cleared."""
        return self._latched.copy()

    @property
    def disturbance_estimate(self) -> NDArray[np.float64]:
        """(n, 3) the filter's own τ_d estimate [N, N, Nm] (includes fault forces)."""
        return self._s[:, :, 1].copy()

    def clear(self, vessel: int, dof: int) -> None:
        """Re-arm a latched DOF (after repair)."""
        self._latched[vessel, dof] = False
        self._A[vessel, dof] = 0.0
        self._onsets.pop((int(vessel), int(dof)), None)

    def update(self, t_s: float, nu_meas: ArrayLike, tau: ArrayLike
               ) -> tuple[FaultEvent, ...]:
        """Take one sample; return the faults newly detected at ``t_s`` (often none).

        Parameters
        ----------
        t_s : float
            Time of the measurement [s].
        nu_meas : array_like, (n, 3)
            Measured ν [m/s, m/s, rad/s]; NaN marks a dropout (that vessel's windows
            restart).
        tau : array_like, (n, 3)
            Healthy-actuator thrust applied over the last step [N, N, Nm].
        """
        nu = self._rows(nu_meas, "nu_meas")
        tq = self._rows(tau, "tau")
        self._head = (self._head + 1) % self.W
        self._k += 1
        _detector_step(self._s, nu, tq, self._P, self._Minv, self._M, self._K,
                       self.model.dt_s, self._A, self._Bc, self._rho,
                       self._count, self._ring_g, self._ring_t, self._head, self._mon,
                       self._latched, self._stat, self._arg, self._S, self.arm_steps)
        hits = np.argwhere(self._stat > self.threshold)
        if hits.size == 0:
            return ()
        events = []
        for i, j in hits:
            m = int(self._arg[i, j])
            self._onsets[(int(i), int(j))] = (self._k - m, float(t_s) - m * self.model.dt_s)
            events.append(self._classify(float(t_s), int(i), int(j), m,
                                         float(self._stat[i, j])))
            self._latched[i, j] = True
            self._A[i, j] = 0.0
            self._stat[i, j] = 0.0
        return tuple(events)

    def diagnose(self, t_s: float, vessel: int, dof: int) -> FaultEvent:
        """Classify a latched fault again with every sample since its onset that the
        window still holds (thrust that varied after the alarm separates the kinds; at
        most the last W samples are used, the onset reported is the alarm's).

        Parameters
        ----------
        t_s : float
            Time of the latest update [s].
        """
        key = (int(vessel), int(dof))
        if key not in self._onsets:
            raise StateError(f"no fault latched on vessel {vessel}, dof {dof}")
        k0, onset_t = self._onsets[key]
        m = min(self._k - k0, self.W - 1)
        ev = self._classify(float(t_s), key[0], key[1], m, float("nan"))
        return dataclasses.replace(ev, onset_t_s=onset_t)

    def _classify(self, t_s: float, i: int, j: int, m: int, stat: float) -> FaultEvent:
        L = m + 1
        idx = (self._head - np.arange(m, -1, -1)) % self.W
        g = self._ring_g[i, j, idx] / math.sqrt(self._S[0, j])
        tq = self._ring_t[i, j, idx]
        h, Phi = self.model.dt_s, self._Phi[j]
        sq = math.sqrt(self._S[0, j])
        r1 = _innovation_response(Phi, h, np.ones(L)) / sq
        rt = _innovation_response(Phi, h, -tq) / sq
        lo, hi = self.params.actuators.tau_min[j], self.params.actuators.tau_max[j]
        fits: dict[FaultKind, tuple[float, float]] = {}

        def ls(x: NDArray[np.float64], y: NDArray[np.float64]) -> float:
            den = float(x @ x)
            return float(x @ y) / den if den > 0 else 0.0

        b = ls(r1, g)
        fits["bias"] = (float(np.sum((g - b * r1) ** 2)), b)
        c = min(max(ls(rt, g), 0.0), 1.0)
        fits["loss_of_thrust"] = (float(np.sum((g - c * rt) ** 2)), c)
        s_ = min(max(ls(r1, g - rt), lo), hi)
        fits["stuck"] = (float(np.sum((g - s_ * r1 - rt) ** 2)), s_)
        rss = np.array([fits[k][0] for k in _KINDS])
        w = np.exp(-0.5 * (rss - rss.min()))
        w /= w.sum()
        best = int(np.argmax(w))
        kind = _KINDS[best]
        force = b if kind == "bias" else (-c * float(tq[-1]) if kind == "loss_of_thrust"
                                          else s_ - float(tq[-1]))
        return FaultEvent(t_s=t_s, onset_t_s=t_s - m * h, vessel=i, dof=j, kind=kind,
                          confidence=float(w[best]), force=float(force),
                          parameter=float(fits[kind][1]), statistic=stat)

    def _rows(self, a: ArrayLike, what: str) -> NDArray[np.float64]:
        arr = np.asarray(a, dtype=np.float64)
        if arr.shape == (3,) and self.n == 1:
            arr = arr[None, :]
        if arr.shape != (self.n, 3):
            raise StateError(f"detector {what} must have shape ({self.n}, 3), "
                             f"actually: {arr.shape}")
        return np.ascontiguousarray(arr)
