"""Lookahead-based line-of-sight (LOS) path following along a chain of waypoints.

After Fossen (2011), *Handbook of Marine Craft Hydrodynamics and Motion Control*, ch. 10.3:
the path is the chain of straight legs between waypoints :math:`p_k = (x_k, y_k)` (NED).
On the leg from :math:`p_k` to :math:`p_{k+1}` with path-tangential angle
:math:`\\pi_p = \\operatorname{atan2}(y_{k+1} - y_k,\\, x_{k+1} - x_k)`, a craft at
:math:`(x, y)` has the along-track distance :math:`s` and the cross-track error :math:`e`

.. math::

    \\begin{bmatrix} s \\\\ e \\end{bmatrix} =
    \\begin{bmatrix} \\cos\\pi_p & \\sin\\pi_p \\\\ -\\sin\\pi_p & \\cos\\pi_p \\end{bmatrix}
    \\begin{bmatrix} x - x_k \\\\ y - y_k \\end{bmatrix}

(:math:`e > 0`: the craft is to starboard of the path, looking along it), and the
lookahead-based steering law with lookahead distance :math:`\\Delta > 0`

.. math::

    \\chi_d = \\pi_p + \\chi_r(e), \\qquad \\chi_r(e) = \\arctan(-e / \\Delta)

drives :math:`e \\to 0` for a craft that follows :math:`\\chi_d` (the origin of the
cross-track dynamics :math:`\\dot e = U \\sin(\\chi - \\pi_p)` is uniformly globally
asymptotically stable for :math:`U > 0`). Small :math:`\\Delta` steers aggressively, large
:math:`\\Delta` gently.

Bounded intercept angle (optional, ``max_intercept_rad`` = :math:`\\chi_{max}`): the
lookahead grows with the cross-track error, a time-varying lookahead in Fossen's sense
(Fossen 2021, 2nd ed., ch. 12; Lekkas and Fossen 2012 vary it the other way, to converge
faster),

.. math::

    \\Delta(e) = \\max(\\Delta,\\; |e| / \\tan\\chi_{max})
    \\quad\\Rightarrow\\quad |\\chi_r(e)| \\le \\chi_{max},

so a craft far off its path returns at no more than :math:`\\chi_{max}` to it (and makes
headway along it) instead of nearly square to it; near the path (:math:`|e| \\le \\Delta
\\tan\\chi_{max}`) the law is the constant-lookahead one. :math:`\\chi_r` keeps the sign of
:math:`-e`, so :math:`\\dot e = U \\sin\\chi_r` still drives :math:`e \\to 0`.

Waypoint switching: the craft moves on to the next leg when it enters the circle of
acceptance of radius :math:`R` around :math:`p_{k+1}`,
:math:`(x_{k+1} - x)^2 + (y_{k+1} - y)^2 \\le R^2`, or (Fossen's alternative, which also
catches a craft that misses the circle) when its along-track distance passes
:math:`\\lVert p_{k+1} - p_k \\rVert - R`. Fossen's alternative ignores the cross-track
error: a craft pushed far off the leg (by an avoidance manoeuvre) would skip it while
still far from it. With ``switch_cte_m`` the along-track test only counts while
:math:`|e| <` ``switch_cte_m``, or while the next leg (as a segment) is no farther from
the craft than :math:`|e|` (a craft pushed round the far side of the next waypoint heads
for the next leg rather than back to the one it passed); otherwise the craft keeps
steering to its leg (extended beyond its end when it is past it) and switches once it is
near it or inside the circle. After the last waypoint the output is ``done``.

Everything is batched: ``n`` craft on the same route each keep their own leg index.
:func:`los_steer` is the pure, stateless form for craft on different legs (the synthetic
traffic).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.errors import ParameterError, StateError
from asvtwin.guidance.kernels import los_kernel

__all__ = ["LosGuidance", "LosOutput", "los_steer"]

_I8 = NDArray[np.int64]


def los_steer(
    position: ArrayLike, wp_from: ArrayLike, wp_to: ArrayLike, lookahead_m: ArrayLike,
    max_intercept_rad: float | None = None,
) -> tuple[_F8, _F8, _F8, _F8]:
    """Lookahead-based LOS course for craft on given legs (pure, batched).

    Parameters
    ----------
    position : array_like, shape (n, 2) or (2,)
        Craft positions ``[north, east]`` [m], NED.
    wp_from, wp_to : array_like, shape (n, 2) or (2,)
        Start and end of each craft's leg [m], NED (broadcast against ``position``).
    lookahead_m : array_like, shape (n,) or scalar
        Lookahead distance Δ [m], > 0.
    max_intercept_rad : float, optional
        Bound χ_max on the intercept angle, in (0, π/2): Δ(e) = max(Δ, |e| / tan χ_max).
        None: constant Δ.

    Returns
    -------
    course_rad : ndarray (n,)
        Desired course χ_d = π_p + arctan(−e/Δ(e)) [rad], in (−π, π].
    cte_m : ndarray (n,)
        Cross-track error e [m], positive to starboard of the path.
    along_m : ndarray (n,)
        Along-track distance s from ``wp_from`` [m].
    leg_m : ndarray (n,)
        Leg length [m].
    """
    p = np.atleast_2d(np.asarray(position, dtype=np.float64))
    a = np.atleast_2d(np.asarray(wp_from, dtype=np.float64))
    b = np.atleast_2d(np.asarray(wp_to, dtype=np.float64))
    d = b - a
    pi_p = np.arctan2(d[:, 1], d[:, 0])  # path-tangential angle
    rel = p - a
    c, s = np.cos(pi_p), np.sin(pi_p)
    along = rel[:, 0] * c + rel[:, 1] * s  # s = (x - x_k) cos π_p + (y - y_k) sin π_p
    cte = -rel[:, 0] * s + rel[:, 1] * c  # e = -(x - x_k) sin π_p + (y - y_k) cos π_p
    delta = np.maximum(np.asarray(lookahead_m, dtype=np.float64),
                       np.abs(cte) * _cot_max(max_intercept_rad))  # Δ(e)
    chi_d = pi_p + np.arctan(-cte / delta)  # χ_d = π_p + χ_r
    chi_d = np.angle(np.exp(1j * chi_d))  # wrap to (-π, π]
    return chi_d, cte, along, np.hypot(d[:, 0], d[:, 1])


def _cot_max(max_intercept_rad: float | None) -> float:
    """1 / tan χ_max (0 for no bound), checking χ_max in (0, π/2)."""
    if max_intercept_rad is None:
        return 0.0
    v = max_intercept_rad
    if not (isinstance(v, int | float) and 0.0 < v < math.pi / 2):
        raise ParameterError(f"max_intercept_rad must be in (0, pi/2) [rad] or None, "
                             f"actually: {v!r}")
    return 1.0 / math.tan(v)


@dataclass(frozen=True)
class LosOutput:
    """One guidance step for ``n`` craft (arrays of shape (n,), or scalars for one craft).

    Attributes
    ----------
    course_rad : desired course χ_d [rad], NED, clockwise from north.
    cte_m : cross-track error e [m], positive when the craft is to starboard of the leg.
    waypoint_index : index of the waypoint steered to (the end of the active leg); equals
        the number of waypoints once done.
    done : True once the last waypoint has been reached.
    """

    course_rad: _F8 | float
    cte_m: _F8 | float
    waypoint_index: _I8 | int
    done: NDArray[np.bool_] | bool


class LosGuidance:
    """LOS guidance along a fixed chain of waypoints, for one or ``n`` craft.

    Parameters
    ----------
    waypoints : array_like, shape (k, 2)
        Route ``[north, east]`` [m], NED, k >= 1. With k >= 2 the first leg runs from
        ``waypoints[0]`` to ``waypoints[1]`` (put the start position first). With k = 1 the
        single leg runs from where each craft is at its first :meth:`step` to the waypoint.
    lookahead_m : float
        Lookahead distance Δ [m], > 0 (Fossen suggests 1.5-2.5 ship lengths).
    acceptance_radius_m : float
        Radius R of the circle of acceptance [m], > 0 (about 2 ship lengths).
    max_intercept_rad : float, optional
        Bound χ_max on the angle at which a craft off its leg steers back to it, in
        (0, π/2): the lookahead grows to |e| / tan χ_max (see the module docstring).
        None (default): constant lookahead.
    switch_cte_m : float, optional
        The along-track switching test only counts while the cross-track error is below
        this [m] (> 0; e.g. ``acceptance_radius_m``) or the next leg is no farther than
        the cross-track error. None (default): Fossen's alternative as is, at any
        cross-track error.

    Examples
    --------
    A craft 10 m to port of a northbound leg steers back to starboard:

    >>> import numpy as np
    >>> los = LosGuidance([[0.0, 0.0], [100.0, 0.0]], lookahead_m=10.0, acceptance_radius_m=5.0)
    >>> out = los.step(np.array([50.0, -10.0]))
    >>> round(float(out.cte_m), 6), round(float(np.degrees(out.course_rad)), 6)
    (-10.0, 45.0)
    """

    def __init__(self, waypoints: ArrayLike, *, lookahead_m: float,
                 acceptance_radius_m: float, max_intercept_rad: float | None = None,
                 switch_cte_m: float | None = None) -> None:
        w = np.asarray(waypoints, dtype=np.float64)
        if w.ndim != 2 or w.shape[1] != 2 or w.shape[0] < 1 or not np.isfinite(w).all():
            raise ParameterError(
                f"waypoints must be a finite (k, 2) array [m] with k >= 1, actually shape "
                f"{w.shape}"
            )
        for name, v in (("lookahead_m", lookahead_m), ("acceptance_radius_m",
                                                       acceptance_radius_m),
                        ("switch_cte_m", 1.0 if switch_cte_m is None else switch_cte_m)):
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise ParameterError(f"{name} must be finite and > 0 [m], actually: {v!r}")
        self._cot_max = _cot_max(max_intercept_rad)
        self.max_intercept_rad = max_intercept_rad
        self.switch_cte_m = switch_cte_m
        self.waypoints = w.copy()
        self.waypoints.flags.writeable = False
        self.lookahead_m = float(lookahead_m)
        self.acceptance_radius_m = float(acceptance_radius_m)
        self._k: _I8 | None = None  # per craft: index of the waypoint steered to
        self._origin: _F8 | None = None  # per craft: leg start for a one-waypoint route

    def reset(self) -> None:
        """Forget every craft's progress (the next :meth:`step` starts on the first leg)."""
        self._k = None
        self._origin = None

    @property
    def waypoint_index(self) -> _I8 | None:
        """Per craft, the index of the waypoint steered to (None before the first step)."""
        return None if self._k is None else self._k.copy()

    def step(self, position: ArrayLike) -> LosOutput:
        """Advance the waypoint logic and compute the desired course.

        Parameters
        ----------
        position : array_like, shape (2,) or (n, 2)
            Craft positions ``[north, east]`` [m], NED. ``n`` must stay the same between
            calls (until :meth:`reset`).

        Returns
        -------
        LosOutput
            Scalars for a (2,) input, arrays of shape (n,) for an (n, 2) input.
        """
        p_in = np.asarray(position, dtype=np.float64)
        single = p_in.ndim == 1
        p = np.ascontiguousarray(p_in.reshape(1, -1) if single else p_in)
        if p.ndim != 2 or p.shape[1] != 2:
            raise StateError(f"position must have shape (2,) or (n, 2) [m], actually shape "
                             f"{p_in.shape}")
        n = p.shape[0]
        w = self.waypoints
        k_wp = w.shape[0]
        if self._k is None:
            if not np.isfinite(p).all():
                raise StateError(f"position must be finite [m], actually: {p_in!r}")
            self._k = np.full(n, 1 if k_wp >= 2 else 0, dtype=np.int64)
            self._origin = p.copy()
        elif self._k.shape[0] != n:
            raise StateError(f"position holds {n} craft but this guidance tracks "
                             f"{self._k.shape[0]}; call reset() first")
        assert self._origin is not None
        chi = np.empty(n)
        cte = np.empty(n)
        if not los_kernel(p, w, self._origin, self._k, self.lookahead_m,
                          self.acceptance_radius_m, chi, cte, self._cot_max,
                          math.inf if self.switch_cte_m is None else self.switch_cte_m):
            raise StateError(f"position must be finite [m], actually: {p_in!r}")
        k = self._k
        done = k >= k_wp
        if single:
            return LosOutput(float(chi[0]), float(cte[0]), int(k[0]), bool(done[0]))
        return LosOutput(chi, cte, k.copy(), done)
