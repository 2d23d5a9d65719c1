"""The numba measurement/tracker kernels against plain numpy references, and the AIS array path.

The references are the straightforward numpy formulas of the LiDAR and AIS measurement
models (docs/tracking.md); the kernels must give the same numbers (LiDAR: bit for bit,
sums in numpy's pairwise order; AIS: to rounding, numpy's small matmul may use FMA).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from asvtwin.errors import StateError
from asvtwin.sensors import Lidar, LidarConfig
from asvtwin.tracking import (
    AisMeasurement,
    AisMeasurementBatch,
    AisModel,
    Clusters,
    LidarModel,
    Tracker,
    ais_measurements,
    cluster_scan,
    fit_ellipses,
    lidar_measurements,
)
from asvtwin.tracking.clustering import _group
from asvtwin.tracking.measurement_kernels import _pairwise


def _lidar_reference(cl: Clusters, mdl: LidarModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    fits = fit_ellipses(cl.points, cl.offsets)
    cen = cl.centroids
    a, b = fits.semi_axes[:, 0], fits.semi_axes[:, 1]
    d2 = ((cl.points - np.repeat(cen, cl.sizes, axis=0)) ** 2).sum(axis=1)
    ext = np.sqrt(np.add.reduceat(d2, cl.offsets[:-1]) / cl.sizes)
    half = np.sqrt(np.maximum.reduceat(d2, cl.offsets[:-1]))
    with np.errstate(invalid="ignore"):
        use = (fits.ok & (a <= mdl.max_semi_axis_m) & (fits.arc_coverage_rad >= mdl.min_coverage_rad)
               & (a <= 2.0 * half + mdl.fit_floor_m) & (b >= mdl.needle_ratio * a)
               & (np.hypot(*(fits.centre - cen).T) <= a + mdl.fit_floor_m))
    z = np.where(use[:, None], fits.centre, cen)
    origin = np.asarray(cl.origin_ned, float)
    if not np.isfinite(origin).all():
        origin = z.mean(axis=0) - np.array([1.0e4, 0.0])
    cov, resid = np.nan_to_num(fits.arc_coverage_rad, nan=0.0), np.nan_to_num(fits.residual_m, nan=0.0)
    var_fit = mdl.fit_floor_m**2 + resid**2
    a0, b0 = np.nan_to_num(a), np.nan_to_num(b)
    los_fit = (mdl.range_std_m**2 + var_fit + (mdl.depth_gain * b0) ** 2
               + (mdl.coverage_gain * a0 * np.clip(1.0 - cov / np.pi, 0.0, 1.0)) ** 2)
    los_cen = mdl.range_std_m**2 + mdl.fit_floor_m**2 + np.maximum(mdl.needle_depth_gain * half,
                                                                  mdl.default_half_depth_m) ** 2
    d = z - origin
    r = np.hypot(d[:, 0], d[:, 1])
    vl = np.where(use, los_fit, los_cen)
    vc = (r * mdl.bearing_std_rad) ** 2 + np.where(use, var_fit + (mdl.end_gain * a0) ** 2,
                                                   mdl.fit_floor_m**2 + ext**2)
    c, s = d[:, 0] / r, d[:, 1] / r
    R = np.empty((len(z), 2, 2))
    R[:, 0, 0] = c * c * vl + s * s * vc
    R[:, 1, 1] = s * s * vl + c * c * vc
    R[:, 0, 1] = R[:, 1, 0] = c * s * (vl - vc)
    return z, R, use


@pytest.fixture(scope="module")
def scan_clusters() -> Clusters:
    rng = np.random.default_rng(5)
    n = 40
    b, r = rng.uniform(-np.pi, np.pi, n), rng.uniform(60.0, 450.0, n)
    targets = np.column_stack([r * np.cos(b), r * np.sin(b), rng.normal(0, 2, (n, 2))])
    length = rng.uniform(10.0, 60.0, n)
    scan = Lidar(LidarConfig(n_rays=3600, max_range_m=500.0)).scan(np.zeros(6), targets, length, length / 4,
                                                                     None, rng)
    cl = cluster_scan(scan)
    assert len(cl) > 20 and cl.sizes.max() > 128  # pairwise sums take the split path
    return cl


def test_lidar_kernel_equals_numpy_reference_bit_for_bit(scan_clusters: Clusters) -> None:
    mdl = LidarModel(centre="ellipse")  # the paper's fitted-centre model, as the reference computes it
    for cl in (scan_clusters, Clusters(scan_clusters.points, scan_clusters.offsets)):  # known / unknown origin
        m = lidar_measurements(cl, mdl)
        z, R, use = _lidar_reference(cl, mdl)
        assert 0 < use.sum() < len(use)  # both the fit and the centroid branch are exercised
        np.testing.assert_array_equal(m.used_fit, use)
        np.testing.assert_array_equal(m.z, z)
        np.testing.assert_allclose(m.R, R, rtol=1e-14, atol=0.0)


def test_pairwise_sum_and_grouping_match_numpy() -> None:
    rng = np.random.default_rng(2)
    for n in (1, 7, 8, 100, 128, 129, 1000, 3601):
        a = rng.normal(5000.0, 300.0, (n, 2))
        assert _pairwise(a, 0, n, 1) == np.add.reduce(a[:, 1])
    pts = rng.normal(size=(500, 2))
    labels = rng.integers(0, 60, 500)
    p, off, small = _group(pts, labels, 9)
    _, inv, counts = np.unique(labels, return_inverse=True, return_counts=True)
    order = np.argsort(inv, kind="stable")
    order = order[(counts[inv] >= 9)[order]]
    np.testing.assert_array_equal(p, pts[order])
    np.testing.assert_array_equal(np.diff(off), counts[counts >= 9])
    assert small == int(counts[counts < 9].sum())


def _reports(rng: np.random.Generator, k: int, t: float) -> list[AisMeasurement]:
    out = [AisMeasurement(257000000 + int(rng.integers(0, k // 2)), t - float(rng.uniform(0, 40)),
                          float(rng.normal(0, 500)), float(rng.normal(0, 500)), float(rng.uniform(0, 8)),
                          float(rng.uniform(-np.pi, np.pi))) for _ in range(k)]
    out += [AisMeasurement(257000999, t, 1.0, 2.0), AisMeasurement(0, t, 1.0, 1.0),
            AisMeasurement(257000998, float("nan"), 1.0, 1.0), AisMeasurement(257000997, t, 3.0, 4.0, -1.0, 0.0),
            AisMeasurement(257000996, t + 5.0, 3.0, 4.0)]
    return out


def test_ais_kernel_equals_numpy_reference() -> None:
    rng = np.random.default_rng(3)
    mdl = AisModel()
    reports = _reports(rng, 120, 100.0)
    am = ais_measurements(reports, 100.0, mdl)
    arr = np.array([(r.mmsi, r.t_s, r.north_m, r.east_m, r.sog_m_s, r.cog_rad) for r in reports])
    mmsi, tr, n, e, sog, cog = arr[:, 0].astype(np.int64), *arr[:, 1:].T
    good = np.isfinite(tr) & (mmsi > 0) & ~(sog < 0.0)
    fresh = (100.0 - tr <= mdl.max_age_s) & (100.0 - tr >= -mdl.max_future_s)
    assert am.n_rejected == int((~good).sum()) == 3 and am.n_stale == int((good & ~fresh).sum())
    keep = np.flatnonzero(good & fresh)
    order = keep[np.lexsort((tr[keep], mmsi[keep]))]
    idx = order[np.r_[mmsi[order][1:] != mmsi[order][:-1], True]]
    np.testing.assert_array_equal(am.mmsi, mmsi[idx])
    hv = np.isfinite(sog[idx])
    s, c, dt = np.where(hv, sog[idx], 0.0), np.where(hv, cog[idx], 0.0), 100.0 - tr[idx]
    v = np.column_stack([s * np.cos(c), s * np.sin(c)])
    np.testing.assert_array_equal(am.z, np.column_stack([n[idx] + v[:, 0] * dt, e[idx] + v[:, 1] * dt, v]))
    J = np.stack([np.column_stack([np.cos(c), -s * np.sin(c)]), np.column_stack([np.sin(c), s * np.cos(c)])], 1)
    Rv = J @ np.diag([mdl.sog_std_m_s**2, mdl.cog_std_rad**2]) @ J.transpose(0, 2, 1) + mdl.sog_std_m_s**2 * 1e-2 * np.eye(2)
    Rv[~hv] = 1e6 * np.eye(2)
    h = hv[:, None, None] * Rv
    I2, q = np.eye(2), mdl.accel_q
    top = np.concatenate([mdl.position_std_m**2 * I2 + h * (dt**2)[:, None, None]
                          + (q * np.abs(dt) ** 3 / 3)[:, None, None] * I2, h * dt[:, None, None]], 2)
    bot = np.concatenate([(h * dt[:, None, None]).transpose(0, 2, 1), Rv + (q * np.abs(dt))[:, None, None] * I2], 2)
    np.testing.assert_allclose(am.R, np.concatenate([top, bot], 1), rtol=1e-13, atol=1e-300)


def test_ais_batch_equals_list_and_reads_the_pipeline_batch() -> None:
    rng = np.random.default_rng(4)
    reports = _reports(rng, 60, 50.0)
    batch = AisMeasurementBatch.from_list(reports)
    assert len(batch) == len(reports) and batch.mmsi.dtype == np.int64
    a, b = ais_measurements(reports, 50.0), ais_measurements(batch, 50.0)
    assert (a.mmsi == b.mmsi).all() and (a.z == b.z).all() and (a.R == b.R).all()
    assert (a.n_rejected, a.n_stale) == (b.n_rejected, b.n_stale)
    # the AIS pipeline's ReportBatch, read by its columns: unix time minus the scene epoch
    rb = SimpleNamespace(mmsi=batch.mmsi, t_unix_s=batch.t_s + 1.7e9, north_m=batch.north_m, east_m=batch.east_m,
                         sog_m_s=batch.sog_m_s, cog_rad=batch.cog_rad, lat_deg=batch.north_m * np.nan)
    c = ais_measurements(AisMeasurementBatch.from_batch(rb, epoch_unix_s=1.7e9), 50.0)
    np.testing.assert_array_equal(c.mmsi, a.mmsi)
    np.testing.assert_allclose(c.z, a.z, atol=1e-6)  # t_s lost ~1e-7 s to the unix offset
    with pytest.raises(StateError, match="east_m"):
        AisMeasurementBatch(batch.mmsi, batch.t_s, batch.north_m, batch.east_m[:-1], batch.sog_m_s, batch.cog_rad)
    with pytest.raises(StateError, match="t_unix_s"):
        AisMeasurementBatch.from_batch(SimpleNamespace(mmsi=batch.mmsi))
    assert len(ais_measurements(AisMeasurementBatch.from_list([]), 0.0)) == 0


def test_tracker_gives_the_same_tracks_for_ais_objects_and_columns() -> None:
    rng = np.random.default_rng(6)
    x0 = np.array([[150.0, 40.0, 1.0, 0.5], [-200.0, 120.0, -0.5, 1.5], [60.0, -250.0, 0.0, -2.0]])
    lidar = Lidar(LidarConfig(n_rays=720))
    t_obj, t_col = Tracker(), Tracker()
    for k in range(25):
        x = x0.copy()
        x[:, :2] += x0[:, 2:] * k
        scan = lidar.scan(np.zeros(6), x, [30.0, 20.0, 40.0], [8.0, 5.0, 10.0], None, rng, t_s=float(k))
        p = x[:, :2] + rng.normal(0.0, 5.0, (3, 2))
        rep = [AisMeasurement(257000000 + i, float(k), float(p[i, 0]), float(p[i, 1]), float(np.hypot(*x[i, 2:])),
                              float(np.arctan2(x[i, 3], x[i, 2]))) for i in range(3) if (k + i) % 4 == 0]
        s1, s2 = t_obj.step(float(k), scan, rep), t_col.step(float(k), scan, AisMeasurementBatch.from_list(rep))
        np.testing.assert_array_equal(s1.mean, s2.mean)
        np.testing.assert_array_equal(s1.cov, s2.cov)
        assert s1.mmsi == s2.mmsi and s1.status == s2.status
    assert len(s1.confirmed()) == 3 and all(m is not None for m in s1.confirmed().mmsi)
