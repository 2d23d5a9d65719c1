"""What-if (capability level 4, prescriptive): fork the twin, roll alternatives out as
Monte Carlo futures, estimate their risk with confidence intervals and recommend one.

Examples
--------
>>> from asvtwin.whatif import parse_alternative
>>> parse_alternative("port:20").describe()
'alter course 20° to port'
"""

from asvtwin.whatif.alternatives import (
    DECISIONS,
    Alternative,
    default_alternatives,
    parse_alternative,
)
from asvtwin.whatif.ask import RayExecutor, WhatIfAnswer, ask, warm_up
from asvtwin.whatif.fork import Fork, fork, fork_scenario
from asvtwin.whatif.risk import (
    AlternativeRisk,
    Encounter,
    Recommendation,
    encounters,
    proportion_ci,
    recommend,
    summarise,
)
from asvtwin.whatif.rollout import (
    RolloutConfig,
    RolloutResult,
    Samples,
    draw_samples,
    filter_config,
    simulate,
)

__all__ = [
    "DECISIONS",
    "Alternative",
    "AlternativeRisk",
    "Encounter",
    "Fork",
    "RayExecutor",
    "Recommendation",
    "RolloutConfig",
    "RolloutResult",
    "Samples",
    "WhatIfAnswer",
    "ask",
    "default_alternatives",
    "draw_samples",
    "encounters",
    "filter_config",
    "fork",
    "fork_scenario",
    "parse_alternative",
    "proportion_ci",
    "recommend",
    "simulate",
    "summarise",
    "warm_up",
]
