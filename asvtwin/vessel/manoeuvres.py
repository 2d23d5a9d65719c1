"""Standard manoeuvres (IMO MSC.137(76) style) run on the simulator, with their numbers.

The vessels here steer with a yaw moment, not a rudder, so the manoeuvres are stated in
yaw moment: a *turning circle* holds the surge thrust and a constant yaw moment (a fraction
of the largest); a *zig-zag a/b* alternates the yaw moment ``±yaw_fraction · τ_r,max``
whenever the heading has turned ``b`` degrees away from the base course (``a`` names the
yaw fraction in tenths, 10 meaning full yaw moment); a *thrust step* applies a surge
thrust step from rest.

Each starts at the origin on heading ``psi0_rad`` and returns a
:class:`ManoeuvreResult` with the time series (plain arrays), a dict of metrics in SI
units and degrees where a ship handler expects them, the reason for every metric that is
undefined (NaN), and the IMO manoeuvring criteria that apply, with pass/fail.

The IMO criteria are those of the Standards for Ship Manoeuvrability (IMO 2002,
Resolution MSC.137(76)): advance ≤ 4.5 L and tactical diameter ≤ 5 L in the turning
test; in the 10°/10° zig-zag, initial turning (≤ 2.5 L run by a 10° heading change) and
the first and second overshoot limits, which grow with L/V [s]; in the 20°/20° zig-zag,
first overshoot ≤ 25°. The Standards apply to ships of 100 m and more, steered by a
rudder at 35° (turning) or 10°/20° (zig-zag); here the largest yaw moment stands in for
the rudder, so the numbers place the model against the Standards rather than certify it.

Inputs are checked before anything runs: fractions in (0, 1], a switch angle in
(0°, 90°), and a time step below the RK4 stability limit of the model linearised at the
approach speed (:func:`rk4_stable_step`). A run whose speed still grows past twice the
top speed is reported as diverged instead of returning its numbers.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import brentq

from asvtwin.checks import check_positive, check_range
from asvtwin.errors import ParameterError
from asvtwin.vessel.model import coriolis, damping
from asvtwin.vessel.params import VesselParams
from asvtwin.vessel.simulator import VesselSimulator

__all__ = [
    "MANOEUVRES",
    "METRICS",
    "ImoCriterion",
    "ManoeuvreResult",
    "rk4_stable_step",
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
    notes : dict
        Why a metric is NaN (metric name -> reason), empty when all are defined.
    criteria : tuple of ImoCriterion
        The IMO MSC.137(76) criteria this manoeuvre tests, with pass/fail.
    """

    name: str
    vessel: str
    t_s: NDArray[np.floating]
    x: NDArray[np.floating]
    tau: NDArray[np.floating]
    metrics: dict[str, float] = field(default_factory=dict)
    notes: dict[str, str] = field(default_factory=dict)
    criteria: tuple[ImoCriterion, ...] = ()


@dataclass(frozen=True)
class ImoCriterion:
    """One criterion of the IMO Standards for Ship Manoeuvrability (MSC.137(76)).

    Attributes
    ----------
    name : str
        What is limited, in words ("tactical diameter").
    value, limit : float
        The measured value and its upper limit, in ``unit``.
    unit : str
        "L" (ship lengths), "deg".
    clause : str
        Where the limit comes from (paragraph of MSC.137(76), Annex 5.3).
    """

    name: str
    value: float
    limit: float
    unit: str
    clause: str

    @property
    def passed(self) -> bool:
        """True when the value is within the limit (False when it is NaN)."""
        return bool(self.value <= self.limit)


#: Each metric's meaning in words and its unit (for tables and figures).
METRICS: dict[str, tuple[str, str]] = {
    "approach_speed_m_s": ("approach speed", "m/s"),
    "advance_m": ("advance at 90°", "m"),
    "transfer_m": ("transfer at 90°", "m"),
    "tactical_diameter_m": ("tactical diameter (transfer at 180°)", "m"),
    "steady_turning_diameter_m": ("steady turning diameter 2U/r", "m"),
    "steady_speed_m_s": ("steady speed in the turn", "m/s"),
    "steady_yaw_rate_deg_s": ("steady yaw rate", "deg/s"),
    "time_to_540_deg_s": ("time to turn 540°", "s"),
    "advance_L": ("advance", "ship lengths"),
    "tactical_diameter_L": ("tactical diameter", "ship lengths"),
    "steady_turning_diameter_L": ("steady turning diameter", "ship lengths"),
    "swing_checked": ("swing checked by the reversed moment", "1 yes, 0 no"),
    "first_overshoot_deg": ("first overshoot", "deg"),
    "second_overshoot_deg": ("second overshoot", "deg"),
    "initial_turning_time_s": ("time to the first switch", "s"),
    "initial_turning_distance_L": ("run to the first switch", "ship lengths"),
    "period_s": ("period of the first cycle", "s"),
    "L_over_V_s": ("ship length / approach speed", "s"),
    "thrust_n": ("surge thrust", "N"),
    "steady_speed_analytic_m_s": ("steady speed, analytic", "m/s"),
    "final_speed_m_s": ("final speed", "m/s"),
    "t63_s": ("time to 63 % of steady speed", "s"),
    "t95_s": ("time to 95 % of steady speed", "s"),
    "distance_m": ("distance run", "m"),
    "min_distance_to_shore_m": ("closest approach to the shore", "m"),
}


#: Largest |z| on the negative real axis where classic RK4 is stable (|R(z)| ≤ 1).
_RK4_REAL_LIMIT = 2.785


def rk4_stable_step(params: VesselParams, nu: ArrayLike) -> float:
    """Largest time step [s] at which classic RK4 is stable for the model linearised
    at the velocity ``nu`` = [u, v, r] [m/s, m/s, rad/s].

    The linearisation is ν̇ ≈ A δν with A = −M⁻¹ ∂(C(ν)ν + D(ν)ν)/∂ν (central
    differences). The step h is stable when every *decaying* mode λ of A keeps
    |R(hλ)| ≤ 1 with R(z) = 1 + z + z²/2 + z³/6 + z⁴/24; growing modes (the course
    instability of CyberShip II at speed) are physics, not integration error, and are
    left out. The thruster lag is integrated exactly and sets no limit.
    """
    nu = np.asarray(nu, dtype=float).reshape(3)

    def n_of(v: NDArray[np.float64]) -> NDArray[np.float64]:
        v2 = v[None, :]
        return np.einsum("nij,nj->ni", coriolis(params, v2) + damping(params, v2), v2)[0]

    J = np.empty((3, 3))
    for j in range(3):
        h = 1e-6 * max(1.0, abs(nu[j]))
        d = np.zeros(3)
        d[j] = h
        J[:, j] = (n_of(nu + d) - n_of(nu - d)) / (2.0 * h)
    lam = np.linalg.eigvals(-np.linalg.solve(params.M, J))
    lam = lam[lam.real < 0.0]
    if lam.size == 0:
        return math.inf

    def stable(h: float) -> bool:
        z = h * lam
        return bool(np.all(np.abs(1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24) <= 1.0 + 1e-12))

    lo, hi = 0.0, _RK4_REAL_LIMIT / float(np.abs(lam).max())
    while stable(hi):
        lo, hi = hi, 2.0 * hi
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo


def _check_fraction(name: str, value: float) -> None:
    # above 1 the thruster saturates at the first step: the run would be mislabelled
    check_range(value, f"{name} (of the largest thrust)", 0.0, 1.0, lo_open=True)


def _time_step(params: VesselParams, dt_s: float | None, U: float) -> float:
    """``dt_s``, or the default; refused at or above the RK4 stability limit at speed U."""
    if dt_s is None:
        return _time_scale(params)
    check_positive(dt_s, "dt_s [s]")
    limit = rk4_stable_step(params, [U, 0.0, 0.0])
    if dt_s >= limit:
        raise ParameterError(
            f"dt_s = {dt_s:g} s is at or above the RK4 stability limit of {params.name} "
            f"at {U:.3g} m/s ({limit:.3g} s, from the model's damping time constants); "
            f"use dt_s < {limit:.3g} s (default {_time_scale(params):.3g} s = L/U/50)")
    return dt_s


def _check_bounded(params: VesselParams, xs: NDArray[np.floating], dt: float) -> None:
    """Refuse a run whose speed exceeds twice the vessel's top speed: RK4 diverged."""
    top = steady_surge_speed(params, params.actuators.tau_max[0])
    speed = np.hypot(xs[:, 3], xs[:, 4])
    if not np.all(np.isfinite(xs)) or float(speed.max()) > 2.0 * top:
        raise ParameterError(
            f"the simulation diverged at dt_s = {dt:g} s (speed reached "
            f"{float(np.nanmax(speed)):.3g} m/s, top speed {top:.3g} m/s); use a "
            f"smaller time step")


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

    Metrics: advance and transfer at 90°, tactical diameter (transfer at 180°), the
    steady turning diameter 2U/r at the end of the run (U the speed over ground and r
    the yaw rate, both steady by then: the track is a circle of radius U/r), steady speed
    and yaw rate, all also in ship lengths. Criteria: advance ≤ 4.5 L and tactical
    diameter ≤ 5 L (MSC.137(76), Annex 5.3.1).
    """
    _check_fraction("surge_fraction", surge_fraction)
    _check_fraction("yaw_fraction", yaw_fraction)
    F, U0 = _approach(params, surge_fraction)
    N_r = yaw_fraction * params.actuators.tau_max[2]
    dt = _time_step(params, dt_s, U0)
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
    _check_bounded(params, xs, dt)
    if abs(xs[-1, 2]) < math.radians(540.0):
        raise ParameterError(f"{params.name}: the vessel does not complete a turning "
                             f"circle with yaw moment {N_r}")
    t = np.arange(len(xs)) * dt
    psi = np.abs(xs[:, 2])

    def at(angle_deg: float, col: int) -> float:
        return float(np.interp(math.radians(angle_deg), psi, np.abs(xs[:, col])))

    U_end = float(np.hypot(xs[-1, 3], xs[-1, 4]))
    L = params.length
    m = {
        "approach_speed_m_s": U0,
        "advance_m": at(90.0, 0),
        "transfer_m": at(90.0, 1),
        "tactical_diameter_m": at(180.0, 1),
        # the steady circle: radius U/r
        "steady_turning_diameter_m": 2.0 * U_end / abs(float(xs[-1, 5])),
        "steady_speed_m_s": U_end,
        "steady_yaw_rate_deg_s": float(math.degrees(xs[-1, 5])),
        "time_to_540_deg_s": float(t[-1]),
    }
    m["advance_L"] = m["advance_m"] / L
    m["tactical_diameter_L"] = m["tactical_diameter_m"] / L
    m["steady_turning_diameter_L"] = m["steady_turning_diameter_m"] / L
    criteria = (
        ImoCriterion("advance", m["advance_L"], 4.5, "L", "MSC.137(76) 5.3.1.1"),
        ImoCriterion("tactical diameter", m["tactical_diameter_L"], 5.0, "L",
                     "MSC.137(76) 5.3.1.1"),
    )
    return ManoeuvreResult("turning_circle", params.name, t, _rotated(xs, psi0_rad), tau, m,
                           criteria=criteria)


def _zigzag_criteria(switch_deg: float, L_over_V_s: float, initial_turning_L: float,
                     first_deg: float, second_deg: float) -> tuple[ImoCriterion, ...]:
    """MSC.137(76) Annex 5.3.1.2-5.3.1.4 for the 10°/10° and 20°/20° zig-zags."""
    lv = L_over_V_s
    if switch_deg == 10.0:
        # first overshoot: 10° if L/V < 10 s, 20° if L/V ≥ 30 s, 5 + ½ L/V between
        first = 10.0 if lv < 10.0 else 20.0 if lv >= 30.0 else 5.0 + 0.5 * lv
        # second overshoot: 25° if L/V < 10 s, 40° if L/V ≥ 30 s, 17.5 + 0.75 L/V between
        second = 25.0 if lv < 10.0 else 40.0 if lv >= 30.0 else 17.5 + 0.75 * lv
        return (
            ImoCriterion("initial turning (run to 10° heading change)", initial_turning_L,
                         2.5, "L", "MSC.137(76) 5.3.1.2"),
            ImoCriterion("first overshoot, 10°/10° zig-zag", first_deg, first, "deg",
                         "MSC.137(76) 5.3.1.3.1"),
            ImoCriterion("second overshoot, 10°/10° zig-zag", second_deg, second, "deg",
                         "MSC.137(76) 5.3.1.3.2"),
        )
    if switch_deg == 20.0:
        return (ImoCriterion("first overshoot, 20°/20° zig-zag", first_deg, 25.0, "deg",
                             "MSC.137(76) 5.3.1.3.3"),)
    return ()


def zigzag(params: VesselParams, *, switch_deg: float = 10.0, yaw_fraction: float = 1.0,
           surge_fraction: float = 1.0, n_switches: int = 5, dt_s: float | None = None,
           psi0_rad: float = 0.0) -> ManoeuvreResult:
    """Zig-zag: yaw moment ±``yaw_fraction``·τ_r,max, reversed when the heading passes
    ±``switch_deg``. Metrics: first and second overshoot angles [deg], the initial
    turning time and the distance run to the first switch (in ship lengths), the period
    of the first full cycle, and ``swing_checked`` (1 or 0). Criteria: the MSC.137(76)
    limits for the 10°/10° and 20°/20° zig-zags (none for other switch angles).

    CyberShip II's published coefficients make it course-unstable above about 0.35 m/s
    (60 % of top speed): its Munk moment (M22 − M11)·u·v outgrows the largest yaw moment
    once it turns, and a reversed moment no longer checks the swing. The run then ends
    after ~200 ship lengths with NaN overshoots and ``swing_checked = 0``; ``notes`` says
    so for each NaN.
    """
    _check_fraction("surge_fraction", surge_fraction)
    _check_fraction("yaw_fraction", yaw_fraction)
    check_range(switch_deg, "switch_deg (IMO uses 10 and 20)", 0.0, 90.0, lo_open=True,
                hi_open=True, unit="deg")
    F, U0 = _approach(params, surge_fraction)
    N_max = yaw_fraction * params.actuators.tau_max[2]
    dt = _time_step(params, dt_s, U0)
    x0 = np.array([0.0, 0.0, 0.0, U0, 0.0, 0.0])
    sim = VesselSimulator(params, x0, dt_s=dt)
    sim.batch.reset(x0[None], tau0=[[F, 0.0, 0.0]])
    sw = math.radians(switch_deg)
    sign = 1.0
    switch_k: list[int] = []
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
            switch_k.append(k)
            tracking_peak = True
        rows.append(sim.step([F, 0.0, sign * N_max]))
        taus.append(sim.thrust)
        k += 1
        if tracking_peak and rows[-1][5] * rows[-2][5] <= 0.0:  # yaw rate changes sign
            peaks.append(abs(rows[-1][2]) - sw)
            tracking_peak = False
    xs, tau = np.array(rows), np.array(taus)
    _check_bounded(params, xs, dt)
    t = np.arange(len(xs)) * dt
    run_m = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xs[:, :2], axis=0).T))])
    L = params.length
    notes: dict[str, str] = {}
    unchecked = (f"the reversed yaw moment never checked the swing within "
                 f"{k_max * dt:.0f} s (~200 ship lengths): {params.name} is course-unstable "
                 f"at {U0:.3g} m/s with this yaw moment (see docs/vessel.md); try a "
                 f"smaller surge fraction")
    if not switch_k:
        notes["initial_turning_time_s"] = (f"the heading never reached {switch_deg:g}° "
                                           f"within {k_max * dt:.0f} s")
    for i, key in enumerate(("first_overshoot_deg", "second_overshoot_deg")):
        if len(peaks) <= i:
            notes[key] = unchecked if switch_k else notes["initial_turning_time_s"]
    if len(switch_k) < 3:
        notes["period_s"] = (unchecked if switch_k else
                             notes["initial_turning_time_s"])
    peaks += [math.nan] * (2 - len(peaks))
    m = {
        "approach_speed_m_s": U0,
        # 0 when the reversed yaw moment never checked the swing: the vessel is
        # course-unstable at this speed and ends in a steady turn (see docs/vessel.md)
        "swing_checked": float(not math.isnan(peaks[1])),
        "first_overshoot_deg": math.degrees(peaks[0]),
        "second_overshoot_deg": math.degrees(peaks[1]),
        "initial_turning_time_s": switch_k[0] * dt if switch_k else math.nan,
        "initial_turning_distance_L": float(run_m[switch_k[0]]) / L if switch_k else math.nan,
        "period_s": (switch_k[2] - switch_k[0]) * dt if len(switch_k) >= 3 else math.nan,
        "L_over_V_s": L / U0,
    }
    if "initial_turning_time_s" in notes:
        notes["initial_turning_distance_L"] = notes["initial_turning_time_s"]
    criteria = _zigzag_criteria(float(switch_deg), L / U0, m["initial_turning_distance_L"],
                                m["first_overshoot_deg"], m["second_overshoot_deg"])
    return ManoeuvreResult(f"zigzag_{switch_deg:g}", params.name, t, _rotated(xs, psi0_rad),
                           tau, m, notes=notes, criteria=criteria)


def thrust_step(params: VesselParams, *, surge_fraction: float = 1.0,
                duration_s: float | None = None, dt_s: float | None = None,
                psi0_rad: float = 0.0) -> ManoeuvreResult:
    """From rest, a surge thrust step. Metrics: final and analytic steady speed, the time
    to reach 63 % and 95 % of it, distance run."""
    _check_fraction("surge_fraction", surge_fraction)
    F, U = _approach(params, surge_fraction)
    dt = _time_step(params, dt_s, U)
    if duration_s is not None:
        check_positive(duration_s, "duration_s [s]")
    M11 = params.M[0, 0]
    # linearised time constant M11 / d11'(U) sets a sensible duration
    slope = -params.X_u - 2 * params.X_uu * U - 3 * params.X_uuu * U * U
    T = duration_s or max(10.0 * M11 / slope, 20 * dt)
    n = math.ceil(T / dt)
    t, xs, tau = _run(params, np.zeros(6), dt, n, lambda _t, _x: (F, 0.0, 0.0))
    _check_bounded(params, xs, dt)
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
    "turning_circle": turning_circle,
    "zigzag": zigzag,
    "thrust_step": thrust_step,
}
