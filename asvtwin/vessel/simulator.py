"""Fixed-step simulation of many vessels at once (and of one, stepped from Python).

:class:`BatchSimulator` advances n vessels with thruster dynamics and classic RK4 in a
single compiled call per step; :class:`VesselSimulator` is the one-vessel form an RL
environment calls every step. Both take commanded thrust and disturbances as plain arrays
and return new state arrays; time is theirs only as a step counter (``t_s``).

Actuator faults (for the diagnostic twin) are injected per vessel and DOF as a gain and a
bias on the thrust that reaches the hull: see :meth:`BatchSimulator.set_fault`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from asvtwin.errors import StateError
from asvtwin.vessel.kernels import step_batch
from asvtwin.vessel.model import validate_array
from asvtwin.vessel.params import VesselParams

__all__ = ["BatchSimulator", "VesselSimulator"]

_STATE_FIELDS = ("x", "y", "psi", "u", "v", "r")
_DOF = ("surge", "sway", "yaw")


def _pack(params: VesselParams | Sequence[VesselParams], n: int
          ) -> tuple[NDArray[np.float64], NDArray[np.float64], tuple[VesselParams, ...]]:
    plist = (params,) if isinstance(params, VesselParams) else tuple(params)
    if len(plist) not in (1, n):
        raise StateError(f"expected 1 or {n} parameter sets (one per vessel), "
                         f"actually: {len(plist)}")
    P = np.ascontiguousarray(np.stack([p.packed() for p in plist]))
    A = np.ascontiguousarray(np.stack([p.actuators.packed() for p in plist]))
    return P, A, plist


class BatchSimulator:
    """n vessels stepped together: thrusters (lag, rate limit, saturation) then RK4.

    Parameters
    ----------
    params : VesselParams or sequence of VesselParams
        One set shared by all vessels, or one per vessel.
    x0 : array_like, shape (n, 6) or (6,)
        Initial states ``[x, y, ψ, u, v, r]`` [m, m, rad, m/s, m/s, rad/s], NED.
    dt_s : float
        Fixed step [s], > 0.
    tau0 : array_like, shape (n, 3), optional
        Initial actual thrust [N, N, Nm]; zero by default.
    t0_s : float
        Simulation time of ``x0`` [s].

    Examples
    --------
    >>> from asvtwin.vessel import BatchSimulator, cybership2
    >>> sim = BatchSimulator(cybership2(), [[0, 0, 0, 0, 0, 0]] * 4, dt_s=0.1)
    >>> x = sim.step([2.0, 0.0, 0.0])      # the same command for all four vessels
    >>> x.shape
    (4, 6)
    """

    def __init__(self, params: VesselParams | Sequence[VesselParams], x0: ArrayLike, *,
                 dt_s: float, tau0: ArrayLike | None = None, t0_s: float = 0.0) -> None:
        if not (math.isfinite(dt_s) and dt_s > 0):
            raise StateError(f"dt_s must be finite and > 0, actually: {dt_s}")
        self._x = np.ascontiguousarray(validate_array(x0, 6, "initial state",
                                                      _STATE_FIELDS)).copy()
        n = self._x.shape[0]
        self._P, self._A, self.params = _pack(params, n)
        self._tau = (np.zeros((n, 3)) if tau0 is None else
                     np.ascontiguousarray(validate_array(tau0, 3, "initial thrust")).copy())
        if self._tau.shape[0] != n:
            raise StateError(f"tau0 must have {n} rows, actually: {self._tau.shape[0]}")
        self._F = np.zeros((1, 2, 3))
        self._F[0, 0, :] = 1.0
        self._x_next = np.empty_like(self._x)
        self._tau_next = np.empty_like(self._tau)
        self._zero_d = np.zeros((n, 3))
        self.dt_s = float(dt_s)
        self.t_s = float(t0_s)

    @property
    def n(self) -> int:
        """Number of vessels."""
        return self._x.shape[0]

    @property
    def state(self) -> NDArray[np.float64]:
        """Copy of the current states (n, 6)."""
        return self._x.copy()

    @property
    def thrust(self) -> NDArray[np.float64]:
        """Copy of the actual actuator thrust (n, 3), before faults."""
        return self._tau.copy()

    @property
    def applied_thrust(self) -> NDArray[np.float64]:
        """Thrust that reaches the hull (n, 3): actual thrust with faults applied."""
        F = np.broadcast_to(self._F, (self.n, 2, 3))
        return F[:, 0, :] * self._tau + F[:, 1, :]

    def _broadcast(self, a: ArrayLike, what: str) -> NDArray[np.float64]:
        arr = np.asarray(a, dtype=np.float64)
        if arr.shape == (3,):
            arr = np.broadcast_to(arr, (self.n, 3))
        if arr.shape != (self.n, 3):
            raise StateError(f"{what} must have shape (3,) or ({self.n}, 3), "
                             f"actually: {arr.shape}")
        return np.ascontiguousarray(arr)

    def step(self, tau_cmd: ArrayLike, d: ArrayLike | None = None) -> NDArray[np.float64]:
        """Advance all vessels by ``dt_s``; return the new states (n, 6), a copy.

        Parameters
        ----------
        tau_cmd : array_like, shape (n, 3) or (3,)
            Commanded thrust [N, N, Nm]; saturated by the actuator limits.
        d : array_like, shape (n, 3) or (3,), optional
            Environmental disturbance τ_d [N, N, Nm], body frame, held over the step.
        """
        tau_cmd = self._broadcast(tau_cmd, "tau_cmd")
        dd = self._zero_d if d is None else self._broadcast(d, "disturbance d")
        bad = step_batch(self._x, self._tau, tau_cmd, dd, self._P, self._A, self._F,
                         self.dt_s, self._x_next, self._tau_next)
        if bad >= 0:
            self._raise_bad(bad, tau_cmd, dd)
        self._x, self._x_next = self._x_next, self._x
        self._tau, self._tau_next = self._tau_next, self._tau
        self.t_s += self.dt_s
        return self._x.copy()

    def _raise_bad(self, i: int, tau_cmd: NDArray[np.float64], d: NDArray[np.float64]
                   ) -> None:
        for arr, what in ((tau_cmd, "commanded thrust"), (d, "disturbance")):
            for j in range(3):
                if not math.isfinite(arr[i, j]):
                    raise StateError(f"{what} of vessel {i} has non-finite {_DOF[j]} "
                                     f"component: {arr[i, j]}")
        raise StateError(f"state of vessel {i} became non-finite after the step from "
                         f"{self._x[i].tolist()} (diverged: is dt_s={self.dt_s} too large?)")

    def reset(self, x0: ArrayLike, *, tau0: ArrayLike | None = None, t0_s: float = 0.0
              ) -> None:
        """Set new states (same n), thrust (zero by default) and time."""
        x = validate_array(x0, 6, "state", _STATE_FIELDS)
        if x.shape[0] != self.n:
            raise StateError(f"reset state must have {self.n} rows, actually: {x.shape[0]}")
        self._x[:] = x
        self._tau[:] = 0.0 if tau0 is None else self._broadcast(tau0, "tau0")
        self.t_s = float(t0_s)

    # ------------------------------------------------------------------ actuator faults
    def set_fault(self, vessel: int, dof: int, *, gain: float = 1.0, bias: float = 0.0
                  ) -> None:
        """Inject an actuator fault: thrust reaching the hull = gain · actual + bias.

        ``gain=0.5`` loses half the thrust; ``gain=0, bias=value`` is an actuator stuck at
        ``value``; ``bias`` alone is an offset. ``clear_faults`` heals all.
        """
        if not (0 <= vessel < self.n and 0 <= dof < 3):
            raise StateError(f"fault index out of range: vessel {vessel} of {self.n}, "
                             f"dof {dof} of 3")
        if not (math.isfinite(gain) and math.isfinite(bias)):
            raise StateError(f"fault gain and bias must be finite: {gain}, {bias}")
        if self._F.shape[0] == 1 and self.n > 1:
            self._F = np.ascontiguousarray(np.repeat(self._F, self.n, axis=0))
        self._F[vessel, 0, dof] = gain
        self._F[vessel, 1, dof] = bias

    def stick_actuator(self, vessel: int, dof: int) -> None:
        """The actuator of ``dof`` sticks at its present thrust."""
        self.set_fault(vessel, dof, gain=0.0, bias=float(self._tau[vessel, dof]))

    def clear_faults(self) -> None:
        """Heal every injected fault."""
        self._F = np.zeros((1, 2, 3))
        self._F[0, 0, :] = 1.0


class VesselSimulator:
    """One vessel stepped from Python, as an RL environment steps it.

    A thin, allocation-light front to the same compiled kernel as
    :class:`BatchSimulator`. ``step`` takes a (3,) command and returns a (6,) state.
    """

    def __init__(self, params: VesselParams, x0: ArrayLike, *, dt_s: float,
                 t0_s: float = 0.0) -> None:
        self._sim = BatchSimulator(params, np.reshape(np.asarray(x0, float), (1, 6)),
                                   dt_s=dt_s, t0_s=t0_s)
        self._cmd = np.zeros((1, 3))
        self._d = np.zeros((1, 3))

    @property
    def params(self) -> VesselParams:
        return self._sim.params[0]

    @property
    def state(self) -> NDArray[np.float64]:
        return self._sim._x[0].copy()

    @property
    def thrust(self) -> NDArray[np.float64]:
        return self._sim._tau[0].copy()

    @property
    def t_s(self) -> float:
        return self._sim.t_s

    @property
    def dt_s(self) -> float:
        return self._sim.dt_s

    @property
    def batch(self) -> BatchSimulator:
        """The underlying one-vessel batch simulator (faults, reset)."""
        return self._sim

    def step(self, tau_cmd: ArrayLike, d: ArrayLike | None = None) -> NDArray[np.float64]:
        """Advance by ``dt_s``; return the new state (6,)."""
        s = self._sim
        self._cmd[0] = tau_cmd
        if d is None:
            self._d[0] = 0.0
        else:
            self._d[0] = d
        bad = step_batch(s._x, s._tau, self._cmd, self._d, s._P, s._A, s._F, s.dt_s,
                         s._x_next, s._tau_next)
        if bad >= 0:
            s._raise_bad(bad, self._cmd, self._d)
        s._x, s._x_next = s._x_next, s._x
        s._tau, s._tau_next = s._tau_next, s._tau
        s.t_s += s.dt_s
        return s._x[0].copy()

    def reset(self, x0: ArrayLike, *, t0_s: float = 0.0) -> None:
        self._sim.reset(np.reshape(np.asarray(x0, float), (1, 6)), t0_s=t0_s)
