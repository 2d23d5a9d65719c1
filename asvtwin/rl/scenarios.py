"""Random training and evaluation scenarios of the predecessors' families (model scale).

A scenario is a smooth random path and the obstacles around it (Meyer et al. 2020,
gym-auv; used with CyberShip II by Vaaler et al. 2023):

- the path: a PCHIP curve through a few waypoints perturbed sideways, about
  ``path_length_m`` long, resampled to ``N_PATH`` points at equal arc length;
- ``"static"``: 8 circles, radius ~ Poisson(25) m, placed at a random point of the path
  and displaced sideways by N(0, 100²) m, at least 100 m from the start and the goal;
- ``"moving"``: 5 such circles and 5 moving circles (radius half a width ~ Poisson(15) m)
  on straight lines at 0.06–2 m/s (mean about 0.54 m/s), each aimed to cross the path
  at a random point between half and twice the time the own ship, at 80 % of its top
  speed, needs to get there (else they rarely meet it; always on time, they made
  following the path at speed a sure collision).

Every draw comes from the ``Generator`` passed in.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import PchipInterpolator

from asvtwin.checks import F8 as _F8

__all__ = ["N_MOVING", "N_PATH", "N_STATIC", "Scenario", "random_path", "random_scenario"]


#: Points of every path polyline (equal arc-length spacing).
N_PATH = 256
#: Obstacle slots: static circles and moving circles per scenario.
N_STATIC = 8
N_MOVING = 5


@dataclass(frozen=True)
class Scenario:
    """One episode's world.

    Attributes
    ----------
    path : ndarray, shape (N_PATH, 2)
        The path [m], NED, from the start to the goal.
    static : ndarray, shape (N_STATIC, 3)
        Static circles ``[north, east, radius]`` [m]; radius 0 marks an unused slot.
    moving : ndarray, shape (N_MOVING, 5)
        Moving circles ``[north, east, v_north, v_east, radius]`` [m, m/s] at t = 0.
    x0 : ndarray, shape (6,)
        Own ship's initial state.
    """

    path: _F8
    static: _F8
    moving: _F8
    x0: _F8


def random_path(rng: np.random.Generator, length_m: float) -> _F8:
    """A smooth random path from the origin, (N_PATH, 2) at equal arc length [m]."""
    n_wp = int(rng.integers(3, 6))
    direction = rng.uniform(-np.pi, np.pi)
    along = np.linspace(0.0, length_m, n_wp + 1)
    side = rng.normal(0.0, 0.1 * length_m, n_wp + 1)
    side[0] = 0.0
    c, s = np.cos(direction), np.sin(direction)
    wp = np.column_stack([along * c - side * s, along * s + side * c])
    k = np.arange(n_wp + 1, dtype=float)
    fine = np.linspace(0.0, n_wp, 2000)
    curve = np.column_stack([PchipInterpolator(k, wp[:, 0])(fine),
                             PchipInterpolator(k, wp[:, 1])(fine)])
    seg = np.hypot(*np.diff(curve, axis=0).T)
    s_cum = np.concatenate([[0.0], np.cumsum(seg)])
    s_new = np.linspace(0.0, s_cum[-1], N_PATH)
    return np.column_stack([np.interp(s_new, s_cum, curve[:, 0]),
                            np.interp(s_new, s_cum, curve[:, 1])])


def _arc(path: _F8) -> _F8:
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))])


def _at(path: _F8, s_cum: _F8, s: float) -> tuple[_F8, float]:
    j = int(np.clip(np.searchsorted(s_cum, s) - 1, 0, len(path) - 2))
    e = path[j + 1] - path[j]
    f = (s - s_cum[j]) / max(s_cum[j + 1] - s_cum[j], 1e-12)
    return path[j] + np.clip(f, 0, 1) * e, float(np.arctan2(e[1], e[0]))


def random_scenario(rng: np.random.Generator, family: str, *, length_m: float = 500.0,
                    U_max: float = 0.57) -> Scenario:
    """Draw one scenario of ``family`` (``"static"``, ``"moving"`` or ``"mixed"``).

    ``U_max`` (own ship's top speed [m/s]) times the moving obstacles' meeting points.
    """
    if family == "mixed":
        family = "static" if rng.random() < 0.5 else "moving"
    path = random_path(rng, length_m)
    s_cum = _arc(path)
    total = s_cum[-1]
    start, goal = path[0], path[-1]
    n_static = N_STATIC if family == "static" else 5
    static = np.zeros((N_STATIC, 3))
    for i in range(n_static):
        for _ in range(100):  # redraw until clear of the start and the goal
            p, chi = _at(path, s_cum, rng.uniform(0.0, total))
            offset = rng.normal(0.0, 100.0)
            c = p + offset * np.array([-np.sin(chi), np.cos(chi)])
            r = float(max(rng.poisson(25.0), 1))
            if min(np.hypot(*(c - start)), np.hypot(*(c - goal))) - r >= 100.0:
                static[i] = (c[0], c[1], r)
                break
    moving = np.zeros((N_MOVING, 5))
    if family == "moving":
        for i in range(N_MOVING):
            s_meet = rng.uniform(0.2, 0.9) * total
            p, _ = _at(path, s_cum, s_meet)
            t_meet = s_meet / (0.8 * U_max) * rng.uniform(0.5, 2.0)
            speed = float(np.clip(0.06 + rng.exponential(0.48), 0.06, 2.0))
            course = rng.uniform(-np.pi, np.pi)
            v = speed * np.array([np.cos(course), np.sin(course)])
            r = 0.5 * float(max(rng.poisson(15.0), 2))
            c0 = p - v * t_meet
            if np.hypot(*(c0 - start)) - r < 30.0:  # never on top of the own ship
                c0 = c0 + (30.0 + r) * v / speed
            moving[i] = (c0[0], c0[1], v[0], v[1], r)
    chi0 = float(np.arctan2(*(path[1] - path[0])[::-1]))
    x0 = np.array([start[0], start[1], chi0 + rng.normal(0.0, 0.1),
                   rng.uniform(0.3, 0.8) * U_max, 0.0, 0.0])
    return Scenario(path=path, static=static, moving=moving, x0=x0)
