"""Risk per alternative with confidence intervals, and a recommendation a navigator reads.

The collision probability of an alternative is estimated from R independent rollouts as
k/R with the Clopper–Pearson ("exact") interval (Clopper and Pearson 1934, *Biometrika*
26(4)), computed by :func:`scipy.stats.binomtest`: its coverage is at least the nominal
level for every true probability, and its width shrinks as 1/√R.

The recommendation (:func:`recommend`) takes the own-ship decisions whose collision and
grounding risks are acceptable (upper confidence bound ≤ ``acceptable``), prefers those
the COLREGs ask for in the most pressing encounter (rules 13–15, 17; classified by
:func:`asvtwin.control.classify_encounters` at the fork) and then the least change to the
plan; if none is acceptable it names the least risky one and says so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import binomtest

from asvtwin.control import EncounterLimits, classify_encounters
from asvtwin.errors import ParameterError
from asvtwin.whatif.alternatives import DECISIONS, Alternative
from asvtwin.whatif.fork import Fork
from asvtwin.whatif.rollout import RolloutResult

__all__ = ["AlternativeRisk", "Encounter", "Recommendation", "encounters", "proportion_ci",
           "recommend", "summarise"]

#: What the rule asks of the own ship, in words.
RULE_TEXT = {
    13: "rule 13 (overtaking): the overtaking vessel keeps out of the way",
    14: "rule 14 (head-on): both vessels alter course to starboard",
    15: "rule 15 (crossing): the vessel with the other on her starboard side keeps out "
        "of the way and avoids crossing ahead",
    17: "rule 17 (stand-on): keep course and speed; if action becomes necessary, do not "
        "alter to port for a vessel on the port side",
}
_KIND_TEXT = {"head_on": "meeting head-on", "crossing_give_way": "crossing from starboard",
              "crossing_stand_on": "crossing from port", "overtaking": "being overtaken by us",
              "overtaken": "overtaking us", "none": "not a risk of collision"}


def proportion_ci(k: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Clopper–Pearson interval of a binomial proportion k/n.

    >>> lo, hi = proportion_ci(0, 100)
    >>> lo, round(hi, 4)
    (0.0, 0.0362)
    """
    if n < 1 or not 0 <= k <= n:
        raise ParameterError(f"need 0 <= k <= n and n >= 1, actually: k={k}, n={n}")
    ci = binomtest(int(k), int(n)).proportion_ci(confidence_level=confidence, method="exact")
    return float(ci.low), float(ci.high)


@dataclass(frozen=True)
class Encounter:
    """One target's COLREG encounter at the fork."""

    track_id: int
    name: str
    kind: str
    rule: int
    range_m: float
    bearing_deg: float
    cpa_m: float
    tcpa_s: float

    def describe(self) -> str:
        side = "starboard" if self.bearing_deg >= 0 else "port"
        return (f"{self.name} is {_KIND_TEXT[self.kind]}, {self.range_m:.0f} m away "
                f"{abs(self.bearing_deg):.0f}° to {side}, CPA {self.cpa_m:.0f} m in "
                f"{self.tcpa_s:.0f} s")


def encounters(fork: Fork) -> tuple[Encounter, ...]:
    """Every believed track's COLREG encounter with the own ship at the fork, the most
    pressing first (those with a rule, by time to CPA)."""
    if fork.n_tracks == 0:
        return ()
    lim = EncounterLimits.for_length(fork.params.length)
    e = classify_encounters(fork.own_state, fork.track_mean[:, :2], fork.track_mean[:, 2:],
                            limits=lim)
    out = [Encounter(int(fork.track_ids[i]), fork.track_names[i], e.kind[i], int(e.rule[i]),
                     float(e.range_m[i]), math.degrees(float(e.bearing_rad[i])),
                     float(e.cpa_m[i]), float(e.tcpa_s[i])) for i in range(len(e))]
    return tuple(sorted(out, key=lambda q: (q.rule == 0, q.tcpa_s if q.tcpa_s >= 0 else 1e12)))


@dataclass(frozen=True)
class AlternativeRisk:
    """The outcome of one alternative over R rollouts.

    Probabilities with their 95 % Clopper–Pearson interval; distances [m] and times [s
    after the fork] as 5/50/95 % quantiles over the rollouts of the closest approach to
    any target; mean filter calls, interventions and fallbacks per rollout."""

    label: str
    description: str
    decision: bool
    filter: bool
    rollouts: int
    collisions: int
    p_collision: float
    p_collision_ci: tuple[float, float]
    groundings: int
    p_grounding: float
    p_grounding_ci: tuple[float, float]
    min_distance_m: tuple[float, float, float]
    t_closest_s: tuple[float, float, float]
    min_land_m: float
    filter_calls: float
    interventions: float
    fallbacks: float

    def to_dict(self) -> dict[str, object]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def _q(a: np.ndarray) -> tuple[float, float, float]:
    if a.size == 0 or not np.isfinite(a).any():
        return (math.inf, math.inf, math.inf)
    q = np.quantile(a[np.isfinite(a)], [0.05, 0.5, 0.95])
    return (float(q[0]), float(q[1]), float(q[2]))


def summarise(alternatives: tuple[Alternative, ...] | list[Alternative], res: RolloutResult,
              confidence: float = 0.95) -> tuple[AlternativeRisk, ...]:
    """One :class:`AlternativeRisk` per alternative."""
    out = []
    R = res.collision.shape[1]
    for i, a in enumerate(alternatives):
        kc = int(res.collision[i].sum())
        kg = int(res.grounding[i].sum())
        if res.min_distance_m.shape[2]:
            j = np.argmin(res.min_distance_m[i], axis=1)
            dmin = res.min_distance_m[i][np.arange(R), j]
            tmin = res.t_min_s[i][np.arange(R), j]
        else:
            dmin = tmin = np.zeros(0)
        out.append(AlternativeRisk(
            label=a.label, description=a.describe(), decision=a.kind in DECISIONS, filter=a.filter, rollouts=R, collisions=kc,
            p_collision=kc / R, p_collision_ci=proportion_ci(kc, R, confidence),
            groundings=kg, p_grounding=kg / R, p_grounding_ci=proportion_ci(kg, R, confidence),
            min_distance_m=_q(dmin), t_closest_s=_q(tmin),
            min_land_m=float(np.min(res.land_clearance_m[i])),
            filter_calls=float(res.filter_calls[i].mean()),
            interventions=float(res.interventions[i].mean()),
            fallbacks=float(res.fallbacks[i].mean())))
    return tuple(out)


@dataclass(frozen=True)
class Recommendation:
    """The advice: which alternative, why (a navigator's sentence) and the COLREG rule
    it follows (13, 14, 15, 17; 0 when no encounter asks for a rule)."""

    label: str
    reason: str
    rule: int
    acceptable: bool

    def to_dict(self) -> dict[str, object]:
        return {"label": self.label, "reason": self.reason, "rule": self.rule,
                "acceptable": self.acceptable}


def _compliant(kind: str, alt_kind: str) -> bool:
    """Whether an own-ship manoeuvre is what the rule of encounter ``kind`` asks."""
    if kind == "head_on":
        return alt_kind == "starboard"
    if kind == "crossing_give_way":
        return alt_kind in ("starboard", "slow", "stop")
    if kind == "overtaking":
        return alt_kind in ("starboard", "port", "slow")
    if kind in ("crossing_stand_on", "overtaken"):
        return alt_kind in ("keep_course", "route")
    return True


def _pct(p: float) -> str:
    return f"{100 * p:.1f} %"


def recommend(fork: Fork, alternatives: tuple[Alternative, ...] | list[Alternative],
              risks: tuple[AlternativeRisk, ...], *, acceptable: float = 0.05
              ) -> Recommendation:
    """Pick an own-ship decision and say why (see the module docstring).

    ``acceptable`` bounds the upper confidence limit of the collision and of the
    grounding probability of an acceptable decision.
    """
    if not 0 < acceptable < 1:
        raise ParameterError(f"acceptable risk must be in (0, 1), actually: {acceptable}")
    enc = encounters(fork)
    main = enc[0] if enc and enc[0].rule else None
    kind = main.kind if main else "none"
    idx = [i for i, a in enumerate(alternatives) if a.kind in DECISIONS]
    # the filter stays as the navigator has set it: "filter off" futures are hypotheses
    same = [i for i in idx if alternatives[i].filter == fork.filter_enabled]
    idx = same or idx
    if not idx:
        raise ParameterError("no own-ship decision among the alternatives (route, "
                             "keep_course, starboard, port, slow, stop)")

    def ok(i: int) -> bool:
        r = risks[i]
        return r.p_collision_ci[1] <= acceptable and r.p_grounding_ci[1] <= acceptable

    def key(i: int) -> tuple:
        a, r = alternatives[i], risks[i]
        return (not ok(i), not _compliant(kind, a.kind), not a.filter,
                DECISIONS.index(a.kind), r.p_collision_ci[1], -r.min_distance_m[1])

    best = min(idx, key=key)
    a, r = alternatives[best], risks[best]
    good = ok(best)
    rule = main.rule if (main and _compliant(kind, a.kind)) else 0
    parts = [a.describe()[0].upper() + a.describe()[1:] + "."]
    if main:
        parts.append(main.describe() + ".")
        parts.append(RULE_TEXT[main.rule] + ("." if rule else
                                             " — no acceptable action follows it."))
    else:
        parts.append("No vessel is a risk of collision by CPA/TCPA.")
    parts.append(f"With it, collision in {r.collisions} of {r.rollouts} futures "
                 f"({_pct(r.p_collision)}, 95 % interval {_pct(r.p_collision_ci[0])}–"
                 f"{_pct(r.p_collision_ci[1])}), closest approach median "
                 f"{r.min_distance_m[1]:.0f} m (5 %: {r.min_distance_m[0]:.0f} m).")
    keep = [i for i in idx if alternatives[i].kind in ("keep_course", "route") and i != best]
    for i in keep[:1]:
        q = risks[i]
        parts.append(f"To {alternatives[i].describe()} instead: collision in "
                     f"{_pct(q.p_collision)} ({_pct(q.p_collision_ci[0])}–"
                     f"{_pct(q.p_collision_ci[1])}).")
    if not good:
        parts.insert(0, f"No alternative keeps the collision and grounding risk below "
                        f"{_pct(acceptable)} with 95 % confidence; the least risky:")
    return Recommendation(label=a.label, reason=" ".join(parts), rule=int(rule),
                          acceptable=good)
