"""COLREG encounter classification of tracked vessels relative to the own ship.

The International Regulations for Preventing Collisions at Sea (IMO 1972, "COLREGs")
assign duties by geometry. With the relative bearing β of the target from the own ship's
bow and the *aspect* α, the bearing of the own ship from the target's course (both
clockwise positive, in (−π, π]):

- **overtaking** (rule 13): the own ship comes up on the target from more than 22.5°
  abaft the target's beam, |α| > 112.5°, and closes; the own ship keeps out of the way;
- **overtaken** (rule 13 for the other ship; the own ship's duty is rule 17, stand on):
  the target comes up from more than 22.5° abaft the own beam, |β| > 112.5°;
- **head_on** (rule 14): each sees the other nearly ahead on reciprocal courses,
  |β| ≤ 11.25° and |α| ≤ 11.25° (one compass point; the rule says "ahead or nearly
  ahead"); both alter course to starboard;
- **crossing_give_way** (rules 15, 16): the target is on the own starboard side
  (0 < β ≤ 112.5°): the own ship keeps out of the way, avoiding crossing ahead,
  normally by turning to starboard;
- **crossing_stand_on** (rule 17): the target is on the own port side: the own ship
  keeps course and speed, and acts only when the give-way vessel does not (17(a)(ii),
  17(b)); if it acts it does not turn to port for a vessel on its own port side (17(c));
- **none**: no risk of collision by the CPA/TCPA test (closest point of approach beyond
  ``cpa_limit_m``, or not within the next ``tcpa_limit_s``), or a target not moving
  (speed below ``min_speed_m_s``: treated as an obstacle, its course is unknown).

The closest point of approach assumes both ships keep their present velocity over
ground (the usual ARPA computation, IMO MSC.192(79)): relative position p = p_t − p_o,
relative velocity w = v_t − v_o, TCPA = −p·w / |w|², CPA = |p + TCPA w|.

Default limits are those of a bridge alarm for an 88 m ship in coastal water
(CPA 0.25 nmi, TCPA 10 min); :meth:`EncounterLimits.for_length` scales them by Froude
similarity to another hull (CyberShip II: 5.4 m and 72 s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.errors import StateError

__all__ = [
    "ENCOUNTER_KINDS",
    "EncounterLimits",
    "Encounters",
    "classify_encounters",
    "cpa_tcpa",
]


#: Encounter kinds, in the order of :attr:`Encounters.kind`'s vocabulary.
ENCOUNTER_KINDS = ("head_on", "crossing_give_way", "crossing_stand_on", "overtaking",
                   "overtaken", "none")
#: COLREG rule giving the own ship's duty per kind (0: no rule applies).
RULE_OF_KIND = {"head_on": 14, "crossing_give_way": 15, "crossing_stand_on": 17,
                "overtaking": 13, "overtaken": 17, "none": 0}

_ABAFT = math.radians(112.5)  # 22.5° abaft the beam (rule 13(b))
_AHEAD = math.radians(11.25)  # "ahead or nearly ahead" (rule 14): one point
_REF_LENGTH_M = 88.0  # the limits below are for this hull (CyberShip II × 70)


@dataclass(frozen=True)
class EncounterLimits:
    """When a target counts as a collision risk (a bridge CPA/TCPA alarm).

    Attributes
    ----------
    cpa_limit_m : float
        Closest point of approach below which there is a risk [m] (default 0.25 nmi).
    tcpa_limit_s : float
        Look-ahead: only approaches within this time count [s] (default 10 min).
    min_speed_m_s : float
        Targets slower than this are not underway for classification [m/s].
    """

    cpa_limit_m: float = 463.0
    tcpa_limit_s: float = 600.0
    min_speed_m_s: float = 0.25

    def __post_init__(self) -> None:
        for name in ("cpa_limit_m", "tcpa_limit_s", "min_speed_m_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise StateError(f"EncounterLimits.{name} must be finite and > 0, "
                                 f"actually: {v}")

    @classmethod
    def for_length(cls, length_m: float) -> EncounterLimits:
        """The default limits Froude-scaled to a hull of ``length_m`` [m] (lengths by
        λ = L / 88 m, times and speeds by √λ)."""
        if not (math.isfinite(length_m) and length_m > 0):
            raise StateError(f"length_m must be finite and > 0, actually: {length_m}")
        lam = length_m / _REF_LENGTH_M
        d = cls()
        return cls(cpa_limit_m=d.cpa_limit_m * lam,
                   tcpa_limit_s=d.tcpa_limit_s * math.sqrt(lam),
                   min_speed_m_s=d.min_speed_m_s * math.sqrt(lam))


@dataclass(frozen=True)
class Encounters:
    """The encounter of the own ship with each of n targets (arrays of length n).

    Attributes
    ----------
    kind : tuple of str
        One of :data:`ENCOUNTER_KINDS` per target.
    rule : ndarray of int
        The COLREG rule of the own ship's duty (13, 14, 15, 17; 0 for ``"none"``).
    geometry : tuple of str
        The kind by geometry alone, ignoring the risk test (``"none"`` only for targets
        not underway).
    cpa_m, tcpa_s : ndarray
        Closest point of approach [m] and time to it [s] (negative: already passed).
    bearing_rad : ndarray
        Relative bearing of the target from the own bow, clockwise positive (starboard
        > 0), in [−π, π) [rad].
    true_bearing_rad : ndarray
        Bearing of the target from north, clockwise [rad].
    aspect_rad : ndarray
        Bearing of the own ship from the target's course over ground [rad].
    range_m : ndarray
        Present distance between the centres [m].
    """

    kind: tuple[str, ...]
    rule: NDArray[np.int64]
    geometry: tuple[str, ...]
    cpa_m: _F8
    tcpa_s: _F8
    bearing_rad: _F8
    true_bearing_rad: _F8
    aspect_rad: _F8
    range_m: _F8

    def __len__(self) -> int:
        return len(self.kind)

    @property
    def give_way(self) -> NDArray[np.bool_]:
        """True where the own ship must keep out of the way (rules 13, 14, 15)."""
        return np.array([k in ("head_on", "crossing_give_way", "overtaking")
                         for k in self.kind], dtype=bool)

    @property
    def starboard_expected(self) -> NDArray[np.bool_]:
        """True where the rules expect an alteration to starboard if the own ship acts
        (head-on, crossing give-way, and crossing stand-on by 17(c))."""
        return np.array([k in ("head_on", "crossing_give_way", "crossing_stand_on")
                         for k in self.kind], dtype=bool)


def _wrap(a: _F8) -> _F8:
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def cpa_tcpa(p_rel: ArrayLike, v_rel: ArrayLike) -> tuple[_F8, _F8]:
    """CPA [m] and TCPA [s] for relative positions and velocities (n, 2) [m, m/s].

    TCPA = −p·w / |w|²; with no relative motion (|w| ≈ 0) the range never changes:
    TCPA = 0 and CPA = the present range.
    """
    p = np.asarray(p_rel, dtype=float).reshape(-1, 2)
    w = np.asarray(v_rel, dtype=float).reshape(-1, 2)
    w2 = np.einsum("ij,ij->i", w, w)
    moving = w2 > 1e-12
    tcpa = np.where(moving, -np.einsum("ij,ij->i", p, w) / np.where(moving, w2, 1.0), 0.0)
    cpa = np.linalg.norm(p + tcpa[:, None] * w, axis=1)
    return cpa, tcpa


def classify_encounters(own_state: ArrayLike, positions: ArrayLike, velocities: ArrayLike,
                        *, limits: EncounterLimits | None = None) -> Encounters:
    """Classify each target's encounter with the own ship (see the module docstring).

    Parameters
    ----------
    own_state : array_like, shape (6,)
        ``[x, y, ψ, u, v, r]`` [m, m, rad, m/s, m/s, rad/s], NED; the bow is ψ.
    positions, velocities : array_like, shape (n, 2)
        Targets' centres [m] and velocities over ground [m/s], NED.
    limits : EncounterLimits, optional
        The risk test; default the 88 m ship's (use :meth:`EncounterLimits.for_length`).

    Examples
    --------
    >>> enc = classify_encounters([0, 0, 0, 4.0, 0, 0], [[2000.0, 5.0]], [[-4.0, 0.0]])
    >>> enc.kind, int(enc.rule[0])
    (('head_on',), 14)
    """
    lim = limits or EncounterLimits()
    x = np.asarray(own_state, dtype=float)
    if x.shape != (6,) or not np.all(np.isfinite(x)):
        raise StateError(f"own_state must be a finite (6,) [x, y, psi, u, v, r], "
                         f"actually: {x!r}")
    p = np.asarray(positions, dtype=float).reshape(-1, 2)
    v = np.asarray(velocities, dtype=float).reshape(-1, 2)
    if p.shape != v.shape:
        raise StateError(f"positions and velocities must both be (n, 2), actually: "
                         f"{p.shape} and {v.shape}")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(v))):
        raise StateError("target positions and velocities must be finite")
    psi = float(x[2])
    c, s = math.cos(psi), math.sin(psi)
    v_own = np.array([c * x[3] - s * x[4], s * x[3] + c * x[4]])
    rel = p - x[:2]
    rng_m = np.linalg.norm(rel, axis=1)
    true_b = np.arctan2(rel[:, 1], rel[:, 0])
    beta = _wrap(true_b - psi)
    course_t = np.arctan2(v[:, 1], v[:, 0])
    alpha = _wrap(true_b + np.pi - course_t)  # own ship seen from the target's course
    cpa, tcpa = cpa_tcpa(rel, v - v_own)
    speed_t = np.linalg.norm(v, axis=1)
    geom: list[str] = []
    kinds: list[str] = []
    for i in range(len(p)):
        b, a = abs(float(beta[i])), abs(float(alpha[i]))
        if speed_t[i] < lim.min_speed_m_s:
            g = "none"
        elif b > _ABAFT:
            g = "overtaken"
        elif a > _ABAFT:
            g = "overtaking"
        elif b <= _AHEAD and a <= _AHEAD:
            g = "head_on"
        elif beta[i] > 0:
            g = "crossing_give_way"
        else:
            g = "crossing_stand_on"
        geom.append(g)
        risk = cpa[i] < lim.cpa_limit_m and 0.0 <= tcpa[i] <= lim.tcpa_limit_s
        kinds.append(g if risk else "none")
    rules = np.array([RULE_OF_KIND[k] for k in kinds], dtype=np.int64)
    return Encounters(kind=tuple(kinds), rule=rules, geometry=tuple(geom), cpa_m=cpa,
                      tcpa_s=tcpa, bearing_rad=beta, true_bearing_rad=_wrap(true_b),
                      aspect_rad=alpha, range_m=rng_m)
