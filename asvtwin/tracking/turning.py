"""Turning targets: a turn rate estimated from a track's course history, and the
constant-turn path it predicts.

The tracker's constant-velocity (CV) model predicts a turning vessel straight on: over the
full-scale safety filter's 209 s horizon a vessel turning at 0.8°/s (a 65 m ship on a
looped route) comes round by 167° while its CV prediction runs off along the tangent. In
the twin's benchmark scene that vessel closed on the own ship from the side its
prediction had left, and hit it. A CV Kalman filter carries no turn rate, so it is
estimated here, outside the filter, from the course of the track's velocity sampled at
the safety filter's calls: the least-squares slope of the unwrapped course over a window
(Bar-Shalom, Li & Kirubarajan 2001, "Estimation with Applications to Tracking and
Navigation", ch. 11: the coordinated-turn model; the slope stands in for its turn-rate
state). A track counts as turning when the slope is both large (|ω| ≥ ``min_rate``) and
well determined (≥ ``min_sigmas`` standard errors), over at least ``min_span_s``, at a
speed where the course means something (≥ ``min_speed_m_s``).

The turn is a hypothesis *beside* the CV prediction, not instead of it: a vessel may
straighten out at any time. The twin gives the safety filter both paths of a turning
track as obstacles, the arc ending after a 90° turn (a vessel turns onto a new course;
:class:`asvtwin.twin.components.FilterStage`).
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np
from numpy.typing import ArrayLike

from asvtwin.checks import F8 as _F8
from asvtwin.errors import ParameterError

__all__ = ["TurnRateEstimator", "constant_turn_positions"]


class TurnRateEstimator:
    """Turn rate per track id from its course history.

    Parameters
    ----------
    window_s : float
        Course samples older than this are forgotten [s].
    min_span_s : float
        A rate needs samples spanning at least this long [s].
    min_speed_m_s : float
        Samples slower than this carry no course and are not kept [m/s].
    min_rate : float
        Smallest turn rate reported [rad/s] (default 0.5°/s: 105° over the full-scale
        filter's 209 s horizon). With 0.17°/s the twin's harbour approach failed: the
        outbound liner's course corrections (0.2–0.34°/s) and a straight boat's track
        noise (0.18°/s) counted as turns, and the arcs closed the approach.
    min_sigmas : float
        The slope must exceed this many of its standard errors.
    forget_s : float
        A track id not updated for this long is dropped [s].
    """

    def __init__(self, *, window_s: float = 30.0, min_span_s: float = 10.0,
                 min_speed_m_s: float = 0.5, min_rate: float = math.radians(0.5),
                 min_sigmas: float = 3.0, forget_s: float = 60.0) -> None:
        for name, v in (("window_s", window_s), ("min_span_s", min_span_s),
                        ("forget_s", forget_s)):
            if not (math.isfinite(v) and v > 0):
                raise ParameterError(f"{name} must be finite and > 0 [s], actually: {v!r}")
        if not (0 < min_span_s <= window_s):
            raise ParameterError(f"min_span_s must lie in (0, window_s = {window_s}], "
                                 f"actually: {min_span_s!r}")
        for name, v in (("min_speed_m_s", min_speed_m_s), ("min_rate", min_rate),
                        ("min_sigmas", min_sigmas)):
            if not (math.isfinite(v) and v >= 0):
                raise ParameterError(f"{name} must be finite and >= 0, actually: {v!r}")
        self.window_s, self.min_span_s = float(window_s), float(min_span_s)
        self.min_speed, self.min_rate = float(min_speed_m_s), float(min_rate)
        self.min_sigmas, self.forget_s = float(min_sigmas), float(forget_s)
        self._hist: dict[int, _CourseHistory] = {}
        self._seen: dict[int, float] = {}

    def __len__(self) -> int:
        return len(self._hist)

    def update(self, t_s: float, ids: ArrayLike, velocities: ArrayLike) -> _F8:
        """Add one course sample per track (velocities (n, 2) [north, east] m/s at time
        ``t_s``) and return each track's turn rate [rad/s, positive to starboard], 0 where
        it is not turning or not known."""
        ids_a = np.asarray(ids, dtype=np.int64).reshape(-1)
        v = np.asarray(velocities, dtype=float).reshape(-1, 2)
        if v.shape[0] != ids_a.shape[0]:
            raise ParameterError(f"{ids_a.shape[0]} ids but {v.shape[0]} velocities")
        out = np.zeros(ids_a.shape[0])
        for k, (i, (vn, ve)) in enumerate(zip(ids_a.tolist(), v.tolist(), strict=True)):
            self._seen[i] = t_s
            h = self._hist.get(i)
            if h is None:
                h = self._hist[i] = _CourseHistory()
            if math.hypot(vn, ve) >= self.min_speed and math.isfinite(vn + ve):
                h.add(t_s, math.atan2(ve, vn), self.window_s)
            else:
                h.clear()  # a slow or stopped vessel: its course history means nothing
            h.drop_before(t_s - self.window_s)
            out[k] = self._rate(h)
        for i in [i for i, t in self._seen.items() if t < t_s - self.forget_s]:
            del self._seen[i]
            self._hist.pop(i, None)
        return out

    def _rate(self, h: _CourseHistory) -> float:
        if h.n < 4 or h.span_s() < self.min_span_s:
            return 0.0
        slope, se = h.slope()
        if abs(slope) < self.min_rate or abs(slope) < self.min_sigmas * se:
            return 0.0
        return slope


class _CourseHistory:
    """One track's unwrapped course samples in a sliding window, with the running sums
    of their least-squares line (O(1) per sample: a Python loop over the tracks stays
    cheap; numpy on every window cost 0.84 ms per call for 50 tracks). Times and courses
    are kept relative to a reference that moves with the window, so the sums stay small
    and their rounding does not build up."""

    __slots__ = ("c0", "n", "samples", "sc", "scc", "st", "stc", "stt", "t0")

    def __init__(self) -> None:
        self.samples: deque[tuple[float, float]] = deque()  # (t - t0, c - c0)
        self.clear()

    def clear(self) -> None:
        self.samples.clear()
        self.t0 = self.c0 = 0.0
        self.n = 0
        self.st = self.sc = self.stt = self.stc = self.scc = 0.0

    def _sum(self, t: float, c: float, sign: float) -> None:
        self.n += int(sign)
        self.st += sign * t
        self.sc += sign * c
        self.stt += sign * t * t
        self.stc += sign * t * c
        self.scc += sign * c * c

    def add(self, t_s: float, course: float, window_s: float) -> None:
        if not self.samples:
            self.t0, self.c0 = t_s, course
        elif t_s - self.t0 > 10.0 * window_s:  # move the reference: recompute the sums
            old = [(t + self.t0, c + self.c0) for t, c in self.samples]
            self.clear()
            self.t0, self.c0 = old[0]
            for t, c in old:
                self.samples.append((t - self.t0, c - self.c0))
                self._sum(t - self.t0, c - self.c0, 1.0)
        c_prev = self.samples[-1][1] + self.c0 if self.samples else course
        # unwrap against the previous sample
        c = c_prev + (course - c_prev + math.pi) % (2 * math.pi) - math.pi
        sample = (t_s - self.t0, c - self.c0)
        self.samples.append(sample)
        self._sum(*sample, 1.0)

    def drop_before(self, t_s: float) -> None:
        while self.samples and self.samples[0][0] + self.t0 < t_s:
            self._sum(*self.samples.popleft(), -1.0)
        if not self.samples:
            self.clear()

    def span_s(self) -> float:
        return self.samples[-1][0] - self.samples[0][0] if self.samples else 0.0

    def slope(self) -> tuple[float, float]:
        """The least-squares slope of course over time [rad/s] and its standard error."""
        n = self.n
        stt = self.stt - self.st * self.st / n
        stc = self.stc - self.st * self.sc / n
        scc = self.scc - self.sc * self.sc / n
        slope = stc / stt
        rss = max(scc - slope * stc, 0.0)
        return slope, math.sqrt(rss / max(n - 2, 1) / stt)


def constant_turn_positions(position: ArrayLike, velocity: ArrayLike, rate: ArrayLike,
                            taus_s: ArrayLike, *, max_turn_rad: float = math.inf) -> _F8:
    """Positions (n, m, 2) [north, east] of ``n`` vessels at the horizon times ``taus_s``
    (m,) [s from now] turning at ``rate`` (n,) [rad/s, positive to starboard] at constant
    speed from ``position`` (n, 2) with ``velocity`` (n, 2); a zero rate goes straight.
    A turn stops after ``max_turn_rad`` of course change, and the vessel goes straight on
    its new course from there."""
    if not max_turn_rad > 0:
        raise ParameterError(f"max_turn_rad must be > 0, actually: {max_turn_rad!r}")
    p = np.asarray(position, dtype=float).reshape(-1, 2)
    v = np.asarray(velocity, dtype=float).reshape(-1, 2)
    w = np.asarray(rate, dtype=float).reshape(-1)
    tau = np.asarray(taus_s, dtype=float).reshape(-1)
    speed = np.hypot(v[:, 0], v[:, 1])[:, None]
    c0 = np.arctan2(v[:, 1], v[:, 0])[:, None]
    small = np.abs(w) < 1e-9
    ws = np.where(small, 1.0, w)[:, None]
    t_turn = np.minimum(tau[None, :], max_turn_rad / np.abs(ws))  # time spent turning
    t_on = tau[None, :] - t_turn  # then straight on
    c1 = c0 + ws * t_turn
    dn = np.where(small[:, None], v[:, :1] * tau,
                  speed / ws * (np.sin(c1) - np.sin(c0)) + speed * np.cos(c1) * t_on)
    de = np.where(small[:, None], v[:, 1:] * tau,
                  -speed / ws * (np.cos(c1) - np.cos(c0)) + speed * np.sin(c1) * t_on)
    return np.stack([p[:, :1] + dn, p[:, 1:] + de], axis=2)
