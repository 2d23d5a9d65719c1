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
  then coasting with the yaw rate damped; or a turn on the spot for a quarter of the
  horizon, then full ahead (astern) for a quarter, then coasting (the way out from rest).

The filter takes the certified candidate closest to the learner's input (the least
intervention); without one, the candidate whose closest approach to any obstacle over the
horizon is largest (inside d_safe: the one that gets furthest out by the horizon's end
without coming closer on the way). The learner's raw input is never applied on a failed solve.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np

from asvtwin.checks import F8 as _F8
from asvtwin.control.terminal_set import braking_input
from asvtwin.vessel.params import VesselParams

__all__ = ["BackupPlan", "Candidate", "Fallback", "backup_input", "candidate_inputs"]



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


def backup_input(params: VesselParams, x: _F8, t_s: float, plan: BackupPlan | None,
                 k_r: float) -> tuple[_F8, Fallback]:
    """The unchecked backup of PSF theory: the plan tail, else braking (kept for callers
    that need the textbook rule; the filter itself scores :func:`candidate_inputs`)."""
    if plan is not None:
        u = plan.input_at(t_s)
        if u is not None:
            return u, Fallback.PLAN_TAIL
    return braking_input(params, x, k_r), Fallback.BRAKING


def candidate_inputs(params: VesselParams, x: _F8, t_s: float, N: int,
                     plan: BackupPlan | None, solver_u: _F8 | None) -> list[Candidate]:
    """Every fallback candidate's input sequence (N, 3) from state ``x`` at ``t_s``.

    Yaw damping (τ_r = −k_r r) is filled in by :func:`damp_yaw` once the candidate's
    states are known; the filter re-simulates exactly the sequence it scores.
    """
    act = params.actuators
    lb = np.asarray(act.tau_min, dtype=float)
    ub = np.asarray(act.tau_max, dtype=float)
    out: list[Candidate] = []
    if plan is not None:
        i = plan.index_at(t_s)
        if 0 <= i < plan.u.shape[0]:
            U = np.zeros((N, 3))
            ut = plan.u[i:]
            U[: len(ut)] = ut
            out.append(Candidate(Fallback.PLAN_TAIL, f"stage {i} of the plan of "
                                 f"t = {plan.t0_s:.1f} s", U, len(ut)))
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
