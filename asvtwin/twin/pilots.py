"""How the simulated targets steer: behaviours turned into thrust, all targets at once.

Every target has a course and speed reference from its behaviour and one batched
:class:`~asvtwin.guidance.HeadingSpeedAutopilot` (per-vessel parameters and gains) turns
them into thrust:

- ``constant_velocity`` — hold the start heading and speed;
- ``waypoints`` — line-of-sight guidance along the route (:func:`asvtwin.guidance.los_steer`
  on each target's active leg; legs switch inside the circle of acceptance of two ship
  lengths or past its end; ``loop`` starts again at the first waypoint, otherwise the last
  course is held);
- ``colreg`` — a simple rule-following vessel (COLREG rules 14-17): it computes the CPA and
  TCPA to the own ship; when they close within ``cpa_limit`` (6 of its lengths) inside
  ``tcpa_limit`` (10 minutes at 88 m, Froude-scaled), a *give-way* vessel (``give_way``,
  or ``auto`` with the own ship on its starboard side from dead ahead to 112.5°, or
  head-on) turns 40° to starboard until the CPA has passed; a *stand-on* vessel holds
  course and speed (rule 17). Then it resumes its route, if any, else its course.
"""

from __future__ import annotations

import math
from dataclasses import fields
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.geo import LocalFrame
from asvtwin.guidance import AutopilotGains, HeadingSpeedAutopilot, los_steer
from asvtwin.scenarios import TargetSpec
from asvtwin.units import KNOT_M_S
from asvtwin.vessel import VesselParams

__all__ = ["TargetPilots"]

_GIVE_WAY_TURN_RAD = math.radians(40.0)
_KIND = {"constant_velocity": 0, "waypoints": 1, "colreg": 2}
_ROLE = {"stand_on": 0, "give_way": 1, "auto": 2}


def _stack_gains(gains: list[AutopilotGains]) -> AutopilotGains:
    vals: dict[str, Any] = {}
    for f in fields(AutopilotGains):
        if f.name == "crab_compensation":
            vals[f.name] = gains[0].crab_compensation
        else:
            vals[f.name] = np.array([float(getattr(g, f.name)) for g in gains])
    return AutopilotGains(**vals)


@njit(cache=True)
def _los_course(pn, pe, an, ae, bn, be, lookahead):  # type: ignore[no-untyped-def]
    """:func:`asvtwin.guidance.los_steer` of one craft (constant lookahead): course, along
    and leg length, the same operations in the same order."""
    dn, de = bn - an, be - ae
    pi_p = math.atan2(de, dn)
    rn, re = pn - an, pe - ae
    c, s = math.cos(pi_p), math.sin(pi_p)
    along = rn * c + re * s
    cte = -rn * s + re * c
    delta = max(lookahead, abs(cte) * 0.0)
    chi = pi_p + math.atan(-cte / delta)
    chi = math.atan2(math.sin(chi), math.cos(chi))  # np.angle(np.exp(1j * chi))
    return chi, along, math.hypot(dn, de)


@njit(cache=True)
def _route_course_kernel(x, routes, n_wp, k, loop, length, course, out, has):  # type: ignore[no-untyped-def]
    """Per target, what :meth:`TargetPilots._route_course_numpy` does for all at once: up
    to three leg switches (inside two lengths of the leg's end or past it; ``loop`` back
    to the first leg; the last leg's course held at the route's end), then the LOS course
    on the leg reached, or the held course without a route. Updates ``k`` and
    ``course``; writes ``out`` and ``has``."""
    for i in range(x.shape[0]):
        h = n_wp[i] >= 2 and k[i] < n_wp[i]
        R = 2.0 * length[i]
        look = 2.5 * length[i]
        settled = False
        for _ in range(3):
            if not h:
                break
            kk = min(k[i], n_wp[i] - 1)
            an, ae = routes[i, kk - 1, 0], routes[i, kk - 1, 1]
            bn, be = routes[i, kk, 0], routes[i, kk, 1]
            chi, along, leg = _los_course(x[i, 0], x[i, 1], an, ae, bn, be, look)
            dist = math.hypot(bn - x[i, 0], be - x[i, 1])
            if not (dist <= R or along >= leg - R):
                out[i] = chi
                settled = True
                break
            k[i] += 1
            if loop[i] and k[i] >= n_wp[i]:
                k[i] = 1
            if k[i] >= n_wp[i]:  # hold the course of the last leg
                course[i] = math.atan2(be - ae, bn - an)
            h = n_wp[i] >= 2 and k[i] < n_wp[i]
        has[i] = h
        if settled:
            continue
        if not h:
            out[i] = course[i]
            continue
        # still switching after three legs: steer on the leg reached
        kk = min(k[i], n_wp[i] - 1)
        j = max(kk - 1, 0)
        chi, _, _ = _los_course(x[i, 0], x[i, 1], routes[i, j, 0], routes[i, j, 1],
                                routes[i, kk, 0], routes[i, kk, 1], look)
        out[i] = chi


class TargetPilots:
    """Course/speed references and thrust of every target (see the module docstring)."""

    def __init__(self, frame: LocalFrame) -> None:
        self.frame = frame
        self.params: list[VesselParams] = []
        self._gains: list[AutopilotGains] = []
        self._ap: HeadingSpeedAutopilot | None = None
        self.kind = np.zeros(0, np.int64)
        self.role = np.zeros(0, np.int64)
        self.loop = np.zeros(0, bool)
        self.speed = np.zeros(0)
        self.course = np.zeros(0)
        self.length = np.zeros(0)
        self.routes = np.zeros((0, 1, 2))
        self.n_wp = np.zeros(0, np.int64)
        self.k = np.zeros(0, np.int64)
        self.giving_way = np.zeros(0, bool)
        self._turned = np.zeros(0)

    def add(self, spec: TargetSpec, params: VesselParams, x0: _F8) -> None:
        """Append one target (its behaviour, start state ``x0`` (6,))."""
        b = spec.behaviour
        kind = _KIND[b.kind]
        route = [x0[:2]] + [p.to_ned(self.frame) for p in getattr(b, "route", [])]
        r = np.asarray(route, dtype=float)
        kmax = max(self.routes.shape[1], r.shape[0])
        pad = np.zeros((len(self.kind) + 1, kmax, 2))
        pad[:-1, : self.routes.shape[1]] = self.routes
        pad[-1, : r.shape[0]] = r
        self.routes = pad
        self.n_wp = np.append(self.n_wp, r.shape[0])
        self.k = np.append(self.k, 1)
        self.kind = np.append(self.kind, kind)
        self.role = np.append(self.role, _ROLE.get(getattr(b, "role", "stand_on"), 0))
        self.loop = np.append(self.loop, bool(getattr(b, "loop", False)))
        self.speed = np.append(self.speed, spec.speed_kn * KNOT_M_S)
        self.course = np.append(self.course, math.radians(spec.heading_deg))
        self.length = np.append(self.length, spec.length_m)
        self.giving_way = np.append(self.giving_way, False)
        self._turned = np.append(self._turned, 0.0)
        self.params.append(params)
        self._gains.append(AutopilotGains.for_vessel(params))
        self._ap = None

    def _autopilot(self) -> HeadingSpeedAutopilot:
        if self._ap is None:
            self._ap = HeadingSpeedAutopilot(self.params, _stack_gains(self._gains))
        return self._ap

    def _route_course(self, x: _F8) -> tuple[_F8, NDArray[np.bool_]]:
        """LOS course of every target with a route left to follow; and which have one.

        One compiled pass over the targets (:func:`_route_course_kernel`); the NumPy
        version (:meth:`_route_course_numpy`) is kept as its reference, equal to the bit
        (``tests/twin/test_pilots.py``)."""
        out = np.empty(len(self.kind))
        has = np.empty(len(self.kind), np.bool_)
        _route_course_kernel(np.ascontiguousarray(x, dtype=np.float64), self.routes,
                             self.n_wp, self.k, self.loop, self.length, self.course, out, has)
        return out, has

    def _route_course_numpy(self, x: _F8) -> tuple[_F8, NDArray[np.bool_]]:
        """The reference of :meth:`_route_course`, vectorised with NumPy."""
        n = len(self.kind)
        has = (self.n_wp >= 2) & (self.k < self.n_wp)
        if not has.any():
            return self.course.copy(), has
        rows = np.arange(n)
        R = 2.0 * self.length
        for _ in range(3):  # leg switching (a few legs per step at most)
            kk = np.minimum(self.k, self.n_wp - 1)
            a, b = self.routes[rows, kk - 1], self.routes[rows, kk]
            chi, _, along, leg = los_steer(x[:, :2], a, b, 2.5 * self.length)
            dist = np.hypot(b[:, 0] - x[:, 0], b[:, 1] - x[:, 1])
            switch = has & ((dist <= R) | (along >= leg - R))
            if not switch.any():  # the legs are settled: chi is the course on them
                return np.where(has, chi, self.course), has
            self.k[switch] += 1
            wrap = switch & self.loop & (self.k >= self.n_wp)
            self.k[wrap] = 1
            ended = switch & (self.k >= self.n_wp)
            if ended.any():  # hold the course of the last leg
                d = b[ended] - a[ended]
                self.course[ended] = np.arctan2(d[:, 1], d[:, 0])
            has = (self.n_wp >= 2) & (self.k < self.n_wp)
        # still switching after three legs: steer on the legs reached
        kk = np.minimum(self.k, self.n_wp - 1)
        chi, _, _, _ = los_steer(x[:, :2], self.routes[rows, np.maximum(kk - 1, 0)],
                                 self.routes[rows, kk], 2.5 * self.length)
        return np.where(has, chi, self.course), has

    def _colreg(self, x: _F8, own: _F8, course: _F8) -> _F8:
        c = self.kind == 2
        if not c.any():
            return course
        # velocities over ground (η̇ = R(ψ)ν), relative geometry to the own ship
        def vel(s: _F8) -> _F8:
            cs, sn = np.cos(s[..., 2]), np.sin(s[..., 2])
            return np.stack([cs * s[..., 3] - sn * s[..., 4], sn * s[..., 3] + cs * s[..., 4]], -1)
        dp = own[None, :2] - x[:, :2]
        dv = vel(own[None])[0][None] - vel(x)
        vv = np.maximum(np.sum(dv * dv, axis=1), 1e-9)
        tcpa = -np.sum(dp * dv, axis=1) / vv
        cpa = np.hypot(*(dp + tcpa[:, None] * dv).T)
        bearing = np.arctan2(dp[:, 1], dp[:, 0])
        rel = np.remainder(bearing - x[:, 2] + np.pi, 2 * np.pi) - np.pi
        aspect = np.remainder(own[2] - x[:, 2] + np.pi, 2 * np.pi) - np.pi
        head_on = (np.abs(rel) < math.radians(10)) & (np.abs(np.abs(aspect) - np.pi) < math.radians(15))
        starboard = (rel > 0) & (rel < math.radians(112.5))
        give = (self.role == 1) | ((self.role == 2) & (head_on | starboard))
        scale = np.sqrt(self.length / 87.85)
        risk = (cpa < 6.0 * self.length) & (tcpa > 0) & (tcpa < 600.0 * scale)
        start = c & give & risk & ~self.giving_way
        self.giving_way[start] = True
        self._turned[start] = x[start, 2] + _GIVE_WAY_TURN_RAD
        self.giving_way &= ~(c & (tcpa <= 0))  # the CPA has passed: resume
        return np.where(self.giving_way, self._turned, course)

    def tau(self, t_s: float, x: _F8, own: _F8) -> _F8:
        """Thrust (n, 3) [N, N, Nm] of the targets at states ``x`` (n, 6)."""
        course, _ = self._route_course(x)
        course = self._colreg(x, own, course)
        return self._autopilot().tau(x, course, self.speed)
