"""What the safety filter applies when the solver gives no certified plan: checked candidates.

The PSF's safety argument (Wabersich & Zeilinger 2021) rests on the *backup*: the last
certified plan stays valid one step later, so its tail can be applied; when the tail is
used up the terminal set's braking backup (no thrust, yaw rate damped out, see
:func:`asvtwin.control.terminal_set.braking_input`) keeps the vessel inside the terminal
ellipsoid and within d_f of where it was. Both arguments assume that nothing new has
appeared: a rock detected 8 m ahead, or a vessel closing from astern, makes the old tail
or braking unsafe. So every fallback here is a *candidate*, re-simulated from the present
state and scored against the obstacles known now:

- ``plan_tail`` — the rest of the last certified plan, then coasting;
- ``solver_plan`` — the solver's best-effort answer (uncertified, but often nearly so);
- ``braking`` — coasting with the yaw rate damped (τ = [0, 0, −k_r r]);
- ``astern`` — full astern thrust, yaw damped (only for hulls that can go astern);
- ``turn_starboard`` / ``turn_port`` — the full yaw moment for a third of the horizon or
  for all of it, with no thrust, full ahead thrust or (when available) astern thrust,
  then coasting with the yaw rate damped (with ``governed``, the filter's comfort
  pass-through, each also with its yaw moment governed so that |r| stays at the comfort
  bound ν_max,r, where the hull allows: at full thrust in a turn CyberShip II's yaw can
  outrun the full opposite moment); or a turn on the spot
  for a quarter of the horizon, then full ahead (astern) for a quarter, then coasting
  (the way out from rest).

The filter takes the certified candidate closest to the learner's input (the least
intervention), preferring one that does not go to port where COLREG expects starboard,
then one that keeps the yaw rate within the comfort bound; without one, the candidate
whose closest approach to any obstacle over the horizon is largest (inside d_safe: the
one that gets furthest out of the clearances violated now by the horizon's end without
coming closer to them on the way). The learner's raw input is never applied on a failed
solve.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum
from typing import NamedTuple

import numpy as np

from asvtwin.checks import F8 as _F8
from asvtwin.control.certification import Certifier
from asvtwin.control.terminal_set import braking_input
from asvtwin.vessel.params import VesselParams

__all__ = ["BackupPlan", "Candidate", "Fallback", "Scored", "backup_input",
           "candidate_inputs", "plan_side", "plan_tail", "select_candidate"]



class Fallback(str, Enum):
    """Which input the filter applied."""

    NONE = "none"  #: the fresh, certified solution
    PLAN_TAIL = "plan_tail"  #: the next input of the last certified plan
    SOLVER_PLAN = "solver_plan"  #: the solver's uncertified best effort, checked
    BRAKING = "braking"  #: the terminal set's braking backup
    ASTERN = "astern"  #: full astern thrust (hulls that can go astern)
    TURN_STARBOARD = "turn_starboard"  #: full yaw moment to starboard
    TURN_PORT = "turn_port"  #: full yaw moment to port


@dataclass
class BackupPlan:
    """The last certified plan: inputs (N, 3), states (N+1, 6), its start time [s]."""

    u: _F8
    x: _F8
    t0_s: float
    dt_s: float

    def index_at(self, t_s: float) -> int:
        """Stage of the plan at time ``t_s`` (may be ≥ N: exhausted)."""
        return round((t_s - self.t0_s) / self.dt_s)

    def input_at(self, t_s: float) -> _F8 | None:
        """The plan's input for time ``t_s``, or None when the tail is used up."""
        i = self.index_at(t_s)
        if 0 <= i < self.u.shape[0]:
            return self.u[i].copy()
        return None

    def tail(self, t_s: float) -> tuple[_F8, _F8]:
        """States (N+1-i, 6) and inputs (N-i, 3) from time ``t_s`` on."""
        i = max(0, self.index_at(t_s))
        return self.x[i:].copy(), self.u[i:].copy()


@dataclass(frozen=True)
class Candidate:
    """A fallback candidate: its kind, detail (e.g. "full ahead, 1/3 horizon"), the input
    sequence (N, 3) whose first row would be applied, and the stage from which the yaw
    rate is damped (τ_r = −k_r r, filled in by :func:`damp_yaw`; N: never)."""

    kind: Fallback
    detail: str
    u: _F8
    damp_from: int
    #: stages 0..govern_to-1 have their yaw moment governed to hold |r| at the comfort
    #: bound (:func:`asvtwin.control.kernels.rollout_governed`); 0: none
    govern_to: int = 0


def backup_input(params: VesselParams, x: _F8, t_s: float, plan: BackupPlan | None,
                 k_r: float) -> tuple[_F8, Fallback]:
    """The unchecked backup of PSF theory: the plan tail, else braking (kept for callers
    that need the textbook rule; the filter itself scores :func:`candidate_inputs`)."""
    if plan is not None:
        u = plan.input_at(t_s)
        if u is not None:
            return u, Fallback.PLAN_TAIL
    return braking_input(params, x, k_r), Fallback.BRAKING


def plan_tail(plan: BackupPlan | None, t_s: float, N: int) -> Candidate | None:
    """The last certified plan's remainder from ``t_s`` (padded with coasting, its yaw
    damped), or None when there is no plan or it is used up."""
    if plan is None:
        return None
    i = plan.index_at(t_s)
    if not 0 <= i < plan.u.shape[0]:
        return None
    U = np.zeros((N, 3))
    ut = plan.u[i:]
    U[: len(ut)] = ut
    return Candidate(Fallback.PLAN_TAIL, f"stage {i} of the plan of t = {plan.t0_s:.1f} s",
                     U, len(ut))


def candidate_inputs(params: VesselParams, x: _F8, t_s: float, N: int,
                     plan: BackupPlan | None, solver_u: _F8 | None, *,
                     governed: bool = False) -> list[Candidate]:
    """Every fallback candidate's input sequence (N, 3) from state ``x`` at ``t_s``.

    Yaw damping (τ_r = −k_r r) is filled in by :func:`damp_yaw` once the candidate's
    states are known; the filter re-simulates exactly the sequence it scores.
    """
    act = params.actuators
    lb = np.asarray(act.tau_min, dtype=float)
    ub = np.asarray(act.tau_max, dtype=float)
    out: list[Candidate] = []
    tail = plan_tail(plan, t_s, N)
    if tail is not None:
        out.append(tail)
    if solver_u is not None and np.all(np.isfinite(solver_u)):
        out.append(Candidate(Fallback.SOLVER_PLAN, "best effort",
                             np.clip(solver_u, lb, ub), N))
    out.append(Candidate(Fallback.BRAKING, "coasting, yaw damped", np.zeros((N, 3)), 0))
    thrusts = [(0.0, "no thrust"), (float(ub[0]), "full ahead")]
    if lb[0] < 0:
        thrusts.append((float(lb[0]), "full astern"))
        U = np.zeros((N, 3))
        U[:, 0] = lb[0]
        out.append(Candidate(Fallback.ASTERN, "full astern, yaw damped", U, 0))
    for side, kind, tr in ((1.0, Fallback.TURN_STARBOARD, ub[2]),
                           (-1.0, Fallback.TURN_PORT, lb[2])):
        if tr * side <= 0:
            continue
        for n_turn, span in ((max(1, N // 3), "1/3 horizon"), (N, "whole horizon")):
            for thrust, word in thrusts:
                U = np.zeros((N, 3))
                U[:n_turn, 0] = thrust
                U[:n_turn, 2] = tr
                out.append(Candidate(kind, f"{word}, {span}", U, n_turn))
                if governed:
                    out.append(Candidate(kind, f"{word}, {span}, held at the comfort bound",
                                         U.copy(), n_turn, govern_to=n_turn))
        # turn on the spot, then go ahead (or astern) and coast: the way out from rest
        n1, n2 = max(1, N // 4), max(2, N // 2)
        for thrust, word in thrusts[1:]:
            U = np.zeros((N, 3))
            U[:n1, 2] = tr
            U[n1:n2, 0] = thrust
            out.append(Candidate(kind, f"turn on the spot, then {word}", U, n1))
    return out


def damp_yaw(U: _F8, X: _F8, k_r: float, lb: float, ub: float, start: int) -> None:
    """Set τ_r = −k_r r_k (clipped) on stages ``start..N-1`` of ``U`` from states ``X``."""
    if start < U.shape[0]:
        U[start:, 2] = np.clip(-k_r * X[start:-1, 5], lb, ub)


def plan_side(X: _F8, length_m: float) -> int:
    """Which way a plan's states ``X`` (N+1, 6) go from the line ahead of stage 0:
    +1 to starboard, −1 to port, 0 neither (mean lateral offset over stages 1..N within
    a quarter ship length ``length_m``). The offset is measured across the initial
    heading ψ_0, positive to starboard: −sin ψ_0 Δn + cos ψ_0 Δe."""
    psi = float(X[0, 2])
    lat = -np.sin(psi) * (X[1:, 0] - X[0, 0]) + np.cos(psi) * (X[1:, 1] - X[0, 1])
    m = float(np.mean(lat))
    if abs(m) < 0.25 * length_m:
        return 0
    return 1 if m > 0 else -1


class Scored(NamedTuple):
    """A candidate re-simulated and certified against the obstacles known now."""

    kind: Fallback
    detail: str
    X: _F8  #: states (N+1, 6)
    U: _F8  #: inputs (N, 3)
    margins: _F8  #: per-stage obstacle margins (N+1, m + k) [m]
    term: float  #: terminal margin 1 − ν_Nᵀ P_f ν_N
    certified: bool
    why: str  #: why not certified ("" if it is)
    closest: float  #: closest approach over stages 1..N against d_safe alone [m]
    dist: float  #: ‖u_0 − u_L‖²_W, the size of the intervention


def static_low(r: Scored, cert: Certifier) -> float:
    """A candidate's closest approach to the *static* obstacles and the coast over stages
    1..N against d_safe (their terminal requirement at N) [m]; +inf without any."""
    static = cert.static_cols
    mg = r.margins
    if static is None or static.shape[0] != mg.shape[1] or not static.any():
        return math.inf
    path = float(mg[1:-1, static].min()) if mg.shape[0] > 2 else math.inf
    return min(path, float(cert.terminal_clearance(mg, r.term)[static].min()))


def select_candidate(rows: list[Scored], x: _F8, m0: _F8, cert: Certifier, *,
                     length_m: float, r_comfort: float, prefer_starboard: bool,
                     previous: tuple[str, str] | None = None,
                     spread: _F8 | None = None,
                     ) -> tuple[Scored, list[tuple[str, str, float, bool]]]:
    """The candidate to apply, and every candidate's score (kind, detail, closest
    approach [m], certified), best first.

    - Certified candidates exist: the one nearest u_L (W-norm), preferring first one
      that does not go to port where COLREG expects starboard (``prefer_starboard``:
      rules 14, 15, 17(c)), then one whose yaw rate stays within ``r_comfort`` [rad/s]
      (or the present |r|, if larger), else the one that exceeds it least.
    - Inside d_safe (some stage-0 margin ``m0`` < 0): the plan that gets out of the
      clearances violated now without closing in on them, then the one that ends
      furthest out of them; then the others as below. Judged on those clearances
      alone: in dense traffic every plan ends deep in some vessel's grown circle, and
      judging the recovery by the deepest of all chose, in the twin's benchmark scene,
      full astern towards a vessel closing from the starboard quarter (a collision).
    - Otherwise the plan whose first deep intrusion (a margin below −10 % of d_safe)
      comes latest; between plans as late, the one whose first deep intrusion around a
      vessel's predicted *mean* position comes latest (``spread``, (N+1, m) [m]: the
      uncertainty part of each circle's radius, :func:`~asvtwin.control.obstacles.
      stage_spread`); then the largest closest approach; where COLREG expects starboard, a
      starboard or straight plan as late and within 10 % of d_safe of it (and not inside
      d_safe where the best is outside) is taken instead. The choice says so in its
      detail.

    Without a certified candidate the coast and static obstacles come first: a candidate
    that keeps d_safe from them (or closes in on them least) beats one that is further
    from a vessel's predicted clearance circle. The coast is where it is; a moving
    obstacle's circle at a late stage is mostly the growth of its prediction's
    uncertainty, and the next call re-plans with a fresher track. (The twin's hour-long
    benchmark run, where no plan was certified for minutes in dense traffic, drove onto
    the shore three times when both counted alike.) And the manoeuvre ``previous``
    (kind, detail: the uncertified fallback applied at the last call) is kept while it
    stays as good on the coast and within 10 % of d_safe of the best closest approach:
    re-deciding from scratch every call alternated between turning to port, turning to
    starboard and coasting, which together held the course the candidates turned from.

    Time comes before depth among vessels: over a 209 s horizon (the 88 m hull) every
    candidate's closest approach is usually set by a late stage, where a track's circle
    has grown by its prediction's uncertainty to several hundred metres, and the largest
    closest approach alone chose, in the twin's dense scene, full thrust across the bow of
    a vessel 300 m away (a collision 80 s later) because it ended 50 m less deep in
    another vessel's circle 3 minutes on. A plan that stays clear longer leaves the next
    calls, with fresher tracks, the time to re-plan.

    And the predicted positions before depth: over that horizon the 95 % circles grow
    faster than the ship can move (several hundred metres at 200 s), so every candidate
    is often deep in some circle from the same stage on, and the choice between turning
    to port, to starboard or coasting was decided by metres of a circle's edge that
    changed from one call to the next. In the twin's dense scene the stopped ship
    turned to port and to starboard on alternate calls for two minutes while a vessel
    whose predicted track passed 14 m from it closed from ahead, and it passed 53 m off
    (d_safe 88 m). Measured against the predicted mean positions, the plans that move
    the ship off that track stay clear longest, and the next call finds the same.
    """
    d_safe = cert.d_safe_m
    m0_static = (m0[cert.static_cols] if cert.static_cols is not None
                 and cert.static_cols.shape == m0.shape else np.zeros(0))
    static_now = min(float(m0_static.min()), 0.0) if m0_static.size else 0.0

    def coast(r: Scored) -> float:  # 0 when the static obstacles keep d_safe (or no worse)
        return min(static_low(r, cert) - static_now + cert.tol_m, 0.0)

    def port(r: Scored) -> bool:
        return prefer_starboard and plan_side(r.X, length_m) < 0

    def brisk(r: Scored) -> float:  # how far the plan turns beyond the comfort bound
        return max(float(np.max(np.abs(r.X[1:, 5]))) - max(r_comfort, abs(float(x[5]))),
                   0.0)

    def closest(r: Scored) -> tuple[float, float]:
        return (r.closest if math.isfinite(r.closest) else -1e300, r.term)

    deep = -max(0.1 * d_safe, cert.tol_m)

    def first_deep(mg: _F8) -> int:  # the first stage deeper than `deep`; N + 1: none
        if mg.shape[0] < 2 or not mg.shape[1]:
            return mg.shape[0]
        bad = np.flatnonzero(~(mg[1:].min(axis=1) >= deep))  # (NaN counts as deep)
        return int(bad[0]) + 1 if bad.size else mg.shape[0]

    def clear_until(r: Scored) -> tuple[int, int]:  # (the circles, around the means)
        mg = r.margins
        if not (spread is not None and spread.shape[0] == mg.shape[0]
                and spread.shape[1] <= mg.shape[1] and spread.size):
            return first_deep(mg), mg.shape[0]
        core = mg.copy()
        core[:, : spread.shape[1]] += spread
        return first_deep(mg), first_deep(core)

    certified = [r for r in rows if r.certified]
    note = ""
    if certified:
        pick = min(certified, key=lambda r: (port(r), brisk(r), r.dist))  # the least brisk
        if port(min(certified, key=lambda r: r.dist)) and not port(pick):
            note = "starboard preferred (COLREG), a port plan was nearer u_L"
    elif m0.size and m0.min() < 0:  # inside d_safe: out by the end, no closer on the way
        inside = m0 < 0  # the clearances violated now: the recovery is from these
        floor = np.minimum(m0, 0.0)[inside] - cert.tol_m

        def out_score(r: Scored) -> tuple[bool, float, tuple[int, int], float, float]:
            # first a plan that gets out of them without closing in, then the one that
            # ends furthest out of them (staying put does not decrease a margin but never
            # leaves), then the others by time and depth as outside d_safe
            mg = r.margins
            end = float(cert.terminal_clearance(mg, r.term)[inside].min())
            leaves = end >= -cert.tol_m
            return (leaves and bool(np.all(mg[1:-1, inside] >= floor)), end,
                    clear_until(r), *closest(r))

        pick = max(rows, key=lambda r: (coast(r), *out_score(r)))
    else:
        pick = max(rows, key=lambda r: (coast(r), clear_until(r), *closest(r)))
        if previous is not None and (pick.kind.value, pick.detail) != previous:
            keep = [r for r in rows if (r.kind.value, r.detail) == previous
                    and coast(r) >= coast(pick) and clear_until(r) >= clear_until(pick)
                    and r.closest >= pick.closest - 0.1 * d_safe
                    and (pick.closest < 0 or r.closest >= 0)]
            if keep:
                pick = keep[0]
                note = "the manoeuvre of the last call kept"
        if port(pick):
            lim = pick.closest - 0.1 * d_safe
            alt = [r for r in rows if not port(r) and r.closest >= lim
                   and (pick.closest < 0 or r.closest >= 0) and coast(r) >= coast(pick)
                   and clear_until(r) >= clear_until(pick)]
            if alt:
                gap = pick.closest
                pick = max(alt, key=lambda r: (clear_until(r), *closest(r)))
                note = ("starboard preferred (COLREG), a port plan came "
                        f"{gap - pick.closest:.2f} m further off")
    if note:
        pick = pick._replace(detail=f"{pick.detail}; {note}")
    scores = sorted(((r.kind.value, r.detail, round(float(r.closest + d_safe), 4),
                      bool(r.certified)) for r in rows), key=lambda q: -q[2])
    return pick, scores
