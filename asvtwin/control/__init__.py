"""Control: the predictive safety filter (NMPC), its obstacles, terminal set and fallback.

Examples
--------
>>> from asvtwin.control import SafetyFilter, PsfConfig, CircleObstacles
>>> from asvtwin.vessel import cybership2
>>> psf = SafetyFilter(cybership2(), config=PsfConfig(N=40, backend="casadi-ipopt"))
>>> res = psf.filter([0, 0, 0, 0.3, 0, 0], [2.0, 0, 0],
...                  CircleObstacles(centres=[[30.0, 0.0]], radii=[1.0]), t_s=0.0)
>>> res.fallback, bool(abs(res.delta_u[0]) < 0.01)
('none', True)
"""

from __future__ import annotations

from asvtwin.control.backends import BACKENDS, available_backends
from asvtwin.control.colreg import (
    ENCOUNTER_KINDS,
    EncounterLimits,
    Encounters,
    classify_encounters,
    cpa_tcpa,
)
from asvtwin.control.fallback import BackupPlan, Candidate, Fallback
from asvtwin.control.obstacles import (
    CircleObstacles,
    CoastSegments,
    MovingObstacles,
    Obstacles,
    covariance_inflation,
    lidar_circles,
    obstacle_labels,
    stage_circles,
)
from asvtwin.control.psf import ActiveConstraint, FilterResult, PsfConfig, SafetyFilter
from asvtwin.control.result import comfort_config, plain_config
from asvtwin.control.terminal_set import (
    TerminalSet,
    braking_input,
    compute_terminal_set,
    verify_invariance,
)

__all__ = [
    "BACKENDS",
    "ENCOUNTER_KINDS",
    "ActiveConstraint",
    "BackupPlan",
    "Candidate",
    "CircleObstacles",
    "CoastSegments",
    "EncounterLimits",
    "Encounters",
    "Fallback",
    "FilterResult",
    "MovingObstacles",
    "Obstacles",
    "PsfConfig",
    "SafetyFilter",
    "TerminalSet",
    "available_backends",
    "braking_input",
    "classify_encounters",
    "comfort_config",
    "compute_terminal_set",
    "covariance_inflation",
    "cpa_tcpa",
    "lidar_circles",
    "obstacle_labels",
    "plain_config",
    "stage_circles",
    "verify_invariance",
]
