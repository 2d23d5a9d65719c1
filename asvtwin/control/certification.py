"""Certification of a re-simulated plan: its obstacle margins, the braking credit at its
end, and the verdict (normal or recovery rule) with the reason a navigator reads.

A plan is *certified* when, simulated on the planning model from the present state, it
keeps d_safe from every obstacle at stages 1..N−1 (within the tolerance ``tol_m``) and
ends inside the terminal ellipsoid ν_Nᵀ P_f ν_N ≤ 1 (within 5 %) with d_safe + d_f √V_N
of room from static obstacles and the coast, V_N = ν_Nᵀ P_f ν_N (Wabersich & Zeilinger
2021, eq. (f) with the braking credit: from ν_N the braking backup travels at most
d_f √V_N, see :mod:`asvtwin.control.terminal_set`). Inside d_safe the *recovery* rule
applies: no margin falls below where it starts, and every margin is restored by stage N.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.control.kernels import certify

__all__ = ["TERM_TOL", "Certifier"]

TERM_TOL = 0.05  # terminal ellipsoid tolerance of the certification (5 %)


class Certifier:
    """Margins and verdicts for one filter (constants fixed, per-call state set by
    :meth:`start_call`).

    Parameters
    ----------
    N : int
        Stages.
    d_safe_m, d_f_m, tol_m : float
        Safety distance, terminal distance d_f and certification tolerance [m].
    P_f : ndarray, shape (3, 3)
        The terminal ellipsoid.
    surge_range : float
        Surge thrust range u_ub − u_lb [N]: the braking credit fades out as the
        estimated planar disturbance grows to 10 % of it.
    """

    def __init__(self, N: int, d_safe_m: float, d_f_m: float, tol_m: float, P_f: _F8,
                 surge_range: float) -> None:
        self.d_safe_m, self.d_f_m, self.tol_m = d_safe_m, d_f_m, tol_m
        self.P_f = np.ascontiguousarray(P_f)
        self.clear = np.full(N + 1, d_safe_m)
        self.clear[N] += d_f_m  # eq. (f)
        self._surge_range = surge_range
        #: columns of static obstacles and coast segments in the margins (per call)
        self.static_cols: NDArray[np.bool_] | None = None
        #: share of the braking credit the disturbance estimate leaves (per call)
        self.credit_factor = 1.0

    def start_call(self, moving: NDArray[np.bool_], n_segments: int, d_hat: _F8) -> None:
        """Set the per-call state: which margin columns are static, and the credit.

        The braking credit holds for the nominal model: a disturbance that keeps pushing
        the stopped ship (a current, wind) voids it. It fades out linearly as the
        estimated planar force d̂ grows to 10 % of the surge thrust range (measured: with
        the full credit under a 0.085 m/s current, 4 of 10 model-scale runs onto a coast
        ended inside d_safe; without it 1 of 10)."""
        self.static_cols = np.concatenate([~moving, np.ones(n_segments, dtype=bool)])
        d_planar = math.hypot(float(d_hat[0]), float(d_hat[1]))
        self.credit_factor = min(max(1.0 - d_planar / (0.1 * self._surge_range), 0.0), 1.0)

    def terminal_requirement(self, nu_end: _F8) -> float:
        """What stage N must keep beyond d_safe from static obstacles [m] for a plan
        ending at velocity ``nu_end``: d_f (1 − c (1 − √V_N)), c the credit factor."""
        return self._requirement(float(nu_end @ self.P_f @ nu_end))

    def _requirement(self, V: float) -> float:
        """d_f (1 − c (1 − √V)) [m] for V = ν_Nᵀ P_f ν_N (clipped to [0, 1])."""
        root = math.sqrt(min(max(V, 0.0), 1.0))
        return self.d_f_m * (1.0 - self.credit_factor * (1.0 - root))

    def margins(self, X: _F8, centres: _F8, radii: _F8, segs: _F8,
                ) -> tuple[_F8, float, float, bool]:
        """Per-stage obstacle margins (N+1, m + k) [m] against the required clearance
        (d_safe; d_safe + d_f √V_N at N for static ones, eq. (e)/(f)), their minimum over
        stages 1..N (+inf without obstacles, NaN when a margin is NaN), the terminal
        margin 1 − ν_Nᵀ P_f ν_N (eq. (g)) and whether every state is finite."""
        out = np.empty((X.shape[0], centres.shape[1] + segs.shape[0]))
        low, term, finite = certify(X, np.ascontiguousarray(centres),
                                    np.ascontiguousarray(radii), np.ascontiguousarray(segs),
                                    self.clear, self.P_f, out)
        # Eq. (f) asks d_f, the braking distance from the *edge* of the terminal set. From
        # ν_N inside it the braking backup travels at most d_f √V_N (V = νᵀP_fν decays at
        # rate 2α and ‖(u, v)‖ ≤ α d_f √V, see terminal_set): a plan that ends slow needs
        # only that much beyond d_safe. Static obstacles and the coast get the credit
        # d_f (1 − √V_N) at stage N (none when V_N ≥ 1: eq. (f) as is); moving ones already
        # ask d_safe only there. Without this a full-scale ship (d_f = 527 m) within
        # d_safe + d_f of a harbour's shore had no certifiable plan even when stopping.
        static = self.static_cols
        if finite and out.shape[1] and static is not None and static.any():
            out[-1, static] += self.d_f_m - self._requirement(1.0 - float(term))
            if out.shape[0] > 1:
                low = float(np.min(out[1:]))
        return out, float(low), float(term), bool(finite)

    def terminal_clearance(self, margins: _F8, term: float) -> _F8:
        """Stage N's distance to each obstacle minus d_safe (and its radius) [m]: the
        certified margin with its terminal requirement (d_f √V_N for static obstacles and
        the coast, nothing more for moving ones) added back."""
        static = self.static_cols
        if static is None or static.shape[0] != margins.shape[1]:
            return margins[-1] + self.d_f_m
        back = self._requirement(1.0 - float(term))
        return margins[-1] + np.where(static, back, 0.0)

    def judge(self, margins: _F8, low: float, term: float, finite: bool, m0: _F8,
              strict: bool = False) -> tuple[bool, str, float]:
        """Is a re-simulated plan certified? Returns (certified, reason if not, closest
        approach margin over stages 1..N against d_safe alone [m]).

        Normal rule: every margin ≥ −tol (≥ 0 when ``strict``), terminal ellipsoid within
        5 %. Recovery rule (some stage-0 margin ``m0`` < 0): no obstacle's margin falls
        below min(its stage-0 margin, 0) − tol, and every margin is restored by stage N.
        """
        if not finite or math.isnan(low):
            return False, "plan is not finite (NaN/inf states)", -math.inf
        if margins.shape[1] == 0:
            path_low = math.inf
        else:
            path_low = min(float(margins[1:-1].min()) if margins.shape[0] > 2 else math.inf,
                           float(self.terminal_clearance(margins, term).min()))
        tol = 0.0 if strict else self.tol_m
        if m0.size and m0.min() < 0:  # recovery
            floor = np.minimum(m0, 0.0) - tol
            ok = bool(np.all(margins[1:] >= floor)) and bool(np.all(margins[-1] >= -tol))
        else:
            ok = low >= -tol
        if not ok:
            if margins.shape[0] > 2 and path_low >= -tol:
                # the path keeps d_safe: what fails is eq. (f), the room to stop at its end
                need = self._requirement(1.0 - float(term))
                short = -float(margins[-1].min())
                return False, (f"plan leaves no room to stop at its end (it ends {short:.2f} m "
                               f"short of d_safe + {need:.2f} m braking distance)"), path_low
            return False, (f"plan violates obstacle clearance (closest {path_low:+.2f} m "
                           "against d_safe)"), path_low
        if term < -TERM_TOL:
            return False, "plan ends outside the terminal set", path_low
        return True, "", path_low
