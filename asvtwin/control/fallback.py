"""What the safety filter applies when the solver gives no certified plan.

The PSF's safety argument (Wabersich & Zeilinger 2021) rests on the *backup*: the last
certified plan stays valid one step later, so its tail can be applied; when the tail is
used up the terminal set's braking backup (no thrust, yaw rate damped out, see
:func:`asvtwin.control.terminal_set.braking_input`) keeps the vessel inside the terminal
ellipsoid and within d_f of where it was. The learner's raw input is never passed on.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from asvtwin.control.terminal_set import braking_input
from asvtwin.vessel.params import VesselParams

__all__ = ["BackupPlan", "Fallback"]


class Fallback(str, Enum):
    """Which input the filter applied."""

    NONE = "none"  #: the fresh, certified solution
    PLAN_TAIL = "plan_tail"  #: the next input of the last certified plan
    BRAKING = "braking"  #: the terminal set's braking backup


@dataclass
class BackupPlan:
    """The last certified plan: inputs (N, 3), states (N+1, 6), its start time [s]."""

    u: NDArray[np.float64]
    x: NDArray[np.float64]
    t0_s: float
    dt_s: float

    def index_at(self, t_s: float) -> int:
        """Stage of the plan at time ``t_s`` (may be ≥ N: exhausted)."""
        return round((t_s - self.t0_s) / self.dt_s)

    def input_at(self, t_s: float) -> NDArray[np.float64] | None:
        """The plan's input for time ``t_s``, or None when the tail is used up."""
        i = self.index_at(t_s)
        if 0 <= i < self.u.shape[0]:
            return self.u[i].copy()
        return None

    def tail(self, t_s: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """States (N+1-i, 6) and inputs (N-i, 3) from time ``t_s`` on."""
        i = max(0, self.index_at(t_s))
        return self.x[i:].copy(), self.u[i:].copy()


def backup_input(params: VesselParams, x: NDArray[np.float64], t_s: float,
                 plan: BackupPlan | None, k_r: float
                 ) -> tuple[NDArray[np.float64], Fallback]:
    """The fallback input at state ``x`` and time ``t_s``: plan tail, else braking."""
    if plan is not None:
        u = plan.input_at(t_s)
        if u is not None:
            return u, Fallback.PLAN_TAIL
    return braking_input(params, x, k_r), Fallback.BRAKING


__all__ += ["backup_input"]
