"""The trained agent as a twin controller: ``RlController.act(t_s, nav_state, route, scan)``.

The policy (:class:`asvtwin.rl.policy.NumpyPolicy`, numpy only, no torch) was trained on
CyberShip II at model scale (length L_m = 1.255 m, one action per 1 s). Any other hull of
the same shape — the twin's 88 m :func:`asvtwin.vessel.cybership2_full_scale` — uses it
through Froude similarity with the length ratio s = L / L_m:

- positions, routes and LiDAR ranges are divided by s; speeds u, v by √s; the yaw rate r
  is multiplied by √s (time scales by √s);
- the policy acts every dt·√s seconds of the ship's time (zero-order hold between);
- its action is mapped onto the ship's own actuator limits ([0, F_u,max] surge, ±F_r,max
  yaw): Froude-scaled forces are exactly the limits' ratio, so the dimensionless
  closed loop is the same at every scale (measured in tests/rl/test_controller.py: the
  full-scale trajectory divided by s matches the model-scale one).

The LiDAR scan is resampled to the policy's rays (nearest ray, circularly); without a
scan every ray reads free. The route is followed as a polyline from its first waypoint;
the cross-track error and both heading errors come from the same kernel as training.
"""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from asvtwin.errors import StateError
from asvtwin.rl.kernels import path_features
from asvtwin.rl.observation import action_to_tau, closeness, nav_features, ray_bearings
from asvtwin.rl.policy import NumpyPolicy
from asvtwin.vessel.params import VesselParams

__all__ = ["DEFAULT_POLICY", "RlController", "default_policy_path"]

#: File name of the policy shipped in ``asvtwin/rl/policies/``.
DEFAULT_POLICY = "cybership2_path_colav.npz"


def default_policy_path() -> Path:
    """Path of the shipped policy."""
    return Path(str(resources.files("asvtwin.rl") / "policies" / DEFAULT_POLICY))


class RlController:
    """The PPO agent as a controller for any Froude-similar hull.

    Parameters
    ----------
    params : VesselParams
        The own ship (its length sets the Froude scale, its actuator limits the output).
    policy_path : path, optional
        A policy ``.npz``; default the shipped one.

    Examples
    --------
    >>> import numpy as np
    >>> from asvtwin.vessel import cybership2_full_scale
    >>> ctl = RlController(cybership2_full_scale())
    >>> route = np.array([[0.0, 0.0], [3000.0, 0.0]])
    >>> tau = ctl.act(0.0, np.array([0, 0, 0, 3.0, 0, 0]), route, None)
    >>> tau.shape, bool(tau[0] >= 0.0), float(tau[1])
    ((3,), True, 0.0)
    """

    def __init__(self, params: VesselParams, *, policy_path: str | Path | None = None
                 ) -> None:
        self.params = params
        self.policy_path = Path(policy_path) if policy_path else default_policy_path()
        self.policy = NumpyPolicy.load(self.policy_path)
        meta: dict[str, Any] = self.policy.meta
        self.n_rays = int(meta["n_rays"])
        self.range_m = float(meta["lidar_range_m"])  # model scale
        self.lookahead_m = float(meta["lookahead_m"])
        self.U_max = float(meta["U_max"])
        self.scale = params.length / float(meta["reference_length_m"])
        self.hold_s = float(meta["dt_s"]) * math.sqrt(self.scale)
        self.tau_max = np.asarray(params.actuators.tau_max, dtype=float)
        self.rel = ray_bearings(self.n_rays)
        self._t_next = -math.inf
        self._u = np.zeros(3)
        self._idx = np.zeros(1, dtype=np.int64)
        self._route_key: bytes | None = None

    def reset(self) -> None:
        """Forget the held action and the progress along the route."""
        self._t_next = -math.inf
        self._idx[:] = 0
        self._route_key = None

    def observation(self, nav_state: ArrayLike, route: ArrayLike, scan: Any | None
                    ) -> NDArray[np.float32]:
        """The policy's observation (model scale) for a ship of this controller's size."""
        x = np.asarray(nav_state, dtype=float).reshape(-1)
        if x.shape != (6,) or not np.isfinite(x).all():
            raise StateError(f"nav_state must be a finite (6,) [x, y, psi, u, v, r], "
                             f"actually: {x!r}")
        rt = np.asarray(route, dtype=float)
        if rt.ndim != 2 or rt.shape[1] != 2 or len(rt) < 2 or not np.isfinite(rt).all():
            raise StateError(f"route must be a finite (k, 2) array with k >= 2 waypoints "
                             f"[north_m, east_m], actually shape {rt.shape}")
        key = rt.tobytes()
        if key != self._route_key:
            self._route_key = key
            self._idx[:] = 0
        s, sq = self.scale, math.sqrt(self.scale)
        # Froude similarity: lengths / s, speeds / √s, yaw rate · √s
        pos = x[None, :2] / s
        path = np.ascontiguousarray(rt[None] / s)
        s_cum = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path[0], axis=0).T))])
        feat = np.empty((1, 5))
        path_features(pos, x[2:3].copy(), path, s_cum[None].copy(), self._idx, len(rt),
                      self.lookahead_m, feat)
        nu = np.array([[x[3] / sq, x[4] / sq, x[5] * sq]])
        d = np.full(self.n_rays, self.range_m)
        if scan is not None and len(scan.ranges_m):
            rel_scan = np.asarray(scan.angles_rad) - x[2]
            rng = np.where(np.isfinite(scan.ranges_m), np.asarray(scan.ranges_m) / s,
                           self.range_m)
            diff = np.abs((self.rel[:, None] - rel_scan[None, :] + np.pi) % (2 * np.pi)
                          - np.pi)
            d = np.minimum(rng[np.argmin(diff, axis=1)], self.range_m)
        obs = np.empty(self.n_rays + 6, dtype=np.float32)
        obs[: self.n_rays] = closeness(d, self.range_m)
        obs[self.n_rays:] = nav_features(nu, feat[:, 3], feat[:, 2], feat[:, 1], self.U_max)[0]
        return obs

    def act(self, t_s: float, nav_state: ArrayLike, route: ArrayLike, scan: Any | None
            ) -> NDArray[np.float64]:
        """The commanded thrust u_L (3,) [N, N, Nm] at ``t_s`` (held between decisions)."""
        if t_s >= self._t_next - 1e-9:
            obs = self.observation(nav_state, route, scan)
            tau, _ = action_to_tau(self.policy.act(obs)[None], self.tau_max)
            self._u = tau[0]
            self._t_next = t_s + self.hold_s
        return self._u.copy()
