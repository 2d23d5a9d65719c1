"""Guidance: line-of-sight path following and the heading/speed autopilot (one of each).

:class:`LosGuidance` turns a route into a desired course (Fossen 2011, ch. 10,
lookahead-based LOS with cross-track error and acceptance circles); :func:`los_steer` is its
pure batched form. :class:`HeadingSpeedAutopilot` turns a course and a speed into thrust
within the actuator limits. Both take one vessel or ``n`` at once. :class:`GiveWay` adds the
COLREG give-way alteration to the LOS course and hands back to LOS once the other vessel
is passed.
"""

from __future__ import annotations

from asvtwin.guidance.autopilot import AutopilotGains, HeadingSpeedAutopilot
from asvtwin.guidance.give_way import GiveWay, GiveWayStatus
from asvtwin.guidance.los import LosGuidance, LosOutput, los_steer

__all__ = ["AutopilotGains", "GiveWay", "GiveWayStatus", "HeadingSpeedAutopilot", "LosGuidance",
           "LosOutput", "los_steer"]
