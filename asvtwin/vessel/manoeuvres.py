"""Standard manoeuvres (IMO MSC.137(76) style) run on the simulator, with their numbers.

The vessels here steer with a yaw moment, not a rudder, so the manoeuvres are stated in
yaw moment: a *turning circle* holds the surge thrust and a constant yaw moment (a fraction
of the largest); a *zig-zag a/b* alternates the yaw moment ``±yaw_fraction · τ_r,max``
whenever the heading has turned ``b`` degrees away from the base course (``a`` names the
yaw fraction in tenths, 10 meaning full yaw moment); a *thrust step* applies a surge
thrust step from rest.

Each starts at the origin on heading ``psi0_rad`` and returns a
:class:`ManoeuvreResult` with the time series (plain arrays) and a dict of
metrics in SI units and degrees where a ship handler expects them.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import brentq

from asvtwin.errors import ParameterError
from asvtwin.vessel.params import VesselParams
from asvtwin.vessel.simulator import VesselSimulator

__all__ = [
    "MANOEUVRES",
    "ManoeuvreResult",
    "steady_surge_speed",
    "thrust_step",
    "turning_circle",
    "zigzag",
]


@dataclass(frozen=True)
class ManoeuvreResult:
    """Time series and metrics of one manoeuvre.

    Attributes
    ----------
    name : str
    vessel : str
    t_s : (k,) times [s]
    x : (k, 6) states [x, y, ψ, u, v, r]
    tau : (k, 3) actual thrust [N, N, Nm]
    metrics : dict of named numbers (units in the names)
    """

    name: str
    vessel: str
    t_s: NDArray[np.floating]
    x: NDArray[np.floating]
    tau: NDArray[np.floating]
    metrics: dict[str, float] = field(default_factory=dict)


def steady_surge_speed(params: VesselParams, force_n: float) -> float:
    """The speed u > 0 at which surge damping balances ``force_n``: d11(u)·u = F [m/s]."""
    if force_n <= 0:
        raise ParameterError(f"force_n must be > 0, actually: {force_n}")
    p = params

    def residual(u: float) -> float:
        return (-p.X_u - p.X_uu * u - p.X_uuu * u * u) * u - force_n

    hi = 1.0
    while residual(hi) < 0:
        hi *= 2.0
    return float(brentq(residual, 0.0, hi, xtol=1e-12))


def _run(params: VesselParams, x0: NDArray[np.float64], dt_s: float, n_steps: int,
         control: Callable[[float, NDArray[np.float64]], ArrayLike]
         ) -> tuple[NDArray[np.floating], NDArray[np.floating], NDArray[np.floating]]:
    sim = VesselSimulator(params, x0, dt_s=dt_s)
    xs = np.empty((n_steps + 1, 6))
    taus = np.empty((n_steps + 1, 3))
    xs[0] = x0
    taus[0] = sim.thrust
    for k in range(n_steps):
        xs[k + 1] = sim.step(control(k * dt_s, xs[k]))
        taus[k + 1] = sim.thrust
    return np.arange(n_steps + 1) * dt_s, xs, taus


def _rotated(xs: NDArray[np.floating], psi0_rad: float) -> NDArray[np.floating]:
    """The same run started on heading ``psi0_rad``: positions turned about the start,
    headings offset (the model is invariant to both; metrics are computed before)."""
    if psi0_rad == 0.0:
        return xs
    out = xs.copy()
    c, s = math.cos(psi0_rad), math.sin(psi0_rad)
    out[:, 0] = c * xs[:, 0] - s * xs[:, 1]
    out[:, 1] = s * xs[:, 0] + c * xs[:, 1]
    out[:, 2] = xs[:, 2] + psi0_rad
    return out


def _approach(params: VesselParams, surge_fraction: float) -> tuple[float, float]:
    act = params.actuators
    F = surge_fraction * act.tau_max[0]
    if not (F > 0 and math.isfinite(F)):
        raise ParameterError(f"{params.name}: surge thrust for the manoeuvre must be finite "
                             f"and > 0, actually: {F} (actuators.tau_max[0]={act.tau_max[0]})")
    return F, steady_surge_speed(params, F)


def _time_scale(params: VesselParams) -> float:
    """A time step that resolves the vessel's dynamics: ~1/50 of L/U."""
    _, U = _approach(params, 1.0)
    return max(1e-3, min(1.0, params.length / U / 50.0))


def turning_circle(params: VesselParams, *, surge_fraction: float = 1.0,
                   yaw_fraction: float = 1.0, dt_s: float | None = None,
                   psi0_rad: float = 0.0) -> ManoeuvreResult:
    """Turn to starboard from a steady approach until the heading has changed 540°.

    Metrics: advance and transfer at 90°, tactical diameter (transfer at 180°), steady
    turning diameter (from the last full circle), steady speed and yaw rate, all also
    in ship lengths.
    """
    F, U0 = _approach(params, surge_fraction)
    N_r = yaw_fraction * params.actuators.tau_max[2]
    dt = dt_s or _time_scale(params)
    x0 = np.array([0.0, 0.0, 0.0, U0, 0.0, 0.0])
    sim = VesselSimulator(params, x0, dt_s=dt)
    sim.batch.reset(x0[None], tau0=[[F, 0.0, 0.0]])
    rows, taus = [x0], [sim.thrust]
    cmd = np.array([F, 0.0, N_r])
    limit = 1_000_000
    while abs(rows[-1][2]) < math.radians(540.0) and len(rows) < limit:
        rows.append(sim.step(cmd))
        taus.append(sim.thrust)
    xs, tau = np.array(rows), np.array(taus)
    if abs(xs[-1, 2]) < math.radians(540.0):
        raise ParameterError(f"{params.name}: the vessel does not complete a turning "
                             f"circle with yaw moment {N_r}")
    t = np.arange(len(xs)) * dt
    psi = np.abs(xs[:, 2])

    def at(angle_deg: float, col: int) -> float:
        return float(np.interp(math.radians(angle_deg), psi, np.abs(xs[:, col])))

    last = psi >= math.radians(180.0)
    pos = xs[last][:, :2]
    diam = float(max(np.ptp(pos[:, 0]), np.ptp(pos[:, 1])))
    L = params.length
    m = {
        "approach_speed_m_s": U0,
        "advance_m": at(90.0, 0),
        "transfer_m": at(90.0, 1),
        "tactical_diameter_m": at(180.0, 1),
        "steady_turning_diameter_m": diam,
        "steady_speed_m_s": float(np.hypot(xs[-1, 3], xs[-1, 4])),
        "steady_yaw_rate_deg_s": float(math.degrees(xs[-1, 5])),
        "time_to_540_deg_s": float(t[-1]),
    }
    m["advance_L"] = m["advance_m"] / L
    m["tactical_diameter_L"] = m["tactical_diameter_m"] / L
    return ManoeuvreResult("turning_circle", params.name, t, _rotated(xs, psi0_rad), tau, m)


def zigzag(params: VesselParams, *, switch_deg: float = 10.0, yaw_fraction: float = 1.0,
           surge_fraction: float = 1.0, n_switches: int = 5, dt_s: float | None = None,
           psi0_rad: float = 0.0) -> ManoeuvreResult:
    """Zig-zag: yaw moment ±``yaw_fraction``·τ_r,max, reversed when the heading passes
    ±``switch_deg``. Metrics: first and second overshoot angles [deg], initial turning
    time, period of the first full cycle, and ``swing_checked`` (1 or 0).

    CyberShip II's published coefficients make it course-unstable above about 0.35 m/s
    (60 % of top speed): its Munk moment (M22 − M11)·u·v outgrows the largest yaw moment
    once it turns, and a reversed moment no longer checks the swing. The run then ends
    after ~200 ship lengths with NaN overshoots and ``swing_checked = 0``.
    """
    F, U0 = _approach(params, surge_fraction)
    N_max = yaw_fraction * params.actuators.tau_max[2]
    dt = dt_s or _time_scale(params)
    x0 = np.array([0.0, 0.0, 0.0, U0, 0.0, 0.0])
    sim = VesselSimulator(params, x0, dt_s=dt)
    sim.batch.reset(x0[None], tau0=[[F, 0.0, 0.0]])
    sw = math.radians(switch_deg)
    sign = 1.0
    switch_t: list[float] = []
    rows, taus = [x0], [sim.thrust]
    # each execute ends at the next heading extremum; record peaks after each switch
    peaks: list[float] = []
    tracking_peak = False
    k = 0
    k_max = int(200.0 * params.length / U0 / dt)  # ~200 ship lengths run
    while len(peaks) < n_switches and k < k_max:
        psi = rows[-1][2]
        if sign > 0 and psi >= sw or sign < 0 and psi <= -sw:
            sign = -sign
            switch_t.append(k * dt)
            tracking_peak = True
        rows.append(sim.step([F, 0.0, sign * N_max]))
        taus.append(sim.thrust)
        k += 1
        if tracking_peak and rows[-1][5] * rows[-2][5] <= 0.0:  # yaw rate changes sign
            peaks.append(abs(rows[-1][2]) - sw)
            tracking_peak = False
    xs, tau = np.array(rows), np.array(taus)
    t = np.arange(len(xs)) * dt
    peaks += [math.nan] * (2 - len(peaks))
    m = {
        "approach_speed_m_s": U0,
        # 0 when the reversed yaw moment never checked the swing: the vessel is
        # course-unstable at this speed and ends in a steady turn (see docs/vessel.md)
        "swing_checked": float(not math.isnan(peaks[1])),
        "first_overshoot_deg": math.degrees(peaks[0]),
        "second_overshoot_deg": math.degrees(peaks[1]),
        "initial_turning_time_s": switch_t[0],
        "period_s": (switch_t[2] - switch_t[0]) if len(switch_t) >= 3 else float("nan"),
    }
    return ManoeuvreResult(f"zigzag_{switch_deg:g}", params.name, t, _rotated(xs, psi0_rad),
                           tau, m)


def thrust_step(params: VesselParams, *, surge_fraction: float = 1.0,
                duration_s: float | None = None, dt_s: float | None = None,
                psi0_rad: float = 0.0) -> ManoeuvreResult:
    """From rest, a surge thrust step. Metrics: final and analytic steady speed, the time
    to reach 63 % and 95 % of it, distance run."""
    F, U = _approach(params, surge_fraction)
    dt = dt_s or _time_scale(params)
    M11 = params.M[0, 0]
    # linearised time constant M11 / d11'(U) sets a sensible duration
    slope = -params.X_u - 2 * params.X_uu * U - 3 * params.X_uuu * U * U
    T = duration_s or max(10.0 * M11 / slope, 20 * dt)
    n = math.ceil(T / dt)
    t, xs, tau = _run(params, np.zeros(6), dt, n, lambda _t, _x: (F, 0.0, 0.0))
    u = xs[:, 3]
    m = {
        "thrust_n": F,
        "steady_speed_analytic_m_s": U,
        "final_speed_m_s": float(u[-1]),
        "t63_s": float(np.interp(0.632 * U, u, t)),
        "t95_s": float(np.interp(0.95 * U, u, t)),
        "distance_m": float(xs[-1, 0]),
    }
    return ManoeuvreResult("thrust_step", params.name, t, _rotated(xs, psi0_rad), tau, m)


#: CLI names of the manoeuvres.
MANOEUVRES: dict[str, Callable[..., ManoeuvreResult]] = {
    "turning-circle": turning_circle,
    "zigzag": zigzag,
    "thrust-step": thrust_step,
}
