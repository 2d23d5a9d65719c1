"""Batched certification of the learner's input across Monte Carlo futures.

The safety filter's first step (:meth:`asvtwin.control.SafetyFilter.filter`) re-simulates
"u_L now, then coast" on its planning model and keeps u_L when that plan is certified: no
solve. In a what-if question most filter calls end there, yet each one pays the filter's
per-call preparation (obstacle prediction with covariance inflation, explanation) of about
a millisecond. :class:`ULCertifier` does that step for all due futures of a question at
once: the targets' covariance inflation is computed once per question (it depends only
on the fork's covariances and the stage times, not on the draw), the predicted centres are
vectorised over futures, and each plan is rolled out and certified by the filter's own
compiled kernels (:func:`asvtwin.control.kernels.rollout` and
:func:`~asvtwin.control.kernels.certify`, the same arithmetic and the same model).

It is *stricter* than the filter, never looser: it applies the filter's strict rule
(every margin ≥ 0 over stages 1..N, the terminal ellipsoid within 5 %, no margin negative
at stage 0) but gives static obstacles and the coast no braking credit at stage N (they
need d_safe + d_f there). So a future it certifies is one the filter would have answered
with u_L itself; a future it does not certify goes to the filter, which may still keep
u_L. ``tests/whatif/test_certify.py`` checks this against ``SafetyFilter.filter`` at both
hull scales.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.control import SafetyFilter
from asvtwin.control.certification import TERM_TOL
from asvtwin.control.kernels import certify, rollout
from asvtwin.control.obstacles import covariance_inflation

__all__ = ["ULCertifier"]


def _strictly_certified(low: float, term: float, finite: bool, margins: _F8) -> bool:
    """The strict rule of both checks: finite, every margin ≥ 0 (no tolerance, no recovery
    from a start inside d_safe), the end within the filter's terminal tolerance."""
    return (finite and low >= 0.0 and term >= -TERM_TOL
            and not (margins.shape[1] and margins[0].min() < 0.0))


class ULCertifier:
    """Certify "u_L now, then coast" for many futures against their own targets.

    Parameters
    ----------
    psf : SafetyFilter
        The filter whose model, horizon, d_safe, d_f and terminal set are used.
    hull_radii_m : ndarray (m,)
        Targets' hull radii [m] (as given to ``MovingObstacles``).
    position_cov : ndarray (m, 2, 2)
        Targets' position covariance at the call [m²] (the fork's, the same for every
        future).
    process_noise : float
        Growth of that covariance per second of prediction [m²/s] (as given to
        ``MovingObstacles.constant_velocity``).
    confidence : float
        Mass of the inflated circle (the filter's default 0.95).
    """

    def __init__(self, psf: SafetyFilter, hull_radii_m: _F8, position_cov: _F8,
                 process_noise: float, confidence: float = 0.95) -> None:
        cfg = psf.config
        self.N, self.dt_s = cfg.N, cfg.dt_s
        self.t_stage = np.arange(self.N + 1) * self.dt_s
        m = len(hull_radii_m)
        r = np.repeat(np.asarray(hull_radii_m, float)[None, :], self.N + 1, axis=0)
        if m:
            cov = (np.asarray(position_cov, float)[:, None]
                   + process_noise * self.t_stage[None, :, None, None] * np.eye(2))
            r = r + covariance_inflation(cov, confidence).T
        # moving obstacles need d_safe only at stage N (the filter subtracts d_f there)
        r[self.N] -= psf.d_f_m
        self.radii = np.ascontiguousarray(r)  # (N+1, m)
        self.clear = np.full(self.N + 1, psf.d_safe_m)
        self.clear[self.N] += psf.d_f_m  # eq. (f), without the braking credit (stricter)
        self.P_f = np.ascontiguousarray(psf.terminal_set.P_f)
        self.coef = np.ascontiguousarray(psf.params.packed())
        self.substeps = int(psf.spec.rk4_substeps)
        self.u_lb, self.u_ub = psf.u_lb, psf.u_ub
        self._X = np.empty((self.N + 1, 6))

    def certified(self, x: _F8, u_L: _F8, d: _F8, positions: _F8, velocities: _F8,
                  segments: list[_F8], tails: list[_F8 | None] | None = None
                  ) -> tuple[NDArray[np.bool_], list[_F8 | None]]:
        """Whether a plan starting with u_L is certified, per future, and that plan.

        ``x`` (F, 6) own states, ``u_L`` (F, 3) learner inputs (clipped to the actuator
        range as the filter does), ``d`` (F, 3) disturbances, ``positions`` and
        ``velocities`` (F, m, 2) the targets now [m, m/s], ``segments`` F arrays (k, 4)
        of coast segments near each future. ``tails`` (optional, per future): the rest of
        the last certified plan, shifted to now, (N, 3) with row 0 ignored; tried first,
        as the filter does, then "u_L now, then coast". Returns (certified (F,), the
        certified input sequence (N, 3) or None per future).
        """
        F = x.shape[0]
        out = np.zeros(F, dtype=bool)
        plans: list[_F8 | None] = [None] * F
        if F == 0:
            return out, plans
        # predicted centres of every future's targets: (F, N+1, m, 2)
        centres = (positions[:, None, :, :]
                   + self.t_stage[None, :, None, None] * velocities[:, None, :, :])
        X = self._X
        uL = np.clip(u_L, self.u_lb, self.u_ub)
        for f in range(F):
            segs = np.ascontiguousarray(segments[f], dtype=float).reshape(-1, 4)
            margins = np.empty((self.N + 1, self.radii.shape[1] + segs.shape[0]))
            tail = None if tails is None else tails[f]
            for U in ((tail, np.zeros((self.N, 3))) if tail is not None
                      else (np.zeros((self.N, 3)),)):
                U = np.array(U, dtype=float)
                U[0] = uL[f]
                rollout(np.ascontiguousarray(x[f]), U, np.ascontiguousarray(d[f]),
                        self.coef, self.dt_s, self.substeps, X)
                low, term, finite = certify(X, np.ascontiguousarray(centres[f]), self.radii,
                                            segs, self.clear, self.P_f, margins)
                if _strictly_certified(low, term, finite, margins):
                    out[f] = True
                    plans[f] = U
                    break
        return out, plans

    def first_certified(self, x: _F8, d: _F8, positions: _F8, velocities: _F8,
                        segments: _F8, plans: list[_F8]) -> int:
        """Index of the first of ``plans`` (each (N, 3), applied from now) certified for
        one future (``x`` (6,), ``d`` (3,), ``positions``/``velocities`` (m, 2),
        ``segments`` (k, 4)) by the same strict rule, or −1."""
        centres = np.ascontiguousarray(positions[None, :, :]
                                       + self.t_stage[:, None, None] * velocities[None, :, :])
        segs = np.ascontiguousarray(segments, dtype=float).reshape(-1, 4)
        margins = np.empty((self.N + 1, self.radii.shape[1] + segs.shape[0]))
        X = self._X
        x = np.ascontiguousarray(x, dtype=float)
        d = np.ascontiguousarray(d, dtype=float)
        for k, U in enumerate(plans):
            rollout(x, np.ascontiguousarray(U, dtype=float), d, self.coef, self.dt_s,
                    self.substeps, X)
            low, term, finite = certify(X, centres, self.radii, segs, self.clear, self.P_f,
                                        margins)
            if _strictly_certified(low, term, finite, margins):
                return k
        return -1
