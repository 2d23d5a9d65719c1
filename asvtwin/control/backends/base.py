"""What every solver backend of the safety filter provides: one call, one raw solution."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from asvtwin.control.backends.ocp import OcpSpec

__all__ = ["Backend", "RawSolution"]


@dataclass(frozen=True)
class RawSolution:
    """A backend's answer before the filter checks and explains it.

    Attributes
    ----------
    x : ndarray, shape (N+1, 6)
        Predicted states.
    u : ndarray, shape (N, 3)
        Planned inputs [N, N, Nm].
    max_slack : float
        Largest slack of any soft constraint (0 when every constraint holds).
    success : bool
        The solver reports convergence (or, for RTI, a QP solved without error).
    status : str
        The solver's own status word.
    iterations : int
        Solver iterations (SQP or interior-point).
    solve_time_s : float
        Wall time of the solver call [s].
    """

    x: NDArray[np.float64]
    u: NDArray[np.float64]
    max_slack: float
    success: bool
    status: str
    iterations: int
    solve_time_s: float


class Backend(Protocol):
    """A solver of the OCP in :mod:`asvtwin.control.backends.ocp`."""

    name: str
    spec: OcpSpec

    def solve(self, x0: NDArray[np.float64], u_L: NDArray[np.float64],
              stage_params: NDArray[np.float64], x_guess: NDArray[np.float64],
              u_guess: NDArray[np.float64]) -> RawSolution:
        """Solve from state ``x0`` (6,) for learner input ``u_L`` (3,), stage parameters
        (N+1, n_p) and a primal guess (``x_guess`` (N+1, 6), ``u_guess`` (N, 3))."""
        ...

    def reset(self) -> None:
        """Forget any solver state carried between calls (iterates, multipliers)."""
        ...
