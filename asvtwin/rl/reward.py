"""The paper's reward, term by term (section "Reward Function").

.. math::

    r_{path} = \\Big(\\frac{u}{U_{max}}\\cos\\bar\\psi + \\gamma_r\\Big)
               \\Big(e^{-\\gamma_\\epsilon|\\epsilon|} + \\gamma_r\\Big) - \\gamma_r^2

    r_{colav} = -\\frac{\\sum_i \\frac{1}{1+\\gamma_\\theta|\\theta_i|} e^{-\\gamma_d d_i}}
                      {\\sum_i \\frac{1}{1+\\gamma_\\theta|\\theta_i|}}

    r_{PSF} = -\\gamma_{PSF} \\frac{\\lVert u_L - u_0 \\rVert}{\\lVert u_{max} \\rVert}

    r = r_{collision} \\text{ if collision, else }
        \\lambda r_{path} + (1-\\lambda) r_{colav} + r_{PSF} + r_{exists}

Every function takes arrays over environments (leading axis n) or scalars and uses the
paper's symbols. Coefficients live in :class:`asvtwin.rl.config.RewardConfig`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from asvtwin.checks import F8 as _F8
from asvtwin.rl.config import RewardConfig

__all__ = ["RewardTerms", "r_colav", "r_path", "r_psf", "reward"]



def r_path(u: ArrayLike, U_max: float, psi_bar: ArrayLike, epsilon: ArrayLike, *,
           gamma_r: float, gamma_e: float) -> _F8:
    """Path-following reward: velocity factor times CTE factor, minus γ_r².

    ``u`` surge speed [m/s], ``U_max`` top speed [m/s], ``psi_bar`` heading error to the
    path tangent [rad], ``epsilon`` cross-track error [m].
    """
    u, psi_bar, epsilon = (np.asarray(a, dtype=float) for a in (u, psi_bar, epsilon))
    velocity = u / U_max * np.cos(psi_bar) + gamma_r
    cte = np.exp(-gamma_e * np.abs(epsilon)) + gamma_r
    return velocity * cte - gamma_r**2


def r_colav(d: ArrayLike, theta: ArrayLike, *, gamma_theta: float, gamma_d: float) -> _F8:
    """Collision-avoidance reward: minus the angle-weighted mean of exp(−γ_d d_i).

    ``d`` (..., n) LiDAR distances [m] (the range where nothing returned), ``theta`` (n,)
    ray bearings relative to the bow [rad]. Returns shape ``d.shape[:-1]``.
    """
    d = np.asarray(d, dtype=float)
    w = 1.0 / (1.0 + gamma_theta * np.abs(np.asarray(theta, dtype=float)))
    return -(np.exp(-gamma_d * d) @ w) / w.sum()


def r_psf(u_L: ArrayLike, u_0: ArrayLike, u_max: ArrayLike, *, gamma_psf: float) -> _F8:
    """Safety-filter reward: minus γ_PSF ‖u_L − u_0‖ / ‖u_max‖ (the paper's equation).

    ``u_L``, ``u_0`` (..., 3) learner and filtered inputs [N, N, Nm]; ``u_max`` (3,) the
    largest input magnitudes [N, N, Nm]. All components enter the one Euclidean norm: the
    predecessor's code divided only part of the yaw term (an operator-precedence bug that
    made it ~200 times too small); this is the equation as printed.
    """
    delta_u = np.asarray(u_L, dtype=float) - np.asarray(u_0, dtype=float)
    return -gamma_psf * np.linalg.norm(delta_u, axis=-1) / np.linalg.norm(u_max)


class RewardTerms:
    """The terms of one step for n environments, as arrays of shape (n,)."""

    __slots__ = ("r_colav", "r_collision", "r_exists", "r_path", "r_psf", "total")

    def __init__(self, total: _F8, r_path: _F8, r_colav: _F8, r_psf: _F8, r_exists: _F8,
                 r_collision: _F8) -> None:
        self.total = total
        self.r_path = r_path
        self.r_colav = r_colav
        self.r_psf = r_psf
        self.r_exists = r_exists
        self.r_collision = r_collision


def reward(cfg: RewardConfig, *, u: ArrayLike, U_max: float, psi_bar: ArrayLike,
           epsilon: ArrayLike, d: ArrayLike, theta: ArrayLike, u_L: ArrayLike,
           u_0: ArrayLike, u_max: ArrayLike, collision: ArrayLike) -> RewardTerms:
    """The whole reward for n environments and each term (zeroed where it does not count).

    On a colliding step the reward is r_collision alone (the other terms are reported as
    0); otherwise λ r_path + (1 − λ) r_colav + r_PSF + r_exists.
    """
    hit = np.asarray(collision, dtype=bool)
    rp = r_path(u, U_max, psi_bar, epsilon, gamma_r=cfg.gamma_r, gamma_e=cfg.gamma_e)
    rc = r_colav(d, theta, gamma_theta=cfg.gamma_theta, gamma_d=cfg.gamma_d)
    rf = r_psf(u_L, u_0, u_max, gamma_psf=cfg.gamma_psf)
    rp, rc, rf = (np.broadcast_to(a, hit.shape) for a in (rp, rc, rf))
    keep = ~hit
    lam = cfg.lambda_
    r_p = np.where(keep, lam * rp, 0.0)
    r_c = np.where(keep, (1.0 - lam) * rc, 0.0)
    r_f = np.where(keep, rf, 0.0)
    r_e = np.where(keep, cfg.r_exists, 0.0)
    r_x = np.where(hit, cfg.r_collision, 0.0)
    return RewardTerms(r_p + r_c + r_f + r_e + r_x, r_p, r_c, r_f, r_e, r_x)
