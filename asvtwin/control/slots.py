"""The solver's obstacle slots: which circles and coast segments the OCP sees, and its
stage parameters.

The OCP (:mod:`asvtwin.control.backends.ocp`) has a fixed number of circle and segment
slots (``PsfConfig.n_circles``, ``n_segments``); the filter certifies every obstacle, but
the solver sees those that come nearest to the predicted paths (the learner's plan and
the warm start), stage by stage for moving circles. Unused slots hold far-away dummies.
Stage N asks what the certification asks, as a pair the solver cannot trade against each
other: the end speed bounded, ν_Nᵀ P_f ν_N ≤ V̂ (by a box inside that ellipsoid, linear
in the state), and the braking distance from that speed, d_safe + d_f √V̂, beyond static
obstacles and the coast
(:meth:`asvtwin.control.certification.Certifier.terminal_requirement`); d_safe from
moving ones. V̂ is the most the room at the warm start's end allows.
"""

from __future__ import annotations

import logging
import math

import numpy as np
from numpy.typing import NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.control.backends.ocp import BOX_OFF, DUMMY_DISTANCE_FACTOR, OcpSpec
from asvtwin.control.certification import Certifier
from asvtwin.control.obstacles import CoastSegments

__all__ = ["SolverSlots"]

log = logging.getLogger("asvtwin.control.psf")


class SolverSlots:
    """The stage-parameter buffer (N+1, n_p) of one filter, rewritten every call:
    ``[d̂ (3), clearance (1), circles (3 n_circles), segments (4 n_segments), box (1)]``."""

    #: Smallest end-speed bound V̂ given to the solver: with ν_N = 0 demanded exactly the
    #: quadratic constraint's gradient vanishes at the answer (stage N then needs
    #: d_safe + d_f √V̂ = d_safe + 0.1 d_f).
    V_MIN = 0.01

    def __init__(self, spec: OcpSpec, length_m: float, cert: Certifier) -> None:
        self.spec, self.cert, self.length_m = spec, cert, length_m
        N, nc = spec.N, spec.n_circles
        far = DUMMY_DISTANCE_FACTOR * length_m
        self.P = np.zeros((N + 1, spec.n_p))
        # the solver plans with the certification tolerance as margin (eq. (e)/(f))
        self.P[:, 3] = cert.clear + cert.tol_m
        self.P[:, -1] = BOX_OFF  # the end box: off (eq. (g) as published) until set_terminal
        self._seg_cols = slice(4 + 3 * nc, 4 + 3 * nc + 4 * spec.n_segments)
        self.circ = self.P[:, 4: 4 + 3 * nc].reshape(N + 1, nc, 3)
        if not np.shares_memory(self.circ, self.P):  # pragma: no cover - numpy layout
            raise AssertionError("the circle slots must be a view of the stage parameters")
        self._dummy_circle = np.stack([np.full(nc, far),
                                       far * (1 + 0.01 * np.arange(nc))], axis=1)
        self._dummy_segment = np.array([-far, -far, -far, -far + 1.0])
        self._r_end = np.zeros(nc)  # stage N's circle radii as given (per call)
        self._V_floor: float | None = None  # the lowest reachable end speed (per call)
        self._moving = np.zeros(nc, dtype=bool)  # which slots hold moving circles
        self._logged = False

    def fill(self, x: _F8, d_hat: _F8, centres: _F8, radii: _F8, segs: _F8,
             paths: list[_F8], nu_end: _F8, V_floor: float | None = None,
             moving: NDArray[np.bool_] | None = None,
             ) -> tuple[_F8, NDArray[np.intp], NDArray[np.intp]]:
        """Stage parameters (N+1, n_p) (an internal buffer: backends copy it) and the
        indices of the circles and segments that got a slot: those that come nearest to
        the predicted ``paths`` (each (N+1, 2), the last one the warm start's),
        stage by stage for moving circles. ``nu_end``: the warm start's end velocity;
        ``V_floor``: the end speed ν_Nᵀ P_f ν_N of coasting from now, for stage N's
        bound (:meth:`set_terminal`; None: eq. (f)/(g) as published, V̂ = 1 and the
        full d_f); ``moving``: which circles move."""
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
            P[:, self._seg_cols] = sg.ravel()
        self._r_end = circ[-1, :, 2].copy()
        self._moving[:] = False
        if used and moving is not None:
            self._moving[:used] = moving[ci] if m > nc else moving
        self._V_floor = V_floor
        self.set_terminal(paths[-1][-1], nu_end)
        return P, ci, si

    def set_terminal(self, p_end: _F8, nu_end: _F8) -> float:
        """Stage N's end-speed bound V̂ and clearance for the warm start ending at
        position ``p_end`` with velocity ``nu_end``. Returns V̂.

        The certification asks stage N for d_safe + d_f √V_N from static obstacles and
        the coast (the braking credit) with V_N the plan's own end speed. Asking the
        solver for d_f √V_N with V_N taken from the warm start failed whenever SQP-RTI's
        one QP moved the end speed (V_N 0.05 in the guess, 0.45 in the answer): the
        answer then missed the requirement at its end while its path was clear
        (benchmarks/psf.py, ``steered``: 30 fallbacks in 300 calls). So the end speed is
        bounded, ν_Nᵀ P_f ν_N ≤ V̂, and the clearance asked is the braking distance from
        V̂: a plan that meets both is certified at its end, whatever speed it ends with.

        V̂ is the largest value the room at the warm start's end leaves (its distance
        to the nearest static slot: a guess certified at its end fits), but not below
        the slowest end the ship is known to reach, the lower of the warm start's and
        coasting from now (a ship without astern thrust cannot end slower; with V̂ from
        the room alone 265 of the 300 steered calls fell back, the answers ending at
        V_N ≈ 0.27 against V̂ ≈ 0.14; with the warm start's V_N as the floor it
        ratcheted up to 1 within two calls); at least :attr:`V_MIN`, at most 1. In open
        water V̂ = 1 and the box is off: eq. (f)/(g) as published. Moving circles keep
        d_safe at stage N (the filter gives them radius − d_f there, and their slot's
        radius grows back by what the clearance gives up).
        """
        c = self.cert
        V_hat = 1.0
        if self._V_floor is not None:
            V_guess = float(nu_end @ c.P_f @ nu_end)
            V_hat = min(max(self._room_bound(p_end), min(self._V_floor, V_guess), self.V_MIN),
                        1.0)
        extra = c.terminal_requirement_at(V_hat)
        self.P[-1, 3] = c.d_safe_m + extra + c.tol_m
        self.P[-1, -1] = math.sqrt(V_hat) if V_hat < 1.0 else BOX_OFF
        self.circ[-1, :, 2] = self._r_end + np.where(self._moving, c.d_f_m - extra, 0.0)
        return V_hat

    def _room_bound(self, p_end: _F8) -> float:
        """The largest V̂ ≤ 1 whose braking distance fits between ``p_end`` and the nearest
        static obstacle or coast segment in a slot (beyond d_safe and the tolerance)."""
        c = self.cert
        room = np.inf
        static = ~self._moving
        if static.any():
            circ = self.circ[-1, static]
            room = float(np.min(np.hypot(circ[:, 0] - p_end[0], circ[:, 1] - p_end[1])
                                - circ[:, 2]))
        if self.spec.n_segments:
            segs = self.P[-1, self._seg_cols].reshape(-1, 4)
            room = min(room, float(CoastSegments(segs).distances(p_end[None, :]).min()))
        return c.speed_bound_for(room - c.d_safe_m - c.tol_m)
