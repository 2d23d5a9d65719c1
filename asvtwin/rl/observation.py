"""The agent's observation and action, shared by the environment and the shipped policy.

Observation (float32, ``n_rays + 6``): the LiDAR "closeness" of each ray,
1 − log(1 + d)/log(1 + d_max) in [0, 1] (Meyer et al. 2020), rays at bearings
−π + 2πj/n_rays from the bow (clockwise positive, the order of
:meth:`asvtwin.sensors.LidarConfig.relative_bearings`), then six navigation features:
u/U_max, v/U_max, r/r_ref, look-ahead heading error/π, heading error/π, ε/100 m
(clipped to ±10). Lengths, speeds and times are model scale (CyberShip II); other hulls
convert by Froude similarity before calling these (:mod:`asvtwin.rl.controller`).

Action in [−1, 1]²: surge force (a0 + 1)/2 · F_u,max (forward only), yaw moment
a1 · F_r,max; no sway force (Meyer et al. 2020, Vaaler et al. 2023). A non-finite action
is replaced by :data:`SAFE_ACTION` (no thrust, no moment: the vessel coasts and slows).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from asvtwin.checks import F8 as _F8

__all__ = ["N_NAV", "R_REF", "SAFE_ACTION", "action_to_tau", "closeness", "nav_features",
           "ray_bearings"]


#: Number of navigation features after the LiDAR rays.
N_NAV = 6
#: Yaw-rate reference of the observation [rad/s] (model scale): the soft bound 0.15.
R_REF = 0.15
#: The documented safe action for NaN/inf policy outputs: zero surge force, zero moment.
SAFE_ACTION = np.array([-1.0, 0.0])


def ray_bearings(n_rays: int) -> _F8:
    """Ray bearings relative to the bow [rad], shape (n_rays,)."""
    return -np.pi + 2.0 * np.pi * np.arange(n_rays) / n_rays


def closeness(d: NDArray[np.float64], d_max: float) -> _F8:
    """1 − log(1 + d)/log(1 + d_max), d [m] clipped to [0, d_max]."""
    return 1.0 - np.log1p(np.clip(d, 0.0, d_max)) / np.log1p(d_max)


def nav_features(nu: _F8, look_err: _F8, head_err: _F8, eps: _F8, U_max: float) -> _F8:
    """The six navigation features for n ships: ``nu`` (n, 3), the rest (n,)."""
    out = np.empty((nu.shape[0], N_NAV))
    out[:, 0] = nu[:, 0] / U_max
    out[:, 1] = nu[:, 1] / U_max
    out[:, 2] = nu[:, 2] / R_REF
    out[:, 3] = look_err / np.pi
    out[:, 4] = head_err / np.pi
    out[:, 5] = eps / 100.0
    return np.clip(out, -10.0, 10.0)


def action_to_tau(a: ArrayLike, tau_max: _F8) -> tuple[_F8, NDArray[np.bool_]]:
    """Actions (n, 2) → commanded thrust u_L (n, 3) [N, N, Nm] and which were non-finite.

    Non-finite rows become :data:`SAFE_ACTION`; finite ones are clipped to [−1, 1].
    """
    a = np.asarray(a, dtype=np.float64).reshape(-1, 2)
    bad: NDArray[np.bool_] = np.asarray(~np.isfinite(a).all(axis=1))
    a = np.where(bad[:, None], SAFE_ACTION, np.clip(np.nan_to_num(a), -1.0, 1.0))
    tau = np.zeros((a.shape[0], 3))
    tau[:, 0] = 0.5 * (a[:, 0] + 1.0) * tau_max[0]
    tau[:, 2] = a[:, 1] * tau_max[2]
    return tau, bad
