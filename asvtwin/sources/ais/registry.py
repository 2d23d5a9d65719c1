"""The target registry: one record per MMSI, dead reckoning between irregular AIS reports.

The paper's descriptive twin maps "the position and motion of other commercial ships" from a
real-time AIS stream and extrapolates their motion between reports, which arrive at irregular
intervals ("Capability Level 1: Descriptive"). :class:`TargetRegistry` keeps, per MMSI, the
latest dynamic report, the merged static data and the report age, in fixed-capacity numpy
arrays, and answers :meth:`TargetRegistry.extrapolate` with plain arrays for the twin, the
tracker and the viewer.

Dead reckoning from the last report at time :math:`t_k` with speed :math:`U`, course
:math:`\\chi` and rate of turn :math:`\\omega` (when reported), over :math:`\\Delta t = t - t_k`:

.. math::

    \\omega = 0:\\quad p(t) = p_k + U\\,\\Delta t\\,(\\cos\\chi, \\sin\\chi)

    \\omega \\ne 0:\\quad p(t) = p_k + \\frac{U}{\\omega}
        \\big(\\sin(\\chi + \\omega\\tau) - \\sin\\chi,\\; \\cos\\chi - \\cos(\\chi + \\omega\\tau)\\big)
        + U (\\Delta t - \\tau) (\\cos(\\chi + \\omega\\tau), \\sin(\\chi + \\omega\\tau))

with :math:`\\tau = \\min(\\Delta t, T_{rot})`: the turn is trusted for ``rot_horizon_s`` only,
then the target runs straight.

**Geodetically.** AIS course is *true* course, measured from north at the ship; in the scene's
tangent plane, north at a ship 20 km east of the origin is turned by the meridian
convergence (about 0.3 degrees in the fjord), so a plane dead reckoning of 600 s drifts tens
of metres. The displacement above, :math:`(d_n, d_e)` in metres north and east *at the ship*,
is therefore applied on the WGS84 ellipsoid by middle-latitude sailing (a rhumb line, the
track of a ship keeping its course; exact to millimetres over the few kilometres dead
reckoning spans),

.. math::

    \\varphi_1 = \\varphi_0 + \\frac{d_n}{M(\\varphi_m)}, \\qquad
    \\lambda_1 = \\lambda_0 + \\frac{d_e}{N(\\varphi_m)\\cos\\varphi_m}, \\qquad
    \\varphi_m = \\tfrac12(\\varphi_0 + \\varphi_1),

with the meridian and prime-vertical radii :math:`M, N`, and the result is projected into the
scene frame exactly (:class:`~asvtwin.geo.LocalFrame`); velocity and heading are turned by the
convergence at the ship. Batches from :class:`~asvtwin.sources.ais.AisPipeline` carry their
frame; without one (reports built by hand) the registry falls back to the plane.

A target is *stale* once its age exceeds ``stale_factor`` times its nominal reporting interval
(ITU-R M.1371: class A 2-10 s under way, 3 min at anchor or moored; class B 30 s, 3 min below
2 kn; the speed counts even when the course is not available), and *evicted* after
``evict_after_s``. Memory is bounded by ``capacity`` whatever the feed does: when full, stale
targets go first, then the oldest.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from numpy.typing import NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.errors import ParameterError
from asvtwin.geo import WGS84_A_M, WGS84_F, LocalFrame
from asvtwin.sources.ais.reports import AisReport, AisStatic, ReportBatch
from asvtwin.units import KNOT_M_S

__all__ = ["TargetRegistry", "TargetSnapshot", "nominal_report_interval_s"]

_E2 = WGS84_F * (2.0 - WGS84_F)


def _empty_f8() -> _F8:
    return np.empty(0)


def rhumb_destination(lat_deg: _F8, lon_deg: _F8, north_m: _F8, east_m: _F8
                      ) -> tuple[_F8, _F8]:
    """Move points by ``(north_m, east_m)`` metres along the WGS84 surface (middle-latitude
    sailing: a rhumb line; see the module docstring). Returns latitude and longitude [deg]
    (compiled: the NumPy arithmetic it replaced, element by element, to 1e-12)."""
    args = [np.asarray(a, np.float64) for a in (lat_deg, lon_deg, north_m, east_m)]
    shape = np.broadcast_shapes(*(a.shape for a in args))
    lat, lon, dn, de = (np.ascontiguousarray(np.broadcast_to(a, shape)) for a in args)
    out = np.empty((2, lat.size))
    _rhumb(lat.reshape(-1), lon.reshape(-1), dn.reshape(-1), de.reshape(-1), WGS84_A_M, _E2,
           out[0], out[1])
    return out[0].reshape(shape), out[1].reshape(shape)


@njit(cache=True)
def _dead_reckon(U, chi, w, dt, horizon_s, d_n, d_e, chi_end, tau):  # pragma: no cover
    """Displacement [m] north/east of each target after ``dt`` [s]: a constant turn at
    rate ``w`` for at most ``horizon_s``, then straight on along the course reached."""
    for i in range(U.shape[0]):
        turning = abs(w[i]) > 1e-5
        t = min(dt[i], horizon_s) if turning else 0.0
        c_end = chi[i] + w[i] * t
        if turning:
            arc_n = U[i] / w[i] * (math.sin(c_end) - math.sin(chi[i]))
            arc_e = U[i] / w[i] * (math.cos(chi[i]) - math.cos(c_end))
        else:
            arc_n = 0.0
            arc_e = 0.0
        run = U[i] * (dt[i] - t)
        d_n[i] = arc_n + run * math.cos(c_end)
        d_e[i] = arc_e + run * math.sin(c_end)
        chi_end[i] = c_end
        tau[i] = t


@njit(cache=True)
def _rhumb(lat_deg, lon_deg, north_m, east_m, a, e2, lat_out, lon_out):  # pragma: no cover
    for i in range(lat_deg.shape[0]):
        phi0 = math.radians(lat_deg[i])
        phi1 = phi0
        w = 1.0
        phi_m = phi0
        for _ in range(3):
            phi_m = 0.5 * (phi0 + phi1)
            w = 1.0 - e2 * math.sin(phi_m) ** 2
            M = a * (1.0 - e2) / w**1.5
            phi1 = phi0 + north_m[i] / M
        N = a / math.sqrt(w)
        lat_out[i] = math.degrees(phi1)
        lon_out[i] = lon_deg[i] + math.degrees(east_m[i] / (N * math.cos(phi_m)))


def dead_reckon(U: _F8, chi: _F8, w: _F8, dt: _F8, horizon_s: float
                ) -> tuple[_F8, _F8, _F8, _F8]:
    """Compiled dead reckoning of targets (speed ``U`` [m/s], course ``chi`` [rad], rate
    of turn ``w`` [rad/s], ``dt`` [s] since the report): the displacement north and east
    [m], the course reached [rad] and the time spent turning [s] (the turn lasts at most
    ``horizon_s``; a rate below 1e-5 rad/s is straight). The arithmetic of the NumPy
    version it replaced, element by element (tested to 1e-12)."""
    n = U.shape[0]
    out = np.empty((4, n))
    _dead_reckon(np.ascontiguousarray(U, np.float64), np.ascontiguousarray(chi, np.float64),
                 np.ascontiguousarray(w, np.float64), np.ascontiguousarray(dt, np.float64),
                 float(horizon_s), out[0], out[1], out[2], out[3])
    return out[0], out[1], out[2], out[3]


def nominal_report_interval_s(sog_m_s: _F8, class_b: NDArray[np.bool_],
                              nav_status: NDArray[np.int64]) -> _F8:
    """Nominal AIS reporting interval [s] (ITU-R M.1371-5, Table 1; class B "CS" units).

    Parameters
    ----------
    sog_m_s : ndarray
        Speed over ground [m/s]; NaN (unknown) counts as under way.
    class_b : ndarray of bool
        True for class B transponders.
    nav_status : ndarray of int
        Navigational status; 1 (at anchor) and 5 (moored) report every 3 min.
    """
    sog, cb, nav = np.broadcast_arrays(np.asarray(sog_m_s, dtype=np.float64),
                                       np.asarray(class_b, dtype=np.bool_),
                                       np.asarray(nav_status, dtype=np.int64))
    out = np.empty(sog.shape)
    # (one compiled pass: the twin asks this at every snapshot for every target)
    _report_intervals(np.ascontiguousarray(sog).reshape(-1), np.ascontiguousarray(cb).reshape(-1),
                      np.ascontiguousarray(nav).reshape(-1), out.reshape(-1))
    return out


@njit(cache=True)
def _report_intervals(sog_m_s, class_b, nav_status, out):  # pragma: no cover - compiled
    for i in range(sog_m_s.shape[0]):
        kn = sog_m_s[i] / KNOT_M_S
        if math.isnan(kn):
            kn = 10.0  # unknown counts as under way
        if class_b[i]:
            out[i] = 30.0 if kn > 2.0 else 180.0
        elif kn <= 3.0 and (nav_status[i] == 1 or nav_status[i] == 5):
            out[i] = 180.0
        elif kn > 23.0:
            out[i] = 2.0
        elif kn > 14.0:
            out[i] = 6.0
        else:
            out[i] = 10.0


@dataclass(frozen=True)
class TargetSnapshot:
    """All targets at one time, extrapolated; plain arrays, row i = one vessel.

    Attributes
    ----------
    t_s : float
        Simulation time of the snapshot [s].
    mmsi : ndarray of int64, (n,)
    position_m : ndarray, (n, 2)
        Dead-reckoned ``(north, east)`` [m], NED.
    velocity_m_s : ndarray, (n, 2)
        Velocity over ground ``(north, east)`` [m/s]; zero where unknown.
    velocity_known : ndarray of bool, (n,)
        False when SOG or COG was not available.
    heading_rad : ndarray, (n,)
        Orientation to draw [rad] in the scene's NED axes: the heading, else the course,
        else 0 (never NaN; for the "not available" truth read ``true_heading_rad``).
    age_s : ndarray, (n,)
        Time since the last report [s].
    stale : ndarray of bool, (n,)
        Age beyond ``stale_factor`` reporting intervals.
    static : tuple
        :class:`AisStatic` or None per row.
    sog_m_s : ndarray, (n,)
        Reported speed over ground [m/s]; NaN when not available.
    cog_rad : ndarray, (n,)
        True course over ground [rad] (from north at the ship, clockwise, turned by the
        reported rate of turn as dead reckoned); NaN when not available.
    true_heading_rad : ndarray, (n,)
        True heading [rad], same convention; NaN when not available.
    lat_deg, lon_deg : ndarray, (n,)
        The dead-reckoned position in WGS84 [deg].
    class_b : ndarray of bool, (n,)
        Class B transponder (types 18/19).
    """

    t_s: float
    mmsi: NDArray[np.int64]
    position_m: _F8
    velocity_m_s: _F8
    velocity_known: NDArray[np.bool_]
    heading_rad: _F8
    age_s: _F8
    stale: NDArray[np.bool_]
    static: tuple[AisStatic | None, ...]
    sog_m_s: _F8 = field(default_factory=_empty_f8)
    cog_rad: _F8 = field(default_factory=_empty_f8)
    true_heading_rad: _F8 = field(default_factory=_empty_f8)
    lat_deg: _F8 = field(default_factory=_empty_f8)
    lon_deg: _F8 = field(default_factory=_empty_f8)
    class_b: NDArray[np.bool_] = field(default_factory=lambda: np.empty(0, np.bool_))

    def __len__(self) -> int:
        return int(self.mmsi.shape[0])


def _wrap(a: _F8) -> _F8:
    """Angles to [-pi, pi) (NaN stays NaN)."""
    return (a + np.pi) % (2 * np.pi) - np.pi


class TargetRegistry:
    """Latest state of every AIS target, with bounded memory and dead reckoning.

    Parameters
    ----------
    capacity : int
        Most targets held at once.
    epoch_unix_s : float
        UNIX time of simulation time 0 [s]; times in and out of the registry are simulation
        seconds ``t_unix_s - epoch_unix_s``.
    stale_factor : float
        A target is stale after this many nominal reporting intervals (ITU-R M.1371; a
        25-kn ship reporting every 2 s is stale after 6 s).
    min_stale_s : float
        Optional lower bound of the stale age [s] (0: none).
    evict_after_s : float
        Targets older than this are removed [s].
    rot_horizon_s : float
        How long a reported rate of turn is extrapolated [s] (0 disables ROT).
    frame : LocalFrame, optional
        Scene frame for geodetic dead reckoning; taken from the first batch that carries
        one when omitted (without any, dead reckoning is done in the plane).
    """

    def __init__(self, *, capacity: int = 4096, epoch_unix_s: float = 0.0,
                 stale_factor: float = 3.0, min_stale_s: float = 0.0,
                 evict_after_s: float = 1200.0, rot_horizon_s: float = 60.0,
                 frame: LocalFrame | None = None) -> None:
        if capacity < 1:
            raise ParameterError(f"TargetRegistry: capacity must be >= 1, actually: {capacity}")
        for name, v in (("stale_factor", stale_factor), ("min_stale_s", min_stale_s),
                        ("evict_after_s", evict_after_s), ("rot_horizon_s", rot_horizon_s)):
            if not (math.isfinite(v) and v >= 0):
                raise ParameterError(f"TargetRegistry: {name} must be finite and >= 0, "
                                     f"actually: {v}")
        self.capacity = int(capacity)
        self.epoch_unix_s = float(epoch_unix_s)
        self.stale_factor = float(stale_factor)
        self.min_stale_s = float(min_stale_s)
        self.evict_after_s = float(evict_after_s)
        self.rot_horizon_s = float(rot_horizon_s)
        self.frame = frame
        c = self.capacity
        self._mmsi = np.zeros(c, dtype=np.int64)
        self._active = np.zeros(c, dtype=np.bool_)
        self._t = np.zeros(c)
        self._p = np.zeros((c, 2))
        self._sog = np.zeros(c)
        self._cog = np.zeros(c)
        self._vel_ok = np.zeros(c, dtype=np.bool_)
        self._hdg = np.zeros(c)
        self._sog_n = np.full(c, np.nan)  # as reported: NaN = not available
        self._cog_n = np.full(c, np.nan)
        self._hdg_n = np.full(c, np.nan)
        self._ll = np.full((c, 2), np.nan)  # reported latitude, longitude [deg]
        self._rot = np.zeros(c)
        self._class_b = np.zeros(c, dtype=np.bool_)
        self._nav = np.full(c, -1, dtype=np.int64)
        self._slot: dict[int, int] = {}
        self._free = list(range(c - 1, -1, -1))
        self._static: dict[int, AisStatic] = {}
        self.evicted = 0
        self.ignored_older = 0

    def __len__(self) -> int:
        return len(self._slot)

    def __contains__(self, mmsi: int) -> bool:
        return mmsi in self._slot

    # ----------------------------------------------------------------- updates
    def update(self, report: AisReport) -> None:
        """Take one dynamic report (a convenience over :meth:`update_batch`)."""
        self.update_batch(ReportBatch.from_reports([report]))

    def update_static(self, static: AisStatic) -> None:
        """Merge static data (24A and 24B arrive separately); bounded to 2 x capacity."""
        old = self._static.pop(static.mmsi, None)
        self._static[static.mmsi] = static if old is None else old.merged(static)
        if len(self._static) > 2 * self.capacity:
            for m in list(self._static)[: len(self._static) - 2 * self.capacity]:
                if m not in self._slot:
                    del self._static[m]

    def ingest(self, messages: Iterable[AisReport | AisStatic]) -> None:
        """Take a mixed sequence of reports and static records, in order."""
        reports: list[AisReport] = []
        for m in messages:
            if isinstance(m, AisStatic):
                self.update_static(m)
            else:
                reports.append(m)
        if reports:
            self.update_batch(ReportBatch.from_reports(reports))

    def update_batch(self, batch: ReportBatch) -> None:
        """Take a batch of dynamic reports and its static records (vectorised)."""
        for record in batch.static:
            self.update_static(record)
        if self.frame is None and batch.frame is not None:
            self.frame = batch.frame
        n = len(batch)
        if n == 0:
            return
        # the last report per MMSI in the batch wins (the pipeline keeps time order per MMSI)
        uniq, first_rev = np.unique(batch.mmsi[::-1], return_index=True)
        rows = n - 1 - first_rev
        t = batch.t_unix_s[rows] - self.epoch_unix_s
        if len(uniq) > self.capacity:  # more vessels in one batch than room: newest win
            newest = np.argsort(t)[-self.capacity:]
            uniq, rows, t = uniq[newest], rows[newest], t[newest]
        slots = np.empty(len(uniq), dtype=np.int64)
        keep = np.ones(len(uniq), dtype=np.bool_)
        get = self._slot.get
        t_list = t.tolist()
        for i, m in enumerate(uniq.tolist()):
            s = get(m)
            if s is None:
                s = self._allocate(m, t_list[i])
            elif t_list[i] < self._t[s]:
                keep[i] = False
                self.ignored_older += 1
            else:
                self._t[s] = t_list[i]  # claim the slot now: an eviction below must not free it
            slots[i] = s
        if not keep.all():
            rows, slots, t = rows[keep], slots[keep], t[keep]
        sog = batch.sog_m_s[rows]
        cog = batch.cog_rad[rows]
        hdg = batch.heading_rad[rows]
        rot = batch.rot_rad_s[rows]
        vel_ok = ~(np.isnan(sog) | np.isnan(cog))
        self._mmsi[slots] = batch.mmsi[rows]
        self._active[slots] = True
        self._t[slots] = t
        self._p[slots, 0] = batch.north_m[rows]
        self._p[slots, 1] = batch.east_m[rows]
        self._vel_ok[slots] = vel_ok
        self._sog[slots] = np.where(vel_ok, sog, 0.0)
        self._cog[slots] = np.where(vel_ok, cog, 0.0)
        # heading: reported, else course, else 0 (never NaN in the state)
        self._hdg[slots] = np.where(np.isnan(hdg), np.where(np.isnan(cog), 0.0, cog), hdg)
        self._sog_n[slots] = sog
        self._cog_n[slots] = cog
        self._hdg_n[slots] = hdg
        self._ll[slots, 0] = batch.lat_deg[rows]
        self._ll[slots, 1] = batch.lon_deg[rows]
        self._rot[slots] = np.where(np.isnan(rot), 0.0, rot)
        self._class_b[slots] = np.isin(batch.msg_type[rows], (18, 19))
        self._nav[slots] = batch.nav_status[rows]

    def _allocate(self, mmsi: int, t_s: float) -> int:
        if not self._free:
            self.evict(t_s)
        if not self._free:  # still full: drop the oldest tenth
            idx = np.flatnonzero(self._active)
            k = max(1, len(idx) // 10)
            oldest = idx[np.argpartition(self._t[idx], k - 1)[:k]]
            self._remove(oldest)
        s = self._free.pop()
        self._slot[mmsi] = s
        self._mmsi[s] = mmsi
        self._active[s] = True
        self._t[s] = t_s
        return s

    def _remove(self, slots: NDArray[np.int64]) -> None:
        for s in slots.tolist():
            m = int(self._mmsi[s])
            del self._slot[m]
            self._static.pop(m, None)
            self._free.append(s)
        self._active[slots] = False
        self.evicted += len(slots)

    def evict(self, t_s: float) -> int:
        """Remove targets older than ``evict_after_s`` at time ``t_s``; return how many."""
        old = np.flatnonzero(self._active & (t_s - self._t > self.evict_after_s))
        if len(old):
            self._remove(old)
        return len(old)

    # ----------------------------------------------------------------- queries
    def static(self, mmsi: int) -> AisStatic | None:
        """Merged static data of one vessel, if any was received."""
        return self._static.get(mmsi)

    def extrapolate(self, t_s: float, *, evict: bool = True) -> TargetSnapshot:
        """Dead-reckon every target to simulation time ``t_s`` (see module docstring).

        Parameters
        ----------
        t_s : float
            Simulation time [s]. Targets reported after ``t_s`` are shown where they were
            reported (no extrapolation backwards).
        evict : bool
            Remove targets older than ``evict_after_s`` first.
        """
        if evict:
            self.evict(t_s)
        idx = np.flatnonzero(self._active)
        age = t_s - self._t[idx]
        dt = np.maximum(age, 0.0)
        U = self._sog[idx]
        chi = self._cog[idx]
        w = self._rot[idx] if self.rot_horizon_s > 0 else np.zeros(len(idx))
        # arc for tau (constant turn), then straight along chi_end; the displacement in
        # metres north/east at the ship (its own north: AIS course is true)
        d_n, d_e, chi_end, tau = dead_reckon(U, chi, w, dt, self.rot_horizon_s)
        ll = self._ll[idx]
        geodetic = self.frame is not None and not np.isnan(ll).any()
        if geodetic:
            frame = self.frame
            lat, lon = np.empty(len(idx)), np.empty(len(idx))
            _rhumb(np.ascontiguousarray(ll[:, 0]), np.ascontiguousarray(ll[:, 1]), d_n, d_e,
                   WGS84_A_M, _E2, lat, lon)  # (rhumb_destination without its broadcasting)
            # the positions and, for the meridian convergence (the angle of the ship's
            # north in the scene's NED axes), points 1e-5 deg north of them: one
            # conversion of both (elementwise, so the same numbers as two)
            k = len(idx)
            ne, ee = frame.to_ned(np.concatenate([lat, lat + 1e-5]),  # type: ignore[union-attr]
                                  np.concatenate([lon, lon]))
            pn, pe, qn, qe = ne[:k], ee[:k], ne[k:], ee[k:]
            pos = np.column_stack([pn, pe]) if k else np.zeros((0, 2))
            gamma = np.arctan2(qe - pe, qn - pn)
        else:
            pos = self._p[idx].copy()
            pos[:, 0] += d_n
            pos[:, 1] += d_e
            lat, lon = ll[:, 0].copy(), ll[:, 1].copy()
            gamma = np.zeros(len(idx))
        vel = np.column_stack([U * np.cos(chi_end + gamma), U * np.sin(chi_end + gamma)])
        sog_n = self._sog_n[idx]
        interval = nominal_report_interval_s(sog_n, self._class_b[idx], self._nav[idx])
        stale = age > np.maximum(self.stale_factor * interval, self.min_stale_s)
        mmsi = self._mmsi[idx].copy()
        turn = w * tau
        return TargetSnapshot(
            t_s=float(t_s), mmsi=mmsi, position_m=pos, velocity_m_s=vel,
            velocity_known=self._vel_ok[idx].copy(),
            heading_rad=_wrap(self._hdg[idx] + turn + gamma),
            age_s=age, stale=stale,
            static=tuple(self._static.get(m) for m in mmsi.tolist()),
            sog_m_s=sog_n.copy(), cog_rad=_wrap(self._cog_n[idx] + turn),
            true_heading_rad=_wrap(self._hdg_n[idx] + turn),
            lat_deg=np.asarray(lat, np.float64), lon_deg=np.asarray(lon, np.float64),
            class_b=self._class_b[idx].copy(),
        )

    snapshot = extrapolate
