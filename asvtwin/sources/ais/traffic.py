"""Other ships in the Trondheim Fjord, simulated with the project's vessel model.

The embedded default of the descriptive twin needs traffic when no live feed is configured.
:class:`FjordTraffic` steps a handful of vessels (:func:`default_fleet`: two ferries, a coastal
passenger ship, a fishing boat, a leisure craft) along plausible routes with
:class:`asvtwin.vessel.BatchSimulator`: each is CyberShip II Froude-scaled to its length
(:func:`asvtwin.vessel.froude_scale`), steered by line-of-sight guidance and a PD heading
controller, with a feed-forward + proportional speed controller, all vectorised over the
vessels. :mod:`asvtwin.sources.ais.synthetic` turns the states into NMEA.

Line-of-sight guidance is :func:`asvtwin.guidance.los_steer` (Fossen 2011, ch. 10; look-ahead
4 L + 50 m) on each vessel's current leg; heading and speed are held by the project's one
:class:`asvtwin.guidance.HeadingSpeedAutopilot` with the rate-limited cascade
(:math:`r_d = \\mathrm{sat}_{r_{max}}(\\omega_n \\tilde\\psi)`,
:math:`\\tau_r = 20\\omega_n I (r_d - r) - N_r r_d`, :math:`I = I_z - N_{\\dot r}`) and
:math:`\\tau_u = d(u_d) + k_u (u_d - u)`, saturated to each vessel's actuator limits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.errors import ParameterError
from asvtwin.geo import Scene, default_scene
from asvtwin.guidance import AutopilotGains, HeadingSpeedAutopilot, los_steer
from asvtwin.units import wrap_angle
from asvtwin.vessel import BatchSimulator, cybership2, froude_scale
from asvtwin.vessel.params import RHO_SEA, ActuatorParams, VesselParams

__all__ = ["FjordTraffic", "TrafficVessel", "default_fleet"]


#: Yaw-moment limit of the traffic vessels relative to CyberShip II's thruster (a rudder).
YAW_MOMENT_FACTOR = 5.0


@dataclass(frozen=True)
class TrafficVessel:
    """One simulated ship: identity, size, speed and route.

    Attributes
    ----------
    mmsi, name, callsign : identity broadcast in the AIS messages.
    ship_type : int
        AIS ship and cargo type (30 fishing, 37 pleasure craft, 60 passenger).
    ais_class : str
        ``"A"`` (types 1/3 and 5) or ``"B"`` (types 18 and 24).
    scale : float
        Froude scale λ of CyberShip II (length 1.255 λ m, top speed about 0.57 √λ m/s).
    cruise_speed_m_s : float
        Service speed [m/s].
    route_latlon : tuple of (lat_deg, lon_deg)
        Waypoints; a closed loop when the last equals the first, otherwise run back and forth.
    dwell_s : tuple of float
        Time moored at the first and at the last waypoint of a back-and-forth route [s].
    start_fraction : float
        Where along the route the vessel starts, as a fraction of its length.
    """

    mmsi: int
    name: str
    callsign: str
    ship_type: int
    ais_class: str
    scale: float
    cruise_speed_m_s: float
    route_latlon: tuple[tuple[float, float], ...]
    dwell_s: tuple[float, float] = (0.0, 0.0)
    start_fraction: float = 0.0

    def __post_init__(self) -> None:
        if self.ais_class not in ("A", "B"):
            raise ParameterError(f"{self.name}: ais_class must be 'A' or 'B', "
                                 f"actually: {self.ais_class!r}")
        if len(self.route_latlon) < 2:
            raise ParameterError(f"{self.name}: a route needs >= 2 waypoints, "
                                 f"actually: {len(self.route_latlon)}")
        top = 0.57 * math.sqrt(self.scale)
        if not 0 < self.cruise_speed_m_s <= top:
            raise ParameterError(f"{self.name}: cruise_speed_m_s must be in (0, {top:.2f}] for "
                                 f"scale {self.scale}, actually: {self.cruise_speed_m_s}")
        if not 0 <= self.start_fraction < 1:
            raise ParameterError(f"{self.name}: start_fraction must be in [0, 1), "
                                 f"actually: {self.start_fraction}")

    @property
    def closed(self) -> bool:
        """True for a loop route (last waypoint == first)."""
        return self.route_latlon[0] == self.route_latlon[-1]

    def params(self) -> VesselParams:
        """CyberShip II Froude-scaled to this vessel, in sea water, with a rudder-sized yaw moment.

        The hull model is directionally unstable above about half its top speed, and
        CyberShip II's tunnel-thruster yaw moment (0.15 Nm at model scale) cannot hold a turn
        there; a ship's rudder can. The yaw moment limit is therefore ``YAW_MOMENT_FACTOR``
        times the thruster's; everything else is the published model.
        """
        base = cybership2()
        act = base.actuators
        k = YAW_MOMENT_FACTOR
        base = base.replace(actuators=ActuatorParams(
            tau_min=(act.tau_min[0], act.tau_min[1], k * act.tau_min[2]),
            tau_max=(act.tau_max[0], act.tau_max[1], k * act.tau_max[2]),
            time_constant_s=act.time_constant_s))
        return froude_scale(base, self.scale, rho_water=RHO_SEA,
                            name=f"{self.name.lower().replace(' ', '_')}")


def default_fleet() -> tuple[TrafficVessel, ...]:
    """Five vessels on plausible Trondheim Fjord routes (checked against the scene's land).

    MMSIs use the Norwegian MIDs 257-259 in a block not assigned to a real ship's name here;
    names are invented.
    """
    return (
        TrafficVessel(257100100, "FLAKKFERJA", "LFLK", 60, "A", 70.0, 4.1,
                      ((63.4545, 10.2080), (63.4700, 10.2000), (63.4950, 10.1850),
                       (63.5135, 10.1600)), dwell_s=(300.0, 300.0), start_fraction=0.3),
        TrafficVessel(257100200, "FOSENFERGA", "LFSN", 60, "A", 45.0, 3.3,
                      ((63.4430, 10.3950), (63.4520, 10.3700), (63.4900, 10.3200),
                       (63.5300, 10.2600), (63.5510, 10.2410)), dwell_s=(240.0, 240.0),
                      start_fraction=0.6),
        TrafficVessel(258100300, "KYSTRUTEN NORD", "LKYS", 60, "A", 105.0, 5.0,
                      ((63.4470, 10.4000), (63.4580, 10.3950), (63.4700, 10.2500),
                       (63.4780, 10.0500), (63.4840, 9.9600), (63.5100, 9.8900),
                       (63.5500, 9.8750), (63.5750, 9.8350)), dwell_s=(900.0, 0.0),
                      start_fraction=0.1),
        TrafficVessel(259100400, "HAVSULE", "LHAV", 30, "A", 18.0, 2.0,
                      ((63.5050, 10.4500), (63.5250, 10.5200), (63.5150, 10.6000),
                       (63.4950, 10.5300), (63.5050, 10.4500)), start_fraction=0.25),
        TrafficVessel(259100500, "SJOBLIKK", "LM1234", 37, "B", 9.0, 1.5,
                      ((63.4560, 10.3950), (63.4650, 10.3750), (63.4700, 10.4200),
                       (63.4600, 10.4400), (63.4560, 10.3950)), start_fraction=0.5),
    )


class FjordTraffic:
    """The fleet stepped together by the vessel model, guided along its routes.

    Parameters
    ----------
    fleet : sequence of TrafficVessel
        The vessels.
    scene : Scene, optional
        Frame for the routes; the default scene when omitted.
    dt_s : float
        Simulation step [s].
    """

    def __init__(self, fleet: tuple[TrafficVessel, ...] | list[TrafficVessel], *,
                 scene: Scene | None = None, dt_s: float = 0.5) -> None:
        if not fleet:
            raise ParameterError("FjordTraffic needs at least one vessel, actually: none")
        self.fleet = tuple(fleet)
        self.scene = scene if scene is not None else default_scene()
        n = len(self.fleet)
        params = [v.params() for v in self.fleet]
        kmax = max(len(v.route_latlon) for v in self.fleet)
        self._W = np.zeros((n, kmax, 2))
        self._nw = np.array([len(v.route_latlon) for v in self.fleet])
        for i, v in enumerate(self.fleet):
            ll = np.asarray(v.route_latlon, dtype=np.float64)
            north, east = self.scene.frame.to_ned(ll[:, 0], ll[:, 1])
            self._W[i, : len(ll)] = np.column_stack([north, east])
        self._closed = np.array([v.closed for v in self.fleet])
        self._dwell = np.array([v.dwell_s for v in self.fleet], dtype=np.float64)
        self._U = np.array([v.cruise_speed_m_s for v in self.fleet])
        L = np.array([p.length for p in params])
        self._lookahead = 4.0 * L + 50.0
        self._accept = 2.0 * L + 30.0
        self._brake = 40.0 * L
        # heading cascade and speed gains from each vessel's own model
        inertia = np.array([p.I_z - p.N_rdot for p in params])
        wn = 0.35 / np.sqrt(np.array([v.scale for v in self.fleet]))
        self.autopilot = HeadingSpeedAutopilot(params, AutopilotGains(
            k_psi=wn,
            # gentle turns (diameter ~ 6 ship lengths): a hard turn builds up sway, and the
            # model's sway-yaw coupling (N_v, N_vv) then beats the yaw actuator
            r_max_rad_s=self._U / (3.0 * L),
            k_r=20.0 * wn * inertia,
            yaw_feedforward=1.0,
            k_u=np.array([p.m - p.X_udot for p in params])
            / (10.0 * np.sqrt([v.scale for v in self.fleet])),
            speed_feedforward=1.0,
            crab_compensation=False,
        ))
        # start positions along the routes
        self._k = np.ones(n, dtype=np.int64)  # index of the waypoint steered to
        self._dir = np.ones(n, dtype=np.int64)
        self._dwell_until = np.full(n, -np.inf)
        x0 = np.zeros((n, 6))
        for i, v in enumerate(self.fleet):
            p, k, chi = self._along(i, v.start_fraction)
            self._k[i] = k
            x0[i, :3] = (p[0], p[1], chi)
            x0[i, 3] = v.cruise_speed_m_s
        self.sim = BatchSimulator(params, x0, dt_s=dt_s)
        self.nav_status = np.zeros(n, dtype=np.int64)  # 0 under way using engine, 5 moored

    def _along(self, i: int, frac: float) -> tuple[_F8, int, float]:
        """Point at ``frac`` of route i's length, the next waypoint index, the leg angle."""
        W = self._W[i, : self._nw[i]]
        legs = np.linalg.norm(np.diff(W, axis=0), axis=1)
        s = frac * legs.sum()
        k = int(np.searchsorted(np.cumsum(legs), s, side="right"))
        k = min(k, len(legs) - 1)
        s0 = s - (np.cumsum(legs)[k - 1] if k > 0 else 0.0)
        d = W[k + 1] - W[k]
        return W[k] + d * (s0 / legs[k]), k + 1, math.atan2(d[1], d[0])

    @property
    def t_s(self) -> float:
        """Simulation time [s] since the traffic started."""
        return self.sim.t_s

    @property
    def state(self) -> _F8:
        """States (n, 6) ``[north, east, ψ, u, v, r]`` (a copy)."""
        return self.sim.state

    def step(self) -> _F8:
        """Guide, control and advance every vessel by ``dt_s``; return the states (n, 6)."""
        x = self.sim._x  # read-only use of the current state, no copy
        t = self.sim.t_s
        n = len(self.fleet)
        rows = np.arange(n)
        k = self._k
        prev = self._W[rows, k - self._dir]
        nxt = self._W[rows, k]
        chi_d, _, along, leg = los_steer(x[:, :2], prev, nxt, self._lookahead)  # LOS guidance
        dist = np.linalg.norm(nxt - x[:, :2], axis=1)
        last = np.where(self._dir > 0, self._nw - 1, 0)
        terminal = (k == last) & ~self._closed
        # speed: slow down towards a terminal, stop while moored
        u_d = np.where(terminal, self._U * np.clip(dist / self._brake, 0.12, 1.0), self._U)
        moored = t < self._dwell_until
        u_d = np.where(moored, 0.0, u_d)
        arrive = ((dist < self._accept) | (along > leg - self._accept)) & ~moored
        if arrive.any():
            self._advance(np.flatnonzero(arrive), terminal, t)
        tau = self.autopilot.tau(x, chi_d, u_d)
        tau[:, 0] = np.where(moored, 0.0, tau[:, 0])
        self.nav_status = np.where(moored & (np.hypot(x[:, 3], x[:, 4]) < 0.3), 5, 0)
        return self.sim.step(tau)

    def _advance(self, idx: NDArray[np.int64], terminal: NDArray[np.bool_], t: float) -> None:
        """Switch waypoints; at a terminal moor (if it has a dwell) and turn the route round."""
        for i in idx.tolist():
            if terminal[i]:
                end = 1 if self._dir[i] > 0 else 0
                self._dwell_until[i] = t + self._dwell[i, end]
                self._dir[i] = -self._dir[i]
                self._k[i] += self._dir[i]
            elif self._closed[i] and self._k[i] == self._nw[i] - 1:
                self._k[i] = 1
            else:
                self._k[i] += self._dir[i]

    def kinematics(self) -> tuple[_F8, _F8, _F8, _F8, _F8]:
        """Ground truth now: position (n, 2) [m], SOG [m/s], COG [rad], heading [rad], ROT [rad/s].

        COG is the direction of the velocity over ground, ψ plus the sideslip angle.
        """
        x = self.sim._x
        c, s = np.cos(x[:, 2]), np.sin(x[:, 2])
        vn = c * x[:, 3] - s * x[:, 4]  # eq. (η̇ = R(ψ) ν)
        ve = s * x[:, 3] + c * x[:, 4]
        return (x[:, :2].copy(), np.hypot(vn, ve), np.arctan2(ve, vn), np.asarray(wrap_angle(x[:, 2])),
                x[:, 5].copy())
