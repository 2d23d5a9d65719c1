"""Give way by COLREG, then return to the route: a course offset on top of LOS guidance.

A navigator who must keep out of the way (rule 13 overtaking, rule 14 head-on, rule 15
crossing with the other vessel on the own starboard side; IMO 1972, *COLREGs*) alters
course to starboard early and substantially (rules 8 and 16), holds the new course until
the other vessel is past and clear, and then returns to the planned track. A vessel that
is the stand-on vessel (rule 17: crossing from port, being overtaken) keeps its course and
speed. :class:`GiveWay` is that manoeuvre as a course offset Δ ≥ 0 (to starboard) added
to the LOS course χ_LOS:

- a target *enters* the give-way set when :func:`asvtwin.control.colreg.classify_encounters`
  names it ``head_on``, ``crossing_give_way`` or ``overtaking`` with a risk of collision:
  with both ships holding their present velocity over ground, closest point of approach
  (CPA) below ``pass_distance_m`` within ``tcpa_limit_s``;
- each call, Δ is the smallest alteration in ``step_rad`` steps up to ``max_offset_rad``
  for which every target of the set is passed at ``pass_distance_m`` or more (CPA and
  TCPA of the own ship at its speed on course χ_LOS + Δ against the target's velocity:
  CPA ≥ pass distance, or the range already opening, TCPA ≤ 0). An overtaken vessel may
  be passed on either side (rule 13): for ``overtaking`` targets port offsets are tried
  at each magnitude after starboard;
- a target *leaves* the set when the LOS course alone passes it with a margin
  (``release_factor`` × pass distance, or opening): then Δ falls to 0 and the LOS law
  brings the own ship back to its track. Δ shrinks as the other vessel draws aft, so the
  return starts as soon as the stern of a crossing vessel is clear, not when the range is
  large;
- when no offset up to ``max_offset_rad`` clears every target, the one that maximises
  the smallest CPA is held (the safety filter, when present, has the last word).

The stand-on vessel keeps its course and speed (rule 17(a)(i)), but "may take action to
avoid collision by her manoeuvre alone, as soon as it becomes apparent to her that the
vessel required to keep out of the way is not taking appropriate action" (17(a)(ii)), and
shall when collision can no longer be avoided by the give-way vessel alone (17(b)); in a
crossing situation she shall not alter to port for a vessel on her own port side (17(c)).
With ``stand_on_tcpa_s`` set, a vessel the classifier names ``crossing_stand_on`` with a
risk of collision is *watched*: its course over ground when the risk was first seen is
kept; if, with TCPA at or below ``stand_on_tcpa_s``, the CPA is still below the pass
distance and its course has changed by less than ``altered_rad`` (it has not altered), it
enters the set as ``stand_on_act`` and the own ship alters to starboard only, by the same
smallest-alteration rule, until the LOS course passes it again. A give-way vessel that
does alter (by ``altered_rad`` or more) is left to it (and to the safety filter).

The targets are what the own ship knows (tracked positions and velocities), never ground
truth. CPA/TCPA as an ARPA computes them (constant velocities, IMO MSC.192(79)).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from asvtwin.errors import ParameterError, StateError

__all__ = ["GiveWay", "GiveWayStatus"]

_GIVE_WAY_KINDS = ("head_on", "crossing_give_way", "overtaking")


@dataclass(frozen=True)
class GiveWayStatus:
    """The give-way layer's decision at one call.

    Attributes
    ----------
    offset_rad : float
        Course alteration Δ added to the LOS course [rad] (> 0: starboard).
    targets : tuple of int
        Ids of the targets the own ship is keeping out of the way of.
    kinds : tuple of str
        Their encounter kinds when they entered (``head_on``, ``crossing_give_way``,
        ``overtaking``, or ``stand_on_act``: a give-way vessel that did not give way).
    min_cpa_m : float
        Smallest CPA to them on the commanded course [m] (inf without targets).
    """

    offset_rad: float = 0.0
    targets: tuple[int, ...] = ()
    kinds: tuple[str, ...] = ()
    min_cpa_m: float = math.inf


@dataclass
class GiveWay:
    """COLREG give-way course offset (see the module docstring).

    Parameters
    ----------
    pass_distance_m : float
        Passing distance the own ship keeps from a vessel it gives way to [m], centre to
        centre.
    tcpa_limit_s : float
        Only approaches within this time are a risk [s].
    min_speed_m_s : float
        Slower targets are not underway (left to the safety filter as obstacles) [m/s].
    max_offset_rad : float
        Largest alteration [rad].
    step_rad : float
        Alterations tried, in steps of this [rad].
    release_factor : float
        A target leaves the set when the LOS course passes it at this many pass
        distances (hysteresis, >= 1).
    stand_on_tcpa_s : float or None
        As the stand-on vessel of a crossing, act (rule 17(a)(ii), to starboard) once the
        TCPA is at or below this [s] while the give-way vessel has not altered and the CPA
        is below the pass distance. None: always stand on (rule 17(a)(i) only).
    altered_rad : float
        A give-way vessel whose course over ground changed by this much [rad] since the
        risk was first seen is taking action (no stand-on action for it).
    """

    pass_distance_m: float
    tcpa_limit_s: float
    min_speed_m_s: float
    max_offset_rad: float = math.radians(90.0)
    step_rad: float = math.radians(5.0)
    release_factor: float = 1.2
    stand_on_tcpa_s: float | None = None
    altered_rad: float = math.radians(10.0)
    _active: dict[int, str] = field(default_factory=dict, init=False, repr=False)
    _watch: dict[int, float] = field(default_factory=dict, init=False, repr=False)
    status: GiveWayStatus = field(default_factory=GiveWayStatus, init=False)

    def __post_init__(self) -> None:
        for name in ("pass_distance_m", "tcpa_limit_s", "min_speed_m_s", "max_offset_rad",
                     "step_rad", "altered_rad"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise ParameterError(f"GiveWay.{name} must be finite and > 0, actually: {v!r}")
        if not (math.isfinite(self.release_factor) and self.release_factor >= 1.0):
            raise ParameterError(f"GiveWay.release_factor must be finite and >= 1, actually: "
                                 f"{self.release_factor!r}")
        v = self.stand_on_tcpa_s
        if v is not None and not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
            raise ParameterError(f"GiveWay.stand_on_tcpa_s must be finite and > 0 or None, "
                                 f"actually: {v!r}")

    @classmethod
    def for_length(cls, length_m: float, *, stand_on_action: bool = False) -> GiveWay:
        """Settings for a hull of ``length_m`` [m]: pass at 6 ship lengths (527 m for the
        88 m supply vessel, the clearance the safety filter's track circles reach about
        three minutes ahead), look 10 minutes ahead at 88 m, and, with
        ``stand_on_action``, as the stand-on vessel act at 5 minutes to the CPA (rule
        17(a)(ii)) when the give-way vessel has not altered by 10° (off by default: the
        twin's library runs of 2026-12-01 came closer to land with it); times
        Froude-scaled (× √λ, λ = L / 88 m)."""
        if not (math.isfinite(length_m) and length_m > 0):
            raise ParameterError(f"length_m must be finite and > 0, actually: {length_m!r}")
        sq = math.sqrt(length_m / 88.0)
        return cls(pass_distance_m=6.0 * length_m, tcpa_limit_s=600.0 * sq,
                   min_speed_m_s=0.25 * sq,
                   stand_on_tcpa_s=300.0 * sq if stand_on_action else None)

    def reset(self) -> None:
        """Forget every target (no manoeuvre in progress)."""
        self._active.clear()
        self._watch.clear()
        self.status = GiveWayStatus()

    def _cpa(self, p_rel: np.ndarray, v_t: np.ndarray, speed: float, chi: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
        """CPA, TCPA (m candidate courses × n targets) of the own ship at ``speed`` on each
        course ``chi`` (m,)."""
        from asvtwin.control.colreg import cpa_tcpa

        v_o = speed * np.stack([np.cos(chi), np.sin(chi)], axis=1)  # (m, 2)
        w = v_t[None, :, :] - v_o[:, None, :]  # (m, n, 2)
        m, n = w.shape[0], w.shape[1]
        p = np.broadcast_to(p_rel[None], (m, n, 2))
        cpa, tcpa = cpa_tcpa(p.reshape(-1, 2), w.reshape(-1, 2))
        return cpa.reshape(m, n), tcpa.reshape(m, n)

    def _stand_on(self, tid: int, v: np.ndarray, tcpa_s: float) -> None:
        """Rule 17(a)(ii) for a give-way vessel ``tid`` at risk (CPA below the pass
        distance at TCPA ``tcpa_s``) with velocity ``v``: watch its course; act (enter
        the set) once TCPA <= ``stand_on_tcpa_s`` and it has not altered."""
        course = math.atan2(float(v[1]), float(v[0]))
        c0 = self._watch.setdefault(tid, course)
        assert self.stand_on_tcpa_s is not None
        turned = abs(math.remainder(course - c0, 2.0 * math.pi))
        if tcpa_s <= self.stand_on_tcpa_s and turned < self.altered_rad:
            self._active[tid] = "stand_on_act"

    def offset(self, own_state: ArrayLike, los_course_rad: float, speed_m_s: float,
               ids: ArrayLike, positions: ArrayLike, velocities: ArrayLike) -> float:
        """The course alteration Δ [rad] (≥ 0 starboard; < 0 only to pass an overtaken
        vessel on its port side) for the targets ``ids`` (n,) at ``positions`` (n, 2) [m]
        with ``velocities`` (n, 2) [m/s] over ground, NED; the decision is kept in
        :attr:`status`."""
        from asvtwin.control.colreg import EncounterLimits, classify_encounters

        x = np.asarray(own_state, dtype=float).reshape(-1)
        ids_a = np.asarray(ids, dtype=np.int64).reshape(-1)
        p = np.asarray(positions, dtype=float).reshape(-1, 2)
        v = np.asarray(velocities, dtype=float).reshape(-1, 2)
        if x.shape != (6,) or not np.isfinite(x).all() or not math.isfinite(los_course_rad):
            raise StateError(f"own_state must be a finite (6,) state and the LOS course finite, "
                             f"actually: {x!r}, {los_course_rad!r}")
        if not (p.shape == v.shape and p.shape[0] == ids_a.shape[0]):
            raise StateError(f"ids (n,), positions and velocities (n, 2) must agree, actually: "
                             f"{ids_a.shape}, {p.shape}, {v.shape}")
        ok = np.isfinite(p).all(axis=1) & np.isfinite(v).all(axis=1)
        ids_a, p, v = ids_a[ok], p[ok], v[ok]
        speed = max(float(speed_m_s), 1e-6)
        # 1. who enters: give-way encounters with a risk at the present velocities (the
        # ARPA risk test first, vectorised: only the few vessels at risk are classified)
        if len(ids_a):
            from asvtwin.control.colreg import cpa_tcpa

            psi = float(x[2])
            v_own = np.array([math.cos(psi) * x[3] - math.sin(psi) * x[4],
                              math.sin(psi) * x[3] + math.cos(psi) * x[4]])
            cpa_now, tcpa_now = cpa_tcpa(p - x[:2], v - v_own)
            risk = (cpa_now < self.pass_distance_m) & (tcpa_now >= 0.0) & \
                (tcpa_now <= self.tcpa_limit_s)
            if risk.any():
                r = np.flatnonzero(risk)
                enc = classify_encounters(x, p[r], v[r], limits=EncounterLimits(
                    cpa_limit_m=self.pass_distance_m, tcpa_limit_s=self.tcpa_limit_s,
                    min_speed_m_s=self.min_speed_m_s))
                for i, k in zip(r, enc.kind, strict=True):
                    tid = int(ids_a[i])
                    if tid in self._active:
                        continue
                    if k in _GIVE_WAY_KINDS:
                        self._active[tid] = k
                    elif k == "crossing_stand_on" and self.stand_on_tcpa_s is not None:
                        self._stand_on(tid, v[i], float(tcpa_now[i]))
            at_risk = {int(t) for t in ids_a[risk]}
        else:
            at_risk = set()
        # a target no longer tracked is forgotten; a watched one no longer at risk too
        known = {int(i) for i in ids_a}
        for tid in [t for t in self._active if t not in known]:
            del self._active[tid]
        for tid in [t for t in self._watch if t not in at_risk or t in self._active]:
            del self._watch[tid]
        if not self._active:
            self.status = GiveWayStatus()
            return 0.0
        sel = np.isin(ids_a, np.fromiter(self._active, dtype=np.int64, count=len(self._active)))
        p_rel, v_t, sel_ids = p[sel] - x[:2], v[sel], ids_a[sel]
        # 2. who leaves: the LOS course alone passes it with a margin
        cpa0, tcpa0 = self._cpa(p_rel, v_t, speed, np.array([los_course_rad]))
        clear0 = (cpa0[0] >= self.release_factor * self.pass_distance_m) | (tcpa0[0] <= 0.0)
        for tid in sel_ids[clear0]:
            del self._active[int(tid)]
        keep = ~clear0
        if not keep.any():
            self.status = GiveWayStatus()
            return 0.0
        p_rel, v_t, sel_ids = p_rel[keep], v_t[keep], sel_ids[keep]
        # 3. the smallest alteration that passes every remaining target
        mags = np.arange(0.0, self.max_offset_rad + 1e-9, self.step_rad)
        port_ok = any(self._active[int(t)] == "overtaking" for t in sel_ids) and \
            all(self._active[int(t)] == "overtaking" for t in sel_ids)
        cands = np.concatenate([[m, -m] if (port_ok and m > 0) else [m] for m in mags])
        cpa, tcpa = self._cpa(p_rel, v_t, speed, los_course_rad + cands)
        clear = (cpa >= self.pass_distance_m) | (tcpa <= 0.0)
        worst = np.where(tcpa <= 0.0, np.inf, cpa).min(axis=1)
        good = np.flatnonzero(clear.all(axis=1))
        j = int(good[0]) if len(good) else int(np.argmax(worst))
        off = float(cands[j])
        self.status = GiveWayStatus(off, tuple(int(t) for t in sel_ids),
                                    tuple(self._active[int(t)] for t in sel_ids),
                                    float(worst[j]))
        return off
