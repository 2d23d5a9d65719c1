"""The solver's obstacle slots: which circles and coast segments the OCP sees, and its
stage parameters.

The OCP (:mod:`asvtwin.control.backends.ocp`) has a fixed number of circle and segment
slots (``PsfConfig.n_circles``, ``n_segments``); the filter certifies every obstacle, but
the solver sees those that come nearest to the predicted paths (the learner's plan and
the warm start), stage by stage for moving circles. Unused slots hold far-away dummies.
Stage N asks what the certification asks: d_safe + d_f √V_N beyond static obstacles and
the coast (:meth:`asvtwin.control.certification.Certifier.terminal_requirement`), d_safe
from moving ones, with V_N the plan's own through the tangent of √V_N at the warm
start's end (:mod:`asvtwin.control.backends.ocp`: its slope and which slots are static
are stage N's last parameters).
"""

from __future__ import annotations

import logging
import math

import numpy as np
from numpy.typing import NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.control.backends.ocp import DUMMY_DISTANCE_FACTOR, OcpSpec
from asvtwin.control.certification import Certifier
from asvtwin.control.obstacles import CoastSegments

__all__ = ["SolverSlots"]

log = logging.getLogger("asvtwin.control.psf")

#: The smallest tangent point √V of stage N's credit term (its slope is c d_f / (2 s)).
MIN_ROOT_V = 0.1


class SolverSlots:
    """The stage-parameter buffer (N+1, n_p) of one filter, rewritten every call:
    ``[d̂ (3), clearance (1), circles (3 n_circles), segments (4 n_segments), a (1),
    static (n_circles)]``."""

    def __init__(self, spec: OcpSpec, length_m: float, cert: Certifier) -> None:
        self.spec, self.cert, self.length_m = spec, cert, length_m
        N, nc = spec.N, spec.n_circles
        far = DUMMY_DISTANCE_FACTOR * length_m
        self.P = np.zeros((N + 1, spec.n_p))
        # the solver plans with the certification tolerance as margin (eq. (e)/(f))
        self.P[:, 3] = cert.clear + cert.tol_m
        self._k0 = spec.credit_index  # a, then the static flags
        self.circ = self.P[:, 4: 4 + 3 * nc].reshape(N + 1, nc, 3)
        if not np.shares_memory(self.circ, self.P):  # pragma: no cover - numpy layout
            raise AssertionError("the circle slots must be a view of the stage parameters")
        self._dummy_circle = np.stack([np.full(nc, far),
                                       far * (1 + 0.01 * np.arange(nc))], axis=1)
        self._dummy_segment = np.array([-far, -far, -far, -far + 1.0])
        self._r_end = np.zeros(nc)  # stage N's circle radii as given (per call)
        self._moving = np.zeros(nc, dtype=bool)  # which slots hold moving circles
        self._logged = False

    def fill(self, x: _F8, d_hat: _F8, centres: _F8, radii: _F8, segs: _F8,
             paths: list[_F8], nu_end: _F8 | None = None,
             moving: NDArray[np.bool_] | None = None,
             ) -> tuple[_F8, NDArray[np.intp], NDArray[np.intp]]:
        """Stage parameters (N+1, n_p) (an internal buffer: backends copy it) and the
        indices of the circles and segments that got a slot: those that come nearest to
        the predicted ``paths`` (each (N+1, 2)), stage by stage for moving circles.
        ``nu_end``: the warm start's end velocity, where stage N's requirement is
        exact (:meth:`set_terminal`); ``moving``: which circles move (default: none)."""
        s = self.spec
        m, k = centres.shape[1], segs.shape[0]
        ci = np.arange(m)
        if m > s.n_circles:
            gap = np.min([np.linalg.norm(centres - p[:, None, :], axis=2) for p in paths],
                         axis=0) - radii
            ci = np.sort(np.argsort(gap.min(axis=0))[: s.n_circles])
        si = np.arange(k)
        if k > s.n_segments:
            pts = np.concatenate([p[::2] for p in paths] + [x[None, :2]])
            dist = CoastSegments(segs).distances(pts).min(axis=0)
            si = np.sort(np.argsort(dist)[: s.n_segments])
        if (m > s.n_circles or k > s.n_segments) and not self._logged:
            log.info("safety filter: %d circles / %d segments given, the %d / %d nearest to "
                     "the predicted path go to the solver, all are certified", m, k,
                     s.n_circles, s.n_segments)
            self._logged = True
        P = self.P  # column 3 (clearance, eq. (e)/(f)): constant but at stage N
        P[:, 0:3] = d_hat
        nc, used = s.n_circles, len(ci)
        circ = self.circ  # a view of P's circle slots
        if used < nc:  # far-away dummies in the unused slots
            circ[:, used:, 0:2] = self._dummy_circle[used:] + x[:2]
            circ[:, used:, 2] = self.length_m
        if used:
            sel = slice(None) if m <= nc else ci
            circ[:, :used, 0:2] = centres[:, sel]
            circ[:, :used, 2] = radii[:, sel]
        if s.n_segments:
            sg = np.empty((s.n_segments, 4))
            sg[len(si):] = self._dummy_segment + x[[0, 1, 0, 1]]
            sg[: len(si)] = segs[si]
            P[:, 4 + 3 * nc: 4 + 3 * nc + 4 * s.n_segments] = sg.ravel()
        self._r_end = circ[-1, :, 2].copy()
        self._moving[:] = False
        if used and moving is not None:
            self._moving[:used] = moving[ci] if m > nc else moving
        # stage N's credit applies to the static circles' slots (and every segment)
        P[-1, self._k0 + 1:] = 0.0
        P[-1, self._k0 + 1: self._k0 + 1 + used] = ~self._moving[:used]
        self.set_terminal(nu_end)
        return P, ci, si

    def set_terminal(self, nu_end: _F8 | None) -> None:
        """Stage N's clearance and the slope a of its credit term, for a warm start
        ending at velocity ``nu_end`` (None: at rest).

        The solver is asked what the certification asks: d_safe + d_f (1 − c) +
        c d_f √V_N beyond the static obstacles and the coast (the braking credit, faded
        by the disturbance estimate: c), through the tangent of √V_N at the warm start's
        V = s² (s ≥ :data:`MIN_ROOT_V`): exact there, larger elsewhere; d_safe from moving
        circles (the filter gives them radius − d_f at stage N: their slot's radius grows
        back by what the clearance gives up, and their credit term is off). With the
        full d_f the OCP was often infeasible among static obstacles where a slow-ending
        plan certifies (benchmarks/psf.py: 4 fallbacks in 300 calls); with a
        requirement fixed from the warm start's end speed the solver ended moving beside
        a shore and its plans failed certification at stage N (a model-scale ship
        stopped 2 m from a headland stayed there for 170 s, both backends)."""
        c, P = self.cert, self.P
        credit = c.credit_factor * c.d_f_m
        V = 0.0 if nu_end is None else float(nu_end @ c.P_f @ nu_end)
        s = min(max(math.sqrt(max(V, 0.0)), MIN_ROOT_V), 1.0)
        base = c.d_f_m - credit + 0.5 * credit * s  # what stage N asks beyond d_safe at V = 0
        P[-1, 3] = c.d_safe_m + base + c.tol_m
        P[-1, self._k0] = 0.5 * credit / s
        self.circ[-1, :, 2] = self._r_end + np.where(self._moving, c.d_f_m - base, 0.0)
