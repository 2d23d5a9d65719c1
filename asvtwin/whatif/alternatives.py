"""Alternatives a what-if question compares: the own ship's choices and the world's turns.

An :class:`Alternative` says what the own ship does over the horizon (follow its route,
keep its present course and speed, alter course to starboard or port by some degrees,
slow down, stop, or another route) and, for "what if the world does X", what a target or
the wind does (a target turns or speeds up, the wind rises), and whether the safety filter
is in the loop. Own-ship choices are *decisions* the recommendation may pick from; the
world's turns are *hypotheses* reported beside them, never recommended.

Written on the command line as ``NAME[:ARG[:ARG]]`` (:func:`parse_alternative`):

==============================  ==========================================================
``route``                        follow the route (LOS) at cruise speed (the plan)
``keep_course``                  hold the present course and speed (COLREG "stand on")
``starboard:DEG`` / ``port:DEG`` alter course by DEG° [1, 120] from the present course
``slow:FRAC``                    follow the route at FRAC (0, 1) of cruise speed
``stop``                         take all way off (speed reference 0)
``target_turns:ID:DEG``          track ID alters course by DEG° (+ starboard) at once
``target_speeds_up:ID:FACTOR``   track ID goes FACTOR times faster [1, 3]
``wind:SPEED:FROM_DEG``          the wind rises to SPEED m/s from FROM_DEG°
``...+filter_off``               any of the above with the safety filter out of the loop
==============================  ==========================================================
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from asvtwin.errors import ParameterError

__all__ = ["DECISIONS", "Alternative", "default_alternatives", "parse_alternative"]

#: Own-ship manoeuvres (decisions), in order of how little they change the plan.
DECISIONS = ("route", "keep_course", "slow", "starboard", "port", "stop")
_WORLD = ("target_turns", "target_speeds_up", "wind")


@dataclass(frozen=True)
class Alternative:
    """One alternative future (see the module docstring).

    Attributes
    ----------
    kind : str
        One of :data:`DECISIONS` or ``target_turns``, ``target_speeds_up``, ``wind``
        (the own ship then follows its route).
    course_change_rad : float
        Alteration from the present course, + to starboard [rad] (``starboard``/``port``).
    speed_factor : float
        Fraction of the cruise speed (``slow``; 0 for ``stop``).
    target_id : int
        Track number the world-hypothesis is about (−1: none).
    target_course_change_rad, target_speed_factor : float
        What that target does.
    wind_speed_m_s, wind_from_rad : float
        Wind of the ``wind`` hypothesis (NaN otherwise).
    filter : bool
        Safety filter in the loop.
    """

    kind: str = "route"
    course_change_rad: float = 0.0
    speed_factor: float = 1.0
    target_id: int = -1
    target_course_change_rad: float = 0.0
    target_speed_factor: float = 1.0
    wind_speed_m_s: float = float("nan")
    wind_from_rad: float = float("nan")
    filter: bool = True

    @property
    def is_decision(self) -> bool:
        """An own-ship choice the recommendation may pick (not a world hypothesis)."""
        return self.kind in DECISIONS and self.filter

    @property
    def label(self) -> str:
        """Short name, e.g. ``starboard:30`` or ``route+filter_off``."""
        k = self.kind
        if k in ("starboard", "port"):
            s = f"{k}:{abs(math.degrees(self.course_change_rad)):g}"
        elif k == "slow":
            s = f"slow:{self.speed_factor:g}"
        elif k == "target_turns":
            s = f"target_turns:{self.target_id}:{math.degrees(self.target_course_change_rad):g}"
        elif k == "target_speeds_up":
            s = f"target_speeds_up:{self.target_id}:{self.target_speed_factor:g}"
        elif k == "wind":
            s = f"wind:{self.wind_speed_m_s:g}:{math.degrees(self.wind_from_rad):g}"
        else:
            s = k
        return s if self.filter else s + "+filter_off"

    def describe(self) -> str:
        """The alternative in a navigator's words."""
        k = self.kind
        deg = abs(math.degrees(self.course_change_rad))
        text = {
            "route": "follow the planned route",
            "keep_course": "keep course and speed",
            "starboard": f"alter course {deg:g}° to starboard",
            "port": f"alter course {deg:g}° to port",
            "slow": f"reduce speed to {100 * self.speed_factor:g} % of cruise speed",
            "stop": "take all way off",
            "target_turns": f"track {self.target_id} alters course "
                            f"{abs(math.degrees(self.target_course_change_rad)):g}° to "
                            f"{'starboard' if self.target_course_change_rad >= 0 else 'port'}",
            "target_speeds_up": f"track {self.target_id} speeds up "
                                f"{self.target_speed_factor:g} times",
            "wind": f"the wind rises to {self.wind_speed_m_s:g} m/s from "
                    f"{math.degrees(self.wind_from_rad) % 360:03.0f}°",
        }[k]
        return text + ("" if self.filter else ", safety filter off")


def _num(text: str, what: str, lo: float, hi: float, spec: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise ParameterError(f"alternative {spec!r}: {what} must be a number in "
                             f"[{lo:g}, {hi:g}], actually: {text!r}") from None
    if not (math.isfinite(v) and lo <= v <= hi):
        raise ParameterError(f"alternative {spec!r}: {what} must be in [{lo:g}, {hi:g}], "
                             f"actually: {v:g}")
    return v


def parse_alternative(spec: str) -> Alternative:
    """An :class:`Alternative` from ``NAME[:ARG[:ARG]][+filter_off]``.

    Raises
    ------
    ParameterError
        Unknown name, wrong number of arguments, an argument out of its range.

    Examples
    --------
    >>> parse_alternative("starboard:30").label
    'starboard:30'
    >>> parse_alternative("route+filter_off").describe()
    'follow the planned route, safety filter off'
    """
    body, _, mod = spec.strip().partition("+")
    if mod and mod != "filter_off":
        raise ParameterError(f"alternative {spec!r}: the only modifier is '+filter_off', "
                             f"actually: {'+' + mod!r}")
    name, *args = body.split(":")
    want = {"route": 0, "keep_course": 0, "stop": 0, "starboard": 1, "port": 1, "slow": 1,
            "target_turns": 2, "target_speeds_up": 2, "wind": 2}
    if name not in want:
        raise ParameterError(f"alternative {spec!r}: unknown name {name!r}; expected one of "
                             f"{', '.join(want)}")
    if len(args) != want[name]:
        raise ParameterError(f"alternative {spec!r}: {name} takes {want[name]} argument(s) "
                             f"separated by ':', actually: {len(args)}")
    a = Alternative(kind=name, filter=not mod)
    if name in ("starboard", "port"):
        deg = _num(args[0], "the course change [deg]", 1.0, 120.0, spec)
        a = replace(a, course_change_rad=math.radians(deg if name == "starboard" else -deg))
    elif name == "slow":
        a = replace(a, speed_factor=_num(args[0], "the speed fraction", 0.05, 0.95, spec))
    elif name == "stop":
        a = replace(a, speed_factor=0.0)
    elif name in ("target_turns", "target_speeds_up"):
        tid = int(_num(args[0], "the track number", 0, 2**31, spec))
        if name == "target_turns":
            deg = _num(args[1], "the target's course change [deg]", -180.0, 180.0, spec)
            a = replace(a, target_id=tid, target_course_change_rad=math.radians(deg))
        else:
            a = replace(a, target_id=tid,
                        target_speed_factor=_num(args[1], "the speed factor", 1.0, 3.0, spec))
    elif name == "wind":
        a = replace(a, wind_speed_m_s=_num(args[0], "the wind speed [m/s]", 0.0, 60.0, spec),
                    wind_from_rad=math.radians(_num(args[1], "the direction [deg]", 0.0,
                                                    360.0, spec)))
    return a


def default_alternatives() -> tuple[Alternative, ...]:
    """The four alternatives asked by default: follow the route with the filter, the same
    without it, keep course and speed, alter course 30° to starboard."""
    return tuple(parse_alternative(s) for s in
                 ("route", "route+filter_off", "keep_course", "starboard:30"))
