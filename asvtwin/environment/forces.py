"""Environmental forces τ_d on the hull from current, wind and wave drift.

All functions are batched over vessels: state ``x`` (n, 6), output τ_d (n, 3) =
``[X, Y, N]`` [N, N, Nm] in the body frame, ready for ``BatchSimulator.step(tau, d=...)``.

Current
    The hydrodynamic forces act on the velocity relative to the water,
    ν_r = ν − ν_c with ν_c = R(ψ)ᵀ[V_N, V_E, 0]. Written as a disturbance on the paper's
    model (which uses ν over ground):

    .. math:: \\tau_{d,c} = C(\\nu)\\nu + D(\\nu)\\nu - C(\\nu_r)\\nu_r - D(\\nu_r)\\nu_r

    so an unpowered vessel drifts with the current (ν → ν_c), as it should (Fossen 2011,
    §8.3, irrotational current, with the rigid-body/added-mass split folded together).
    Both terms come from the vessel kernel's n(ν) = C(ν)ν + D(ν)ν
    (:func:`asvtwin.vessel.kernels.hydrodynamic_force`), the one place the simulator, the
    safety filter and the observer share, in one compiled pass over the vessels.

Wind (Fossen 2011 §8.1, Isherwood-type coefficients)
    .. math::

        u_{rw} = u - u_w,\\; v_{rw} = v - v_w,\\; \\gamma_{rw} = -\\operatorname{atan2}(v_{rw},
        u_{rw}),\\; q = \\tfrac12 \\rho_a V_{rw}^2

        X = -q c_x \\cos\\gamma_{rw} A_F,\\; Y = q c_y \\sin\\gamma_{rw} A_L,\\;
        N = q c_n \\sin(2\\gamma_{rw}) A_L L

    with (u_w, v_w) the wind velocity in the body frame.

Wave drift
    A slowly varying second-order drift force of magnitude F (from the wave state, see
    :mod:`asvtwin.environment.disturbances`) pushing along the waves' travel direction β:
    X = F (B/L) cos(β − ψ), Y = F sin(β − ψ), N = F c_yaw L sin(2(β − ψ)): beam seas
    push hardest, head seas by the ratio of the waterline's widths.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from asvtwin.errors import StateError
from asvtwin.vessel.kernels import hydrodynamic_force
from asvtwin.vessel.params import VesselParams

__all__ = [
    "RHO_AIR",
    "WindCoefficients",
    "current_force",
    "environment_force",
    "wave_drift_force",
    "wind_force",
]

#: Density of air at 10 °C at sea level [kg/m^3].
RHO_AIR = 1.247


class WindCoefficients:
    """Isherwood-type wind coefficients c_x, c_y, c_n (Fossen 2011, Table 8.2 ranges).

    Defaults are mid-range values for a supply ship / general cargo vessel:
    c_x = 0.7 (0.50-0.90), c_y = 0.85 (0.70-0.95), c_n = 0.10 (0.05-0.20).
    """

    __slots__ = ("c_n", "c_x", "c_y")

    def __init__(self, c_x: float = 0.7, c_y: float = 0.85, c_n: float = 0.10) -> None:
        self.c_x, self.c_y, self.c_n = float(c_x), float(c_y), float(c_n)


def _body_components(psi: NDArray[np.float64], vec_ned: NDArray[np.float64]
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Rotate NED vectors (n, 2) into the body frame: R(ψ)ᵀ [N, E]."""
    c, s = np.cos(psi), np.sin(psi)
    return c * vec_ned[:, 0] + s * vec_ned[:, 1], -s * vec_ned[:, 0] + c * vec_ned[:, 1]


_PACKED: dict[int, tuple[VesselParams, NDArray[np.float64]]] = {}


def _packed(params: VesselParams) -> NDArray[np.float64]:
    """The kernels' coefficient row (1, 27) of a parameter set.

    Parameter sets are immutable, so the row is kept per object (by identity: hashing a
    30-field dataclass would cost more than the force itself); at most 64 are kept."""
    hit = _PACKED.get(id(params))
    if hit is not None and hit[0] is params:
        return hit[1]
    P = np.ascontiguousarray(params.packed()[None, :])
    P.flags.writeable = False
    if len(_PACKED) >= 64:
        _PACKED.clear()
    _PACKED[id(params)] = (params, P)
    return P


@njit(cache=True)
def _current_force_batch(x, vc, P, out):  # pragma: no cover - compiled
    shared_v = vc.shape[0] == 1
    for i in range(x.shape[0]):
        j = 0 if shared_v else i
        c = math.cos(x[i, 2])
        s = math.sin(x[i, 2])
        # ν_c = R(ψ)ᵀ [V_N, V_E, 0]
        uc = c * vc[j, 0] + s * vc[j, 1]
        vcb = -s * vc[j, 0] + c * vc[j, 1]
        u, v, r = x[i, 3], x[i, 4], x[i, 5]
        # τ_d,c = n(ν) − n(ν_r), n(ν) = C(ν)ν + D(ν)ν
        a0, a1, a2 = hydrodynamic_force(u, v, r, P[0])
        b0, b1, b2 = hydrodynamic_force(u - uc, v - vcb, r, P[0])
        out[i, 0] = a0 - b0
        out[i, 1] = a1 - b1
        out[i, 2] = a2 - b2


def current_force(params: VesselParams, x: ArrayLike, current_ned_m_s: ArrayLike
                  ) -> NDArray[np.float64]:
    """τ_d of an ocean current (n, 3) [N, N, Nm].

    Parameters
    ----------
    params : VesselParams
    x : array_like, (n, 6) or (6,)
        States [x, y, ψ, u, v, r] [m, m, rad, m/s, m/s, rad/s].
    current_ned_m_s : array_like, (2,) or (n, 2)
        Current velocity over ground [V_N, V_E] [m/s].

    Examples
    --------
    >>> from asvtwin.vessel import cybership2
    >>> # drifting north at 0.1 m/s with a 0.1 m/s northward current: no flow past the
    >>> # hull, so τ_d cancels the still-water drag d11(u)·u the model applies [N]
    >>> tau_d = current_force(cybership2(), [0, 0, 0, 0.1, 0, 0], [0.1, 0.0])
    >>> round(float(tau_d[0, 0]), 4), float(tau_d[0, 1]), float(tau_d[0, 2])
    (0.0914, 0.0, 0.0)
    """
    x = np.ascontiguousarray(np.atleast_2d(np.asarray(x, dtype=np.float64)))
    vc = np.ascontiguousarray(np.atleast_2d(np.asarray(current_ned_m_s, dtype=np.float64)))
    if x.ndim != 2 or x.shape[1] != 6:
        raise StateError(f"x must have shape (n, 6), actually: {x.shape}")
    if vc.ndim != 2 or vc.shape[1] != 2 or vc.shape[0] not in (1, x.shape[0]):
        raise StateError(f"current_ned_m_s must have shape (2,) or ({x.shape[0]}, 2), "
                         f"actually: {np.shape(current_ned_m_s)}")
    out = np.empty((x.shape[0], 3))
    _current_force_batch(x, vc, _packed(params), out)
    return out


def wind_force(params: VesselParams, x: ArrayLike, wind_ned_m_s: ArrayLike, *,
               coefficients: WindCoefficients | None = None, rho_air: float = RHO_AIR
               ) -> NDArray[np.float64]:
    """Wind force and moment (n, 3) [N, N, Nm] from the wind velocity over ground.

    Parameters
    ----------
    wind_ned_m_s : array_like, (2,) or (n, 2)
        Velocity of the air [N, E] [m/s] (the direction it blows *towards*; a wind
        *from* the north at 10 m/s is ``[-10, 0]``, see
        :func:`asvtwin.environment.disturbances.wind_vector`).
    """
    k = coefficients or WindCoefficients()
    x = np.atleast_2d(np.asarray(x, dtype=float))
    vw = np.broadcast_to(np.asarray(wind_ned_m_s, dtype=float), (x.shape[0], 2))
    uw, vwb = _body_components(x[:, 2], vw)
    u_rw = x[:, 3] - uw
    v_rw = x[:, 4] - vwb
    gamma = -np.arctan2(v_rw, u_rw)
    q = 0.5 * rho_air * (u_rw**2 + v_rw**2)
    tau = np.empty((x.shape[0], 3))
    tau[:, 0] = -q * k.c_x * np.cos(gamma) * params.area_frontal
    tau[:, 1] = q * k.c_y * np.sin(gamma) * params.area_lateral
    tau[:, 2] = q * k.c_n * np.sin(2.0 * gamma) * params.area_lateral * params.length
    return tau


def wave_drift_force(params: VesselParams, x: ArrayLike, magnitude_n: ArrayLike,
                     travel_dir_rad: float, *, c_yaw: float = 0.05) -> NDArray[np.float64]:
    """Slowly varying wave-drift force (n, 3) [N, N, Nm].

    Parameters
    ----------
    magnitude_n : array_like, () or (n,)
        Instantaneous drift force magnitude [N] (mean plus slow variation).
    travel_dir_rad : float
        Direction the waves travel towards [rad], NED (from north, clockwise).
    c_yaw : float
        Yaw moment arm as a fraction of the length.
    """
    x = np.atleast_2d(np.asarray(x, dtype=float))
    F = np.broadcast_to(np.asarray(magnitude_n, dtype=float), (x.shape[0],))
    rel = travel_dir_rad - x[:, 2]
    tau = np.empty((x.shape[0], 3))
    # beam seas give the larger drift force: weight sway by the hull's aspect
    tau[:, 0] = F * np.cos(rel) * (params.beam / params.length)
    tau[:, 1] = F * np.sin(rel)
    tau[:, 2] = F * c_yaw * params.length * np.sin(2.0 * rel)
    return tau


@njit(cache=True)
def _environment_force_batch(x, vc, vw, P, wind, wave, F, out):  # pragma: no cover - compiled
    """Current, wind and wave drift on states ``x`` (n, 6) added into ``out`` (n, 3), in
    one compiled pass: the arithmetic of :func:`current_force`, :func:`wind_force` and
    :func:`wave_drift_force` operation for operation (for one vessel the NumPy versions
    spend ~30 calls on 1-element arrays per step).

    ``vc``, ``vw``: (2,) current and air velocity over ground [m/s];
    ``wind``: [c_x, c_y, c_n, rho_air, area_frontal, area_lateral, length];
    ``wave``: [travel direction β, beam/length, c_yaw, length, on (0/1)]; ``F`` the
    drift force magnitude [N].
    Each part is added only where :meth:`Environment.forces` adds it: the current when
    it is non-zero, the wind when it or any vessel's (u, v) is non-zero, the waves when
    H_s > 0."""
    n = x.shape[0]
    use_current = vc[0] != 0.0 or vc[1] != 0.0
    use_wind = vw[0] != 0.0 or vw[1] != 0.0
    if not use_wind:
        for i in range(n):
            if x[i, 3] != 0.0 or x[i, 4] != 0.0:
                use_wind = True
                break
    for i in range(n):
        c = math.cos(x[i, 2])
        s = math.sin(x[i, 2])
        u, v, r = x[i, 3], x[i, 4], x[i, 5]
        if use_current:
            uc = c * vc[0] + s * vc[1]
            vcb = -s * vc[0] + c * vc[1]
            a0, a1, a2 = hydrodynamic_force(u, v, r, P[0])
            b0, b1, b2 = hydrodynamic_force(u - uc, v - vcb, r, P[0])
            out[i, 0] += a0 - b0
            out[i, 1] += a1 - b1
            out[i, 2] += a2 - b2
        if use_wind:
            uw = c * vw[0] + s * vw[1]
            vwb = -s * vw[0] + c * vw[1]
            u_rw = u - uw
            v_rw = v - vwb
            gamma = -math.atan2(v_rw, u_rw)
            q = 0.5 * wind[3] * (u_rw**2 + v_rw**2)
            out[i, 0] += -q * wind[0] * math.cos(gamma) * wind[4]
            out[i, 1] += q * wind[1] * math.sin(gamma) * wind[5]
            out[i, 2] += q * wind[2] * math.sin(2.0 * gamma) * wind[5] * wind[6]
        if wave[4] != 0.0:
            rel = wave[0] - x[i, 2]
            out[i, 0] += F * math.cos(rel) * wave[1]
            out[i, 1] += F * math.sin(rel)
            out[i, 2] += F * wave[2] * wave[3] * math.sin(2.0 * rel)


def environment_force(params: VesselParams, x: ArrayLike, current_ned_m_s: ArrayLike,
                      wind_ned_m_s: ArrayLike, *, wave_magnitude_n: float = 0.0,
                      wave_travel_dir_rad: float = 0.0, waves: bool = False,
                      coefficients: WindCoefficients | None = None, rho_air: float = RHO_AIR,
                      c_yaw: float = 0.05) -> NDArray[np.float64]:
    """τ_d (n, 3) [N, N, Nm] of current, wind and (with ``waves``) wave drift together,
    compiled: the sum of :func:`current_force`, :func:`wind_force` and
    :func:`wave_drift_force` (added in that order, each where the environment adds it),
    one compiled call instead of ~30 NumPy calls.

    Parameters
    ----------
    x : array_like, (n, 6) or (6,)
    current_ned_m_s, wind_ned_m_s : array_like, (2,)
        Current and air velocity over ground [N, E] [m/s], shared by every vessel.
    wave_magnitude_n : float
        Drift force magnitude [N]; ``wave_travel_dir_rad`` the waves' travel direction.
    """
    k = coefficients or WindCoefficients()
    x = np.ascontiguousarray(np.atleast_2d(np.asarray(x, dtype=np.float64)))
    if x.ndim != 2 or x.shape[1] != 6:
        raise StateError(f"x must have shape (n, 6), actually: {x.shape}")
    vc = np.asarray(current_ned_m_s, dtype=np.float64)
    vw = np.asarray(wind_ned_m_s, dtype=np.float64)
    if vc.shape != (2,) or vw.shape != (2,):
        raise StateError(f"current and wind must have shape (2,), actually: {vc.shape}, "
                         f"{vw.shape}")
    wind, wave = environment_rows(params, k, rho_air, wave_travel_dir_rad, c_yaw, waves)
    out = np.zeros((x.shape[0], 3))
    _environment_force_batch(x, vc, vw, _packed(params), wind, wave, float(wave_magnitude_n),
                             out)
    return out


def environment_rows(params: VesselParams, coefficients: WindCoefficients, rho_air: float,
                     wave_travel_dir_rad: float, c_yaw: float, waves: bool
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The constant rows of :func:`_environment_force_batch` (wind, waves) for a hull."""
    k = coefficients
    wind = np.array([k.c_x, k.c_y, k.c_n, rho_air, params.area_frontal,
                     params.area_lateral, params.length])
    wave = np.array([float(wave_travel_dir_rad), params.beam / params.length, c_yaw,
                     params.length, 1.0 if waves else 0.0])
    return wind, wave
