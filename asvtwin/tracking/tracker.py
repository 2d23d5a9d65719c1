"""The multi-target tracker: LiDAR clusters and AIS reports in, a snapshot of tracks out.

One :meth:`Tracker.step` per tick, with the time passed in (Stone Soup's components,
light and batched over tracks):

1. **predictor** — every track (the fused estimate and the two per-sensor filters) is
   propagated to ``t_s`` with the CV model (:func:`~asvtwin.tracking.kalman.cv_predict`);
2. **LiDAR** — the scan is segmented (coast returns removed with the land polygons),
   each cluster fitted (Halir–Flusser) and turned into a centre measurement;
   **associator**: Mahalanobis gate + GNN;
3. **AIS** — reports become position/velocity measurements at ``t_s``; a report whose MMSI
   is tied to a track goes to that track (if it passes a loose gate: a report far from its
   own track is rejected and counted, and after ``ais_reseed_after`` rejections in a row
   the tie is dropped); the others are associated by GNN with the untied tracks, which
   then get tied to the MMSI;
4. **updater** — fusion of whatever arrived (the paper's product of Gaussians by default,
   or Chen 2019 / covariance intersection over the per-sensor filters);
5. **initiator** — unassociated clusters (not too close to a track) and unassociated AIS
   reports start tentative tracks; **confirmation** by M-of-N hits (or two AIS reports);
6. **deleter** — tentative tracks that can no longer reach M of N, tracks not updated for
   ``max_coast_s`` (``max_coast_ais_s`` when tied to an MMSI), tracks whose position
   spread exceeds ``max_position_std_m``, tracks well inside land.

Bad input never raises: time going backwards, non-finite times, bad AIS reports, NaN
returns, tiny clusters are counted in :attr:`Tracker.counters` and skipped.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Sequence
from dataclasses import replace
from types import MappingProxyType
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.geo.land import LandMask
from asvtwin.sensors.lidar import LidarScan
from asvtwin.tracking.association import FORBIDDEN, gate_threshold, gated_costs, gnn_assign
from asvtwin.tracking.clustering import Clusters, cluster_scan, split_clusters
from asvtwin.tracking.config import TrackerConfig
from asvtwin.tracking.fusion import (
    fuse_covariance_intersection,
    fuse_gain_weighted,
)
from asvtwin.tracking.kalman import _predict_in_place
from asvtwin.tracking.measurement import (
    AisMeasurement,
    AisMeasurementBatch,
    LidarMeasurements,
    LidarModel,
    _end_shadows,
    _hull_prm,
    ais_measurements,
    lidar_measurements,
)
from asvtwin.tracking.snapshot import TRACK_STATUS, TrackSnapshot
from asvtwin.tracking.tracker_kernels import (
    bookkeeping,
    coincident,
    near_tracks,
    pair_measurements,
    position_mahalanobis,
    take_assigned,
    take_tied,
    tied_reports,
    update_and_fuse,
)

__all__ = ["Tracker", "VesselDimensions"]


class VesselDimensions(Protocol):
    """What :meth:`Tracker.update_static` reads of an AIS static record
    (:class:`asvtwin.sources.ais.AisStatic` has it)."""

    @property
    def mmsi(self) -> int: ...

    @property
    def length_m(self) -> float | None: ...

    @property
    def beam_m(self) -> float | None: ...

_log = logging.getLogger(__name__)
_NO_SIGHT = np.empty((0, 8))  # pair_measurements' line-of-sight rows when there are none (no course used)
_STATUS = np.array(TRACK_STATUS, dtype=object)  # TRACK_STATUS indexed by an array: the same str objects


def _identities(n: int, m: int) -> _F8:
    """``n`` identity matrices ``m``×``m`` (what ``np.tile(np.eye(m), (n, 1, 1))`` gives, ~4x faster)."""
    out = np.zeros((n, m, m))
    for i in range(m):
        out[:, i, i] = 1.0
    return out


# per-track arrays, in this order; (shape tail, dtype, fill)
_FIELDS: dict[str, tuple[tuple[int, ...], type, float]] = {
    "ids": ((), np.int64, -1), "mmsi": ((), np.int64, -1),
    "x": ((4,), np.float64, 0.0), "P": ((4, 4), np.float64, 0.0),
    "xL": ((4,), np.float64, 0.0), "PL": ((4, 4), np.float64, 0.0), "GL": ((4, 4), np.float64, 0.0),
    "xA": ((4,), np.float64, 0.0), "PA": ((4, 4), np.float64, 0.0), "GA": ((4, 4), np.float64, 0.0),
    "hasL": ((), np.bool_, False), "hasA": ((), np.bool_, False),
    "tL": ((), np.float64, -np.inf), "tA": ((), np.float64, -np.inf), "t_last": ((), np.float64, 0.0),
    "hist": ((), np.int64, 0), "age": ((), np.int64, 0), "n_ais": ((), np.int64, 0),
    "ais_rej": ((), np.int64, 0), "confirmed": ((), np.bool_, False), "axes": ((2,), np.float64, np.nan),
    "gotL": ((), np.bool_, False), "gotA": ((), np.bool_, False),
}


class Tracker:
    """Multi-target tracker with LiDAR–AIS fusion.

    Parameters
    ----------
    config : TrackerConfig, optional
        Settings.
    land : LandMask or None
        The scene's coast (coast-return removal, deletion of tracks on land).
    """

    def __init__(self, config: TrackerConfig | None = None, land: LandMask | None = None) -> None:
        self.config = config or TrackerConfig()
        self.land = land
        self._gL = gate_threshold(self.config.gate_probability, 2)
        self._gA_tied = gate_threshold(self.config.tied_gate_probability, 2)
        self._gM = gate_threshold(self.config.merge_probability, 2)
        self._gA_id = gate_threshold(self.config.identity_gate_probability, 2)
        self._pairs: dict[tuple[int, int], int] = {}
        self._t: float | None = None
        self._t_scan: float | None = None  # time of the last scan (the persistence's Δt)
        self._models: dict[float, LidarModel] = {}
        self._dims: dict[int, tuple[float, float]] = {}  # MMSI -> (length, beam) [m], AIS static data
        self._next_id = 1
        self._a: dict[str, np.ndarray] = {k: np.empty((0, *s), d) for k, (s, d, _) in _FIELDS.items()}
        self._counts: dict[str, int] = dict.fromkeys((
            "ticks", "time_reversals", "bad_time", "clusters", "coast_points", "invalid_points",
            "small_clusters", "fit_fallbacks", "lidar_unassociated", "init_suppressed",
            "ais_reports", "ais_rejected", "ais_stale", "ais_gated_out", "ais_reseeded",
            "tracks_created", "tracks_confirmed", "tracks_deleted", "tracks_merged", "deleted_on_land",
            "nan_guard", "lidar_with_course", "lidar_vetoed_by_ais", "ais_ambiguous", "init_coast_band",
            "ais_recovered", "clusters_split"), 0)
        self._warned: set[str] = set()
        #: Position NIS (2 dof) of this tick's LiDAR updates and tied AIS updates:
        #: ``νᵀ (P + R)⁻¹ ν`` before the update (diagnostics: χ²₂ when consistent).
        self.last_nis: dict[str, NDArray[np.float64]] = {"lidar": np.empty(0), "ais": np.empty(0)}
        self._last = self._snapshot(0.0)

    # ------------------------------------------------------------------ helpers
    @property
    def counters(self) -> MappingProxyType[str, int]:
        """Counts of everything skipped, created and deleted so far (read-only)."""
        return MappingProxyType(dict(self._counts))

    def _count(self, key: str, k: int = 1, msg: str = "") -> None:
        if k <= 0:
            return
        self._counts[key] += int(k)
        if msg and key not in self._warned:
            self._warned.add(key)
            _log.warning("%s (counted in Tracker.counters[%r]; logged once)", msg, key)

    def _append(self, rows: dict[str, np.ndarray]) -> None:
        k = len(next(iter(rows.values())))
        for name, (shape, dtype, fill) in _FIELDS.items():
            new = rows[name] if name in rows else np.full((k, *shape), fill, dtype)
            self._a[name] = np.concatenate([self._a[name], np.asarray(new, dtype).reshape(k, *shape)])
        self._count("tracks_created", k)

    def _keep(self, mask: NDArray[np.bool_]) -> None:
        for name in self._a:
            self._a[name] = self._a[name][mask]

    def _new_ids(self, k: int) -> NDArray[np.int64]:
        ids = np.arange(self._next_id, self._next_id + k, dtype=np.int64)
        self._next_id += k
        return ids

    def set_dimensions(self, mmsi: int, length_m: float | None, beam_m: float | None) -> bool:
        """Known length and beam of the vessel with this MMSI (AIS static data: message 5,
        19 or 24B dimensions ``A + B`` and ``C + D``).

        A track tied to that MMSI is then measured by LiDAR with the hull's real extent
        (:mod:`asvtwin.tracking.hull_model`: the unseen depth is the known length or beam
        less what is seen, to ± ``LidarModel.known_size_tol``) instead of bounds from the
        length/beam ratio. Unknown, zero or non-finite sizes clear the entry (AIS sends 0
        for "not available"). Returns whether dimensions are now known for ``mmsi``.
        """
        key = int(mmsi)
        L = float("nan") if length_m is None else float(length_m)
        B = float("nan") if beam_m is None else float(beam_m)
        if key <= 0 or not (np.isfinite(L) and np.isfinite(B) and L > 0.0 and B > 0.0 and B <= L):
            self._dims.pop(key, None)
            return False
        self._dims[key] = (L, B)
        return True

    def update_static(self, records: Iterable[VesselDimensions]) -> int:
        """Take AIS static records (objects with ``mmsi``, ``length_m`` and ``beam_m``,
        e.g. :class:`asvtwin.sources.ais.AisStatic` from ``ReportBatch.static``) and call
        :meth:`set_dimensions` for each; records without both sizes are skipped (an
        earlier, complete record stays). Returns the number of MMSIs with known dimensions.
        """
        for r in records:
            L, B = r.length_m, r.beam_m
            if L is not None and B is not None:
                self.set_dimensions(int(r.mmsi), L, B)
        return len(self._dims)

    @property
    def dimensions(self) -> MappingProxyType[int, tuple[float, float]]:
        """Known ``(length, beam)`` [m] by MMSI (read-only)."""
        return MappingProxyType(dict(self._dims))

    def _measured_dims(self) -> _F8:
        """:meth:`_track_dims` where they size the LiDAR measurement
        (``measure_with_dimensions``), else NaN: every size unknown to the measurement."""
        if self.config.measure_with_dimensions:
            return self._track_dims()
        return np.full((self._a["mmsi"].shape[0], 2), np.nan)

    def _track_dims(self) -> _F8:
        """Known length and beam of every track (its MMSI's; NaN when none), (n, 2)."""
        mm = self._a["mmsi"]
        out = np.full((mm.shape[0], 2), np.nan)
        if self._dims:
            get = self._dims.get
            for i, m in enumerate(mm.tolist()):
                if m >= 0:
                    d = get(m)
                    if d is not None:
                        out[i] = d
        return out

    # ------------------------------------------------------------------ the tick
    def step(
        self,
        t_s: float,
        scan: LidarScan | Clusters | None = None,
        ais: Sequence[AisMeasurement] | AisMeasurementBatch = (),
    ) -> TrackSnapshot:
        """Advance to ``t_s`` and take in one LiDAR scan and the AIS reports since the last tick.

        Parameters
        ----------
        t_s : float
            Tick time [s] since the scene start; must not decrease.
        scan : LidarScan or Clusters or None
            The scan taken at ``t_s`` (or clusters from another segmenter), or None.
        ais : sequence of AisMeasurement, or AisMeasurementBatch
            AIS reports received since the last tick, as objects or as columns
            (:meth:`AisMeasurementBatch.from_batch` takes the AIS pipeline's ``ReportBatch``);
            both give the same result.

        Returns
        -------
        TrackSnapshot
            All tracks (tentative ones included) at ``t_s``.
        """
        cfg, a = self.config, self._a
        t = float(t_s)
        if not np.isfinite(t):
            self._count("bad_time", 1, f"non-finite tick time {t_s!r} skipped")
            return self._last
        if self._t is not None and t < self._t:
            self._count("time_reversals", 1, f"tick time went backwards ({t} s < {self._t} s), tick skipped")
            return self._last
        dt = 0.0 if self._t is None else t - self._t
        self._t = t
        self._counts["ticks"] += 1
        self.last_nis = {"lidar": np.empty(0), "ais": np.empty(0)}
        n = a["x"].shape[0]

        # 1. predictor
        if n:  # cv_predict's arithmetic, in place (dt is checked above, q by TrackerConfig)
            for xk, Pk in (("x", "P"), ("xL", "PL"), ("xA", "PA")):
                _predict_in_place(a[xk], a[Pk], dt, float(cfg.q))
        a["gotL"] = np.zeros(n, bool)
        a["gotA"] = np.zeros(n, bool)

        # 2. LiDAR: segment, fit, associate
        zL, RL = np.zeros((n, 2)), _identities(n, 2)
        new_z, new_R = np.empty((0, 2)), np.empty((0, 2, 2))
        fit_axes = np.full((n, 2), np.nan)
        if scan is not None:
            cl = cluster_scan(scan, self.land, cfg.cluster) if isinstance(scan, LidarScan) else scan
            if cfg.split_by_tracks and len(cl):
                cl = self._split_by_tracks(t, cl)
            self._count("coast_points", cl.n_coast)
            self._count("invalid_points", cl.n_invalid, "non-finite LiDAR returns dropped")
            self._count("small_clusters", cl.n_small)
            self._count("clusters", len(cl))
            mdl = self._scan_model(t)
            if len(cl):
                m = lidar_measurements(cl, mdl)
                self._count("fit_fallbacks", int((~m.used_fit).sum()))
                cost = gated_costs(a["x"][:, :2], a["P"][:, :2, :2], m.z, m.R, self._gL)[0]
                ti, cj, zp, _, Rpu, with_course = self._pair_measurements(t, cl, cost, m, mdl)
                rows, cols = gnn_assign(cost)
                self.last_nis["lidar"], n_course, free = take_assigned(
                    rows, cols, ti, cj, zp, Rpu, with_course, a["x"], a["P"], m.used_fit, m.fits.arc_coverage_rad,
                    m.fits.semi_axes, len(m), zL, RL, a["gotL"], fit_axes)
                self._count("lidar_with_course", n_course)
                free &= ~self._in_coast_band(cl, free)
                new_z, new_R = m.z[free], m.R[free]

        # 3. AIS: tied by MMSI, else GNN with untied tracks, else new tracks
        zA, RA = np.zeros((n, 4)), _identities(n, 4)
        am = ais_measurements(ais, t, cfg.ais)
        self._count("ais_reports", len(ais))
        self._count("ais_rejected", am.n_rejected, "malformed AIS reports rejected")
        self._count("ais_stale", am.n_stale, "stale or future AIS reports dropped")
        ais_new = np.zeros(len(am), bool)
        if len(am):
            # row of the track tied to each report's MMSI, -1 when none (MMSIs are unique),
            # and the tied reports' position distance to their track
            tied, tj, ti, d2 = tied_reports(am.mmsi, am.z, am.R, a["mmsi"], a["x"], a["P"])
            if tj.size:
                ok = d2 <= self._gA_tied
                all_ok = bool(ok.all())
                if not all_ok:
                    self._recover_identity(ti, tj, ok, am.z, am.R)
                self.last_nis["ais"] = d2[ok]
                n_out = int(ti.size - ok.sum())
                self._count("ais_gated_out", n_out, "AIS reports far from their own track rejected")
                take_tied(ti, tj, ok, am.z, am.R, a["gotA"], zA, RA, a["ais_rej"])
                if n_out:
                    reseed = ti[~ok][a["ais_rej"][ti[~ok]] >= cfg.ais_reseed_after]
                    if reseed.size:
                        self._count("ais_reseeded", reseed.size)
                        a["mmsi"][reseed] = -1
                        ais_new[tj[~ok][np.isin(ti[~ok], reseed)]] = True
            uj = np.flatnonzero(tied < 0)
            if uj.size:
                ui = np.flatnonzero(a["mmsi"] < 0)
                cost, d2u = gated_costs(a["x"][ui, :2], a["P"][ui, :2, :2], am.z[uj, :2], am.R[uj, :2, :2], self._gL)
                # an identity is given only when one track explains the report clearly
                # better than any other (likelihood ratio >= e^(Δ/2)): a wrong tie in a close
                # pair would carry the MMSI to the wrong vessel
                ambiguous = np.zeros(uj.size, bool)
                if ui.size >= 2:
                    d2s = np.sort(np.where(cost < FORBIDDEN, d2u, np.inf), axis=0)
                    with np.errstate(invalid="ignore"):  # inf - inf where no track is in the gate
                        ambiguous = np.isfinite(d2s[1]) & (d2s[1] - d2s[0] < cfg.identity_margin)
                    cost[:, ambiguous] = FORBIDDEN
                    self._count("ais_ambiguous", int(ambiguous.sum()))
                rows, cols = gnn_assign(cost)
                r, c = ui[rows], uj[cols]
                a["gotA"][r] = True
                a["mmsi"][r] = am.mmsi[c]
                zA[r], RA[r] = am.z[c], am.R[c]
                free = ~ambiguous
                free[cols] = False
                ais_new[uj[free]] = True

        # 4. updater, 5. confirmation, 6. deleter: one pass each over the tracks
        v2 = self.config.init_velocity_std_m_s ** 2
        product = cfg.fusion == "product"  # fuse_product's arithmetic: zL/RL, zA/RA are finite, 0/I where absent
        update_and_fuse(a["x"], a["P"], a["xL"], a["PL"], a["GL"], a["hasL"], a["tL"], a["gotL"], zL, RL,
                        a["xA"], a["PA"], a["GA"], a["hasA"], a["tA"], a["gotA"], zA, RA, t, v2, product)
        if not product:
            self._fuse_filters(t)
        check_v = bool(np.isfinite(cfg.confirm_velocity_std_m_s))
        newly, dead, bad, lmax = bookkeeping(
            a["x"], a["P"], a["gotL"], a["gotA"], a["hist"], a["age"], a["n_ais"], a["t_last"], a["axes"], fit_axes,
            a["confirmed"], a["mmsi"], t, (1 << cfg.confirm_n) - 1, cfg.confirm_m, cfg.confirm_n, check_v,
            cfg.confirm_velocity_std_m_s ** 2 if check_v else 0.0, cfg.max_coast_s, cfg.max_coast_ais_s,
            cfg.max_position_std_m)
        self._count("tracks_confirmed", newly)
        self._delete(t, dead, bad, lmax)
        self._merge()

        # 5. initiator (after deletion: new tracks are not judged on this tick)
        if ais_new.any():
            self._start_from_ais(t, am.mmsi[ais_new], am.z[ais_new], am.R[ais_new])
        if len(new_z):
            self._start_from_lidar(t, new_z, new_R)
        self._last = self._snapshot(t)
        return self._last

    # ------------------------------------------------------------------ pieces
    def _split_by_tracks(self, t: float, cl: Clusters) -> Clusters:
        """Cut clusters that two confirmed tracks predict into, one of them tied to an MMSI
        with a fresh report (:func:`~asvtwin.tracking.clustering.split_clusters`): vessels
        closer than the segmentation resolves stay two tracks. A tied track stands at its
        AIS-only estimate (independent of the merged returns), others at their prediction;
        its footprint is its fitted semi-axes along its course, reached within twice its
        largest position σ (at most 10 m)."""
        a, cfg = self._a, self.config
        sel = np.flatnonzero(a["confirmed"])
        if sel.size < 2:
            return cl
        fresh = (a["mmsi"][sel] >= 0) & a["hasA"][sel] & (t - a["tA"][sel] <= cfg.fusion_window_s)
        if not fresh.any():
            return cl
        x = np.where(fresh[:, None], a["xA"][sel, :2], a["x"][sel, :2])
        P = np.where(fresh[:, None, None], a["PA"][sel, :2, :2], a["P"][sel, :2, :2])
        tr, det = P[:, 0, 0] + P[:, 1, 1], P[:, 0, 0] * P[:, 1, 1] - P[:, 0, 1] ** 2
        sig = np.sqrt(0.5 * tr + np.sqrt(np.maximum(0.25 * tr * tr - det, 0.0)))
        # footprint: the fitted semi-axes along the course (5 × 2 m when not fitted)
        ax = a["axes"][sel]
        semi = np.column_stack([np.nan_to_num(ax[:, 0], nan=5.0), np.nan_to_num(ax[:, 1], nan=2.0)])
        # a tied track with AIS dimensions: its real footprint
        dims = self._measured_dims()[sel]
        known = np.isfinite(dims[:, 0])
        semi[known] = 0.5 * dims[known]
        semi[:, 1] = np.minimum(semi[:, 1], semi[:, 0])
        v = a["x"][sel, 2:]
        out, n_split = split_clusters(cl, x, np.minimum(2.0 * sig, 10.0), min_separation_m=cfg.merge_distance_m,
                                      anchored=fresh, course_rad=np.arctan2(v[:, 1], v[:, 0]), semi_axes_m=semi)
        self._count("clusters_split", n_split)
        return out

    def _recover_identity(self, ti: NDArray[np.int64], tj: NDArray[np.int64], ok: NDArray[np.bool_], z: _F8,
                          R: _F8) -> None:
        """A tied report outside its track's gate but consistent with the track's AIS-only
        filter means LiDAR dragged the track onto a neighbour: the track (id and MMSI) goes
        back to the AIS-only estimate and drops its LiDAR filter, instead of losing the tie
        (``ok`` is set for those reports)."""
        a = self._a
        bad = np.flatnonzero(~ok)
        if bad.size == 0:
            return
        r, j = ti[bad], tj[bad]
        dA = position_mahalanobis(z[j, :2] - a["xA"][r, :2], np.ascontiguousarray(a["PA"][r, :2, :2]), R[j, :2, :2])
        rec = a["hasA"][r] & (dA <= self._gA_tied)
        if not rec.any():
            return
        rr = r[rec]
        a["x"][rr], a["P"][rr] = a["xA"][rr], a["PA"][rr]
        a["hasL"][rr] = False
        a["gotL"][rr] = False
        a["axes"][rr] = np.nan
        ok[bad[rec]] = True
        self._count("ais_recovered", int(rr.size))

    def _in_coast_band(self, cl: Clusters, which: NDArray[np.bool_]) -> NDArray[np.bool_]:
        """Clusters (among ``which``) with a return within ``chart_error_m`` of the charted
        shore or on charted land: they may update tracks but never start one. A chart off
        by a few metres leaves coast returns outside the clustering's coast margin; those
        must not become vessels (docs/tracking.md, near the coast)."""
        out = np.zeros(len(cl), bool)
        band = self.config.chart_error_m
        if self.land is None or band <= 0.0 or not which.any():
            return out
        owner = np.repeat(np.arange(len(cl)), cl.sizes)
        sel = which[owner]
        near = self.land.signed_distance(cl.points[sel]) < band
        out[owner[sel][near]] = True
        self._count("init_coast_band", int(out.sum()))
        return out

    def _scan_model(self, t: float) -> LidarModel:
        """The LiDAR model of this scan: ``depth_persistence`` in scans from
        ``TrackerConfig.depth_persistence_s`` and the time since the previous scan (the
        persistent part of the error spans more scans at a higher rate)."""
        cfg = self.config
        dt, self._t_scan = (None if self._t_scan is None else t - self._t_scan), t
        tau = cfg.depth_persistence_s
        if tau is None or dt is None or not dt > 0.0:
            return cfg.lidar
        kappa = round(max(1.0, tau / dt), 6)
        mdl = self._models.get(kappa)
        if mdl is None:
            if len(self._models) > 64:
                self._models.clear()
            mdl = self._models[kappa] = replace(cfg.lidar, depth_persistence=kappa)
        return mdl

    def _pair_measurements(self, t: float, cl: Clusters, cost: _F8, m: LidarMeasurements, mdl: LidarModel) -> tuple[
            NDArray[np.int64], NDArray[np.int64], _F8, _F8, _F8, NDArray[np.bool_]]:
        """The measurement of every gated (track, cluster) pair, and the pair's cost again.

        A cluster is first measured without a hull axis (a wide, honest covariance: a
        flank seen broadside could be a stern, so the centre may lie deep behind it).
        Inside a track's gate it is measured again with that track's course as the hull
        axis (:mod:`asvtwin.tracking.hull_model`), and the pair's gate and cost use *that*
        measurement. With the axis-free one, the near hull of two abreast vessels was
        measured between them and taken by the far vessel's track (an MMSI swap); with its
        course, the same cluster is where the near hull is.

        The AIS identity is evidence: a track tied to an MMSI takes a LiDAR cluster only
        if the cluster (measured with that track's course) is also consistent with the
        track's own AIS-only estimate (its reports aged to ``t``), so LiDAR alone cannot drag
        an MMSI onto a neighbour (counted in ``lidar_vetoed_by_ais``).

        Returns the pairs ``ti``, ``cj``, their ``z``, single-scan ``R`` (gates),
        ``R_update`` (the filter) and whether the course was used; ``cost`` is updated in
        place (pairs that leave the gate or fail the identity gate become :data:`FORBIDDEN`).
        """
        a, cfg = self._a, self.config
        use_course = mdl.centre == "hull_box" and bool(np.isfinite(cl.origin_ned).all()) and m.sight is not None
        # (clusters without the sensor position keep the fitted centre)
        ti, cj, zp, Rp, Rpu, wc, vetoed = pair_measurements(
            cost, a["x"], a["P"], m.z, m.R, m.R if m.R_update is None else m.R_update, use_course,
            np.ascontiguousarray(cl.points, dtype=np.float64).reshape(-1, 2),
            np.ascontiguousarray(cl.offsets, dtype=np.int64), np.asarray(cl.origin_ned, dtype=np.float64).reshape(2),
            _end_shadows(cl), _hull_prm(mdl, cl), mdl.heading_floor_rad, cfg.course_min_speed_m_s ** 2,
            cfg.course_max_std_rad ** 2, self._gL, FORBIDDEN, cfg.course_min_returns,
            self._measured_dims(),
            a["mmsi"], a["hasA"], a["tA"], a["xA"], a["PA"], t, cfg.max_coast_ais_s, self._gA_id,
            _NO_SIGHT if m.sight is None else m.sight)
        self._count("lidar_vetoed_by_ais", vetoed)
        return ti, cj, zp, Rp, Rpu, wc

    def _initial_state(self, z: _F8, R: _F8) -> tuple[_F8, _F8]:
        """Track start from position-only (k, 2) or full (k, 4) measurements."""
        k = z.shape[0]
        v2 = self.config.init_velocity_std_m_s ** 2
        x, P = np.zeros((k, 4)), np.zeros((k, 4, 4))
        x[:, :2], P[:, :2, :2] = z[:, :2], R[:, :2, :2]
        if z.shape[1] == 4:
            x[:, 2:] = z[:, 2:]
            P[:, 2:, 2:] = R[:, 2:, 2:]
            P[:, :2, 2:], P[:, 2:, :2] = R[:, :2, 2:], R[:, 2:, :2]
            unknown = R[:, 2, 2] > v2
            x[unknown, 2:] = 0.0
            P[unknown, :2, 2:] = P[unknown, 2:, :2] = 0.0
            P[unknown, 2:, 2:] = v2 * np.eye(2)
        else:
            P[:, 2:, 2:] = v2 * np.eye(2)
        return x, P

    def _fuse_filters(self, t: float) -> None:
        a, cfg = self._a, self.config
        fL = a["hasL"] & (t - a["tL"] <= cfg.fusion_window_s)
        fA = a["hasA"] & (t - a["tA"] <= cfg.fusion_window_s)
        both = np.flatnonzero(fL & fA)
        for only, xk, Pk in ((fL & ~fA, "xL", "PL"), (fA & ~fL, "xA", "PA")):
            a["x"][only], a["P"][only] = a[xk][only], a[Pk][only]
        if both.size:
            if cfg.fusion == "gain_weighted":
                x, P = fuse_gain_weighted(a["xA"][both], a["PA"][both], a["GA"][both],
                                          a["xL"][both], a["PL"][both], a["GL"][both])
            else:
                x, P, _ = fuse_covariance_intersection(a["xA"][both], a["PA"][both], a["xL"][both], a["PL"][both])
            a["x"][both], a["P"][both] = x, P

    def _delete(self, t: float, dead: NDArray[np.bool_], bad: NDArray[np.bool_], lmax: _F8) -> None:
        """Delete the tracks that :func:`~asvtwin.tracking.tracker_kernels.bookkeeping`
        marked (tentative tracks that can no longer reach M of N, tracks not updated for
        ``max_coast_s`` (``max_coast_ais_s`` when tied), position spread beyond
        ``max_position_std_m``, non-finite estimates) and tracks well inside land."""
        a = self._a
        if a["x"].shape[0] == 0:
            return
        if self.land is not None:
            on_land = np.zeros_like(bad)
            p = np.where(bad[:, None], 0.0, a["x"][:, :2])
            inland = self.land.contains(p)
            if inland.any():
                depth = self.land.distance_to_shore(p[inland])
                on_land[np.flatnonzero(inland)] = depth > 3.0 * np.sqrt(lmax[inland]) + 10.0
            dead = dead | on_land
            self._count("deleted_on_land", int((on_land & ~bad).sum()))
        self._count("nan_guard", int(bad.sum()), "track with a non-finite estimate deleted (a bug)")
        if dead.any():
            self._count("tracks_deleted", int(dead.sum()))
            self._keep(~dead)

    def _merge(self) -> None:
        """Merge duplicates: tracks coincident in position and velocity for ``merge_after`` ticks."""
        a, cfg = self._a, self.config
        if a["x"].shape[0] < 2:
            self._pairs = {}
            return
        ii, jj = coincident(a["x"], a["P"], a["mmsi"], self._gM)
        # and physically one place: two vessels abreast with wide covariances are
        # "coincident" in χ² terms but not within merge_distance_m of each other
        close = np.hypot(*(a["x"][ii, :2] - a["x"][jj, :2]).T) <= cfg.merge_distance_m
        ii, jj = ii[close], jj[close]
        pairs: dict[tuple[int, int], int] = {}
        drop = np.zeros(a["x"].shape[0], bool)
        for i, j in zip(ii.tolist(), jj.tolist()):
            key = (int(a["ids"][i]), int(a["ids"][j]))
            pairs[key] = self._pairs.get(key, 0) + 1
            if pairs[key] >= cfg.merge_after and not (drop[i] or drop[j]):
                # keep the MMSI-tied one, else the older (smaller id); hand over the LiDAR filter
                keep, lose = (i, j) if (a["mmsi"][i] >= 0 or a["mmsi"][j] < 0) else (j, i)
                if a["hasL"][lose] and (not a["hasL"][keep] or a["tL"][lose] > a["tL"][keep]):
                    for name in ("xL", "PL", "GL", "hasL", "tL", "axes"):
                        a[name][keep] = a[name][lose]
                a["confirmed"][keep] |= a["confirmed"][lose]
                drop[lose] = True
        self._pairs = pairs
        if drop.any():
            self._count("tracks_merged", int(drop.sum()))
            self._keep(~drop)

    def _start_from_lidar(self, t: float, z: _F8, R: _F8) -> None:
        a, cfg = self._a, self.config
        if a["x"].shape[0]:
            # a track tied to an MMSI with a fresh report is where its AIS says: a cluster
            # near its fused estimate but away from its AIS-only one is another vessel
            near = near_tracks(z, R, a["x"], a["P"], a["xA"], a["PA"], a["mmsi"], a["hasA"], a["tA"], t,
                               float(cfg.fusion_window_s), a["axes"], float(cfg.min_separation_m), self._gL)
            if self._dims:
                near |= self._on_known_hull(z)
            self._count("init_suppressed", int(near.sum()))
            z, R = z[~near], R[~near]
        if not len(z):
            return
        # one new track per cluster; clusters closer than min_separation to each other: keep first
        keep = np.ones(len(z), bool)
        for i in range(1, len(z)):
            keep[i] = not (np.hypot(*(z[:i][keep[:i]] - z[i]).T) < cfg.min_separation_m).any()
        z, R = z[keep], R[keep]
        x, P = self._initial_state(z, R)
        k = len(z)
        self._append({"ids": self._new_ids(k), "x": x, "P": P, "xL": x, "PL": P,
                      "GL": _identities(k, 4), "hasL": np.ones(k, bool), "tL": np.full(k, t),
                      "t_last": np.full(k, t), "hist": np.ones(k, np.int64), "age": np.ones(k, np.int64),
                      "gotL": np.ones(k, bool)})

    def _on_known_hull(self, z: _F8) -> NDArray[np.bool_]:
        """Which cluster centres ``z (k, 2)`` lie on the footprint of a tied track whose
        vessel's AIS length and beam are known: its rectangle along the track's course,
        widened by ``min_separation_m / 3`` (10 m by default, the margin of
        :func:`near_tracks`), for tracks moving at least
        ``course_min_speed_m_s``. The LiDAR sees a long hull's near side, often as more
        than one cluster; without this, its ends started tracks of their own (a 147 m
        vessel passing at 60 m gave 14 track ids in 300 s). A vessel alongside, outside
        the beam plus the margin, still starts its own track."""
        a, cfg = self._a, self.config
        out = np.zeros(len(z), bool)
        if not len(z):
            return out
        dims = self._track_dims()
        v = a["x"][:, 2:]
        spd = np.hypot(v[:, 0], v[:, 1])
        rows = np.flatnonzero(np.isfinite(dims[:, 0]) & (spd >= cfg.course_min_speed_m_s))
        if not rows.size:
            return out
        u = v[rows] / spd[rows, None]  # unit course (north, east)
        d = z[:, None, :] - a["x"][None, rows, :2]  # (k, r, 2)
        along = d[..., 0] * u[None, :, 0] + d[..., 1] * u[None, :, 1]
        across = -d[..., 0] * u[None, :, 1] + d[..., 1] * u[None, :, 0]
        margin = cfg.min_separation_m / 3.0  # 10 m at full scale, as near_tracks' margin
        inside = ((np.abs(along) <= 0.5 * dims[rows, 0][None, :] + margin)
                  & (np.abs(across) <= 0.5 * dims[rows, 1][None, :] + margin))
        return np.asarray(inside.any(axis=1))

    def _start_from_ais(self, t: float, mmsi: NDArray[np.int64], z: _F8, R: _F8) -> None:
        x, P = self._initial_state(z, R)
        k = len(z)
        self._append({"ids": self._new_ids(k), "mmsi": mmsi, "x": x, "P": P, "xA": x, "PA": P,
                      "GA": _identities(k, 4), "hasA": np.ones(k, bool), "tA": np.full(k, t),
                      "t_last": np.full(k, t), "hist": np.ones(k, np.int64), "age": np.ones(k, np.int64),
                      "n_ais": np.ones(k, np.int64), "gotA": np.ones(k, bool)})

    def _snapshot(self, t: float) -> TrackSnapshot:
        a = self._a
        # 0 tentative, 1 confirmed (updated this tick), 2 coasting: TRACK_STATUS[code]
        code = a["confirmed"] * (2 - (a["gotL"] | a["gotA"]))
        status = tuple(_STATUS[code].tolist())
        nan4 = np.full_like(a["x"], np.nan)
        return TrackSnapshot.build(
            t_s=t, ids=a["ids"], mmsi=a["mmsi"], mean=a["x"], cov=a["P"], status=status,
            semi_axes_m=a["axes"], last_update_s=a["t_last"],
            updated_lidar=a["gotL"], updated_ais=a["gotA"],
            lidar_only_mean=np.where(a["hasL"][:, None], a["xL"], nan4),
            ais_only_mean=np.where(a["hasA"][:, None], a["xA"], nan4),
            counters=self._counts,  # build() copies it
        )
