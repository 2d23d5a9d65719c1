"""One heading/speed autopilot for every vessel of the project, batched.

Heading: a cascade of a heading loop that asks for a yaw rate and a yaw-rate loop that
produces the yaw moment, with optional integral action on the heading error and a
feed-forward of the linear yaw damping at the requested rate (Fossen 2011, ch. 12-13,
PID heading autopilot with reference feed-forward):

.. math::

    \\tilde\\psi = \\operatorname{wrap}(\\psi_d - \\psi), \\qquad
    r_d = \\operatorname{sat}_{r_{max}}(k_\\psi \\tilde\\psi), \\qquad
    \\tau_r = k_r (r_d - r) + k_i \\int \\tilde\\psi \\, dt - f_r N_r r_d

Speed: feed-forward of the surge damping at the requested speed plus PI feedback,

.. math::

    \\tau_u = f_u\\, d(u_d) + k_u (u_d - u) + k_{iu} \\int (u_d - u)\\, dt, \\qquad
    d(u) = -(X_u u + X_{|u|u} |u| u + X_{uuu} u^3)

The output is saturated to the vessel's actuator limits; the integrators are frozen while
their channel saturates (conditional integration, the anti-windup of the observer study).
A course reference (from :class:`~asvtwin.guidance.LosGuidance`) becomes a heading
reference by removing the measured crab angle :math:`\\beta = \\operatorname{atan2}(v, u)`:
:math:`\\psi_d = \\chi_d - \\beta` (``crab_compensation``), so a ship set sideways by a
current still makes good its course.

With :math:`k_\\psi = \\omega/2`, :math:`k_r = 2\\omega m_r` (:math:`m_r = I_z - N_{\\dot r}`)
and no limit, the heading loop is the critically damped PD
:math:`\\tau_r = m_r(\\omega^2 \\tilde\\psi - 2\\omega r)`:
:meth:`AutopilotGains.critically_damped` builds it (plus optional integral action);
:meth:`AutopilotGains.rate_limited` builds the stiff inner loop with a turn-rate limit that
the synthetic traffic uses. :meth:`AutopilotGains.for_vessel` is the twin's own ship's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from asvtwin.checks import F8 as _F8
from asvtwin.errors import ParameterError, StateError
from asvtwin.guidance.kernels import autopilot_kernel
from asvtwin.vessel.params import VesselParams

__all__ = ["AutopilotGains", "HeadingSpeedAutopilot"]

_L_MODEL_M = 1.255


def _froude(params: VesselParams) -> float:
    """√λ with λ = L / 1.255 m: CyberShip II's Froude time ratio."""
    return math.sqrt(params.length / _L_MODEL_M)


@dataclass(frozen=True)
class AutopilotGains:
    """Gains of :class:`HeadingSpeedAutopilot` (scalars for one vessel, or arrays (n,)).

    Attributes
    ----------
    k_psi : heading error to yaw-rate reference [1/s].
    r_max_rad_s : limit of the yaw-rate reference [rad/s] (``inf``: none).
    k_r : yaw-rate error to yaw moment [N m s].
    k_i_psi : integral of the heading error to yaw moment [N m / s] (0: no integral).
    yaw_feedforward : factor f_r of the damping feed-forward ``-N_r r_d`` (0 or 1).
    k_u : surge speed error to surge force [N s / m].
    k_i_u : integral of the speed error to surge force [N / m] (0: no integral).
    speed_feedforward : factor f_u of the damping feed-forward d(u_d) (0 or 1).
    crab_compensation : steer ψ_d = χ_d − β with the measured crab angle β (True) or
        ψ_d = χ_d (False).
    """

    k_psi: float | _F8
    r_max_rad_s: float | _F8
    k_r: float | _F8
    k_i_psi: float | _F8 = 0.0
    yaw_feedforward: float | _F8 = 1.0
    k_u: float | _F8 = 0.0
    k_i_u: float | _F8 = 0.0
    speed_feedforward: float | _F8 = 1.0
    crab_compensation: bool = True

    def __post_init__(self) -> None:
        for name in ("k_psi", "r_max_rad_s", "k_r", "k_i_psi", "yaw_feedforward", "k_u",
                     "k_i_u", "speed_feedforward"):
            v = np.asarray(getattr(self, name), dtype=np.float64)
            if np.isnan(v).any() or (v < 0).any() or (name != "r_max_rad_s"
                                                       and not np.isfinite(v).all()):
                raise ParameterError(f"AutopilotGains.{name} must be finite and >= 0 "
                                     f"(r_max_rad_s may be inf), actually: {v}")
        if (np.asarray(self.r_max_rad_s) <= 0).any():
            raise ParameterError(f"AutopilotGains.r_max_rad_s must be > 0, actually: "
                                 f"{self.r_max_rad_s}")

    @classmethod
    def critically_damped(cls, params: VesselParams, omega_rad_s: float, *,
                          integral: bool = False, speed_time_constant_s: float | None = None,
                          crab_compensation: bool = False) -> AutopilotGains:
        """Heading PD τ_r = m_r(ω²ψ̃ − 2ωr) (+ m_r ω³/10 ∫ψ̃ with ``integral``).

        Speed: feed-forward and, with ``speed_time_constant_s`` = T_u, PI feedback
        k_u = m_u/T_u, k_iu = m_u/(4 T_u²) (m_u = m − X_u̇); without it, feed-forward only.
        """
        if not (math.isfinite(omega_rad_s) and omega_rad_s > 0):
            raise ParameterError(f"omega_rad_s must be finite and > 0, actually: {omega_rad_s}")
        M = params.M
        m_r = float(M[2, 2])
        k_u = k_iu = 0.0
        if speed_time_constant_s is not None:
            Tu = float(speed_time_constant_s)
            if not (math.isfinite(Tu) and Tu > 0):
                raise ParameterError(f"speed_time_constant_s must be > 0 [s], actually: {Tu}")
            k_u, k_iu = float(M[0, 0]) / Tu, float(M[0, 0]) / Tu**2 / 4.0
        return cls(k_psi=omega_rad_s / 2.0, r_max_rad_s=math.inf, k_r=2.0 * omega_rad_s * m_r,
                   k_i_psi=m_r * omega_rad_s**3 / 10.0 if integral else 0.0,
                   yaw_feedforward=0.0, k_u=k_u, k_i_u=k_iu, speed_feedforward=1.0,
                   crab_compensation=crab_compensation)

    @classmethod
    def rate_limited(cls, params: VesselParams, omega_rad_s: float, r_max_rad_s: float,
                     k_u: float, *, crab_compensation: bool = False) -> AutopilotGains:
        """Stiff yaw-rate loop k_r = 20ωm_r under r_d = sat(ωψ̃) with damping feed-forward
        on both channels and proportional speed feedback ``k_u`` [N s/m]."""
        m_r = params.I_z - params.N_rdot
        return cls(k_psi=omega_rad_s, r_max_rad_s=r_max_rad_s, k_r=20.0 * omega_rad_s * m_r,
                   yaw_feedforward=1.0, k_u=k_u, speed_feedforward=1.0,
                   crab_compensation=crab_compensation)

    @classmethod
    def for_vessel(cls, params: VesselParams) -> AutopilotGains:
        """The twin's own-ship autopilot, Froude-scaled from model scale.

        Heading: the rate-limited cascade with ω = 0.35 rad/s ÷ √λ and the turn rate held
        to 0.08 rad/s ÷ √λ; speed: damping feed-forward plus proportional feedback with a
        closed-loop time constant of 5 s × √λ (k_u = m_u / T_u); crab compensation on. No
        integrators, so it needs no control period.
        """
        f = _froude(params)
        return cls.rate_limited(params, 0.35 / f, 0.08 / f, float(params.M[0, 0]) / (5.0 * f),
                                crab_compensation=True)


def _per_vessel(value: ArrayLike, n: int, name: str) -> _F8:
    """A scalar or (n,) reference as a contiguous float64 array (n,)."""
    if isinstance(value, int | float):
        return np.full(n, float(value))
    a = np.asarray(value, dtype=np.float64)
    if a.size == 1:
        return np.full(n, float(a.reshape(-1)[0]))
    if a.shape != (n,):
        raise StateError(f"{name} must be a scalar or have shape ({n},), actually {a.shape}")
    return np.ascontiguousarray(a)


class HeadingSpeedAutopilot:
    """Heading (or course) and surge-speed autopilot for one or ``n`` vessels.

    Parameters
    ----------
    params : VesselParams or sequence of VesselParams
        The vessel(s); a sequence gives one vessel each (per-vessel damping and limits).
    gains : AutopilotGains, optional
        :meth:`AutopilotGains.for_vessel` of the (first) vessel by default.
    dt_s : float, optional
        Control period [s] for the integrators; required when a gain ``k_i_*`` is non-zero.

    Examples
    --------
    >>> import numpy as np
    >>> from asvtwin.vessel import cybership2
    >>> ap = HeadingSpeedAutopilot(cybership2())
    >>> tau = ap.tau(np.array([0, 0, 0, 0.2, 0, 0.0]), np.radians(30.0), 0.2)
    >>> tau.shape, bool(tau[2] > 0)
    ((3,), True)
    """

    def __init__(self, params: VesselParams | list[VesselParams] | tuple[VesselParams, ...],
                 gains: AutopilotGains | None = None, *, dt_s: float | None = None) -> None:
        plist = [params] if isinstance(params, VesselParams) else list(params)
        if not plist:
            raise ParameterError("HeadingSpeedAutopilot needs at least one VesselParams")
        self.params = plist
        self.gains = gains if gains is not None else AutopilotGains.for_vessel(plist[0])
        g = self.gains
        if (np.any(np.asarray(g.k_i_psi) > 0) or np.any(np.asarray(g.k_i_u) > 0)) and not (
                dt_s is not None and math.isfinite(dt_s) and dt_s > 0):
            raise ParameterError(f"dt_s must be finite and > 0 [s] when integral gains are "
                                 f"set, actually: {dt_s}")
        self.dt_s = dt_s
        self._X = np.array([[p.X_u, p.X_uu, p.X_uuu] for p in plist])
        self._Nr = np.array([p.N_r for p in plist])
        self._lo = np.array([p.actuators.tau_min for p in plist])
        self._hi = np.array([p.actuators.tau_max for p in plist])
        self._g = np.ascontiguousarray(np.column_stack(np.broadcast_arrays(*(
            np.atleast_1d(np.asarray(getattr(g, k), dtype=np.float64)) for k in (
                "k_psi", "r_max_rad_s", "k_r", "k_i_psi", "yaw_feedforward", "k_u", "k_i_u",
                "speed_feedforward")))))
        if self._g.shape[0] not in (1, len(plist)) and len(plist) != 1:
            raise ParameterError(f"gains hold {self._g.shape[0]} vessels, params "
                                 f"{len(plist)}")
        self._crab = bool(g.crab_compensation)
        self._h = 0.0 if dt_s is None else float(dt_s)
        self._iu: _F8 | None = None
        self._ipsi: _F8 | None = None

    def reset(self) -> None:
        """Zero the integrators."""
        self._iu = None
        self._ipsi = None

    def surge_feedforward(self, speed_ref_m_s: ArrayLike) -> _F8:
        """d(u_d) = −(X_u u_d + X_|u|u |u_d| u_d + X_uuu u_d³) [N]: thrust holding u_d."""
        u = np.asarray(speed_ref_m_s, dtype=np.float64)
        Xu, Xuu, Xuuu = self._X.T
        return np.asarray(-(Xu * u + Xuu * u * np.abs(u) + Xuuu * u**3))

    def tau(self, state: ArrayLike, course_ref_rad: ArrayLike,
            speed_ref_m_s: ArrayLike) -> _F8:
        """The command τ = [τ_u, 0, τ_r] within the actuator limits.

        Parameters
        ----------
        state : array_like, shape (6,) or (n, 6)
            ``[north, east, ψ, u, v, r]`` [m, m, rad, m/s, m/s, rad/s].
        course_ref_rad : array_like, scalar or (n,)
            Desired course χ_d [rad] (a heading when ``crab_compensation`` is off).
        speed_ref_m_s : array_like, scalar or (n,)
            Desired surge speed u_d [m/s].

        Returns
        -------
        ndarray, shape (3,) or (n, 3)
            [N, N, Nm], body frame.
        """
        x_in = np.asarray(state, dtype=np.float64)
        single = x_in.ndim == 1
        x = np.ascontiguousarray(x_in.reshape(1, -1) if single else x_in)
        if x.ndim != 2 or x.shape[1] != 6:
            raise StateError(f"state must have shape (6,) or (n, 6), actually {x_in.shape}")
        n = x.shape[0]
        if self._X.shape[0] not in (1, n) or self._g.shape[0] not in (1, n):
            raise StateError(f"state holds {n} vessels, the autopilot has "
                             f"{self._X.shape[0]} parameter sets and {self._g.shape[0]} gains")
        chi_d = _per_vessel(course_ref_rad, n, "course_ref_rad")
        u_d = _per_vessel(speed_ref_m_s, n, "speed_ref_m_s")
        if self._ipsi is None or self._iu is None or self._ipsi.shape[0] != n:
            self._ipsi = np.zeros(n)
            self._iu = np.zeros(n)
        out = np.empty((n, 3))
        ok = autopilot_kernel(x, chi_d, u_d, self._g, self._crab, self._X, self._Nr, self._lo,
                              self._hi, self._iu, self._ipsi, self._h, out)
        if not ok:
            raise StateError("state, course_ref_rad and speed_ref_m_s must be finite, "
                             f"actually: state {x_in!r}, course {course_ref_rad!r}, "
                             f"speed {speed_ref_m_s!r}")
        return out[0] if single else out
