"""Target registry: dead reckoning, the error bound of a turning ship, staleness, memory."""

from __future__ import annotations

import math

import numpy as np
import pytest

from asvtwin.sources.ais import (
    AisPipeline,
    AisReport,
    AisStatic,
    ReportBatch,
    TargetRegistry,
    default_fleet,
    nominal_report_interval_s,
)
from asvtwin.units import KNOT_M_S
from asvtwin.vessel import BatchSimulator

from .conftest import T0, line, report


def test_constant_velocity_dead_reckoning_by_hand() -> None:
    reg = TargetRegistry(epoch_unix_s=T0)
    r = report(sog_m_s=5.0, cog_deg=45.0, rot_rad_s=None)
    reg.update(r)
    snap = reg.extrapolate(20.0)
    # 5 m/s for 20 s on 045: 100 m, i.e. 70.7107 m north and east
    assert snap.position_m[0, 0] - r.north_m == pytest.approx(70.71067811865476, abs=1e-9)
    assert snap.position_m[0, 1] - r.east_m == pytest.approx(70.71067811865476, abs=1e-9)
    assert snap.velocity_m_s[0] == pytest.approx([3.5355339, 3.5355339])
    assert snap.age_s[0] == 20.0 and bool(snap.velocity_known[0])


def test_rate_of_turn_arc_then_straight() -> None:
    reg = TargetRegistry(epoch_unix_s=T0, rot_horizon_s=30.0)
    r = report(sog_m_s=5.0, cog_deg=0.0, heading_deg=0.0, rot_rad_s=0.01)
    reg.update(r)
    s30 = reg.extrapolate(30.0)
    # arc of radius U/ω = 500 m through 0.3 rad: 500 sin 0.3 north, 500 (1 - cos 0.3) east
    assert s30.position_m[0, 0] - r.north_m == pytest.approx(500 * math.sin(0.3), abs=1e-9)
    assert s30.position_m[0, 1] - r.east_m == pytest.approx(500 * (1 - math.cos(0.3)), abs=1e-9)
    assert s30.heading_rad[0] == pytest.approx(0.3)
    s40 = reg.extrapolate(40.0)  # 10 s more, straight on 0.3 rad
    step = s40.position_m[0] - s30.position_m[0]
    assert step == pytest.approx([50 * math.cos(0.3), 50 * math.sin(0.3)], abs=1e-9)
    # the same report without ROT extrapolation
    reg0 = TargetRegistry(epoch_unix_s=T0, rot_horizon_s=0.0)
    reg0.update(r)
    assert reg0.extrapolate(30.0).position_m[0] - [r.north_m, r.east_m] == pytest.approx([150, 0])


def _turning_truth(dt_s: float = 0.5, minutes: float = 6.0):
    """A fjord ferry (CyberShip II x70) in a steady port turn, states every dt_s."""
    ferry = default_fleet()[0]
    p = ferry.params()
    sim = BatchSimulator(p, [[0.0, 0.0, 0.0, 3.5, 0.0, 0.0]], dt_s=dt_s)
    U = 3.5
    tau_u = -(p.X_u * U + p.X_uu * U * U + p.X_uuu * U**3)
    tau_r = 0.25 * p.actuators.tau_min[2]
    states = [sim.state[0]]
    for _ in range(int(minutes * 60 / dt_s)):
        states.append(sim.step([tau_u, 0.0, tau_r])[0])
    return np.array(states)


def test_extrapolation_error_bound_for_a_turning_vessel() -> None:
    """Reports every 10 s from a turning ship; dead reckoning in between.

    Constant velocity misses the arc by at most U |r| τ² / 2 (plus AIS resolution); using the
    reported rate of turn it does much better.
    """
    dt = 0.5
    x = _turning_truth(dt)
    x = x[int(120 / dt):]  # after the turn has settled
    frame_lat, frame_lon = 63.46, 10.40
    from asvtwin.geo import default_scene

    frame = default_scene().frame
    n0, e0 = frame.to_ned(frame_lat, frame_lon)
    pos = x[:, :2] + [float(n0), float(e0)]
    vn = np.cos(x[:, 2]) * x[:, 3] - np.sin(x[:, 2]) * x[:, 4]
    ve = np.sin(x[:, 2]) * x[:, 3] + np.cos(x[:, 2]) * x[:, 4]
    U = float(np.mean(np.hypot(vn, ve)))
    r_abs = float(np.mean(np.abs(x[:, 5])))
    assert r_abs > math.radians(0.3)  # a real turn: more than 18 deg/min
    lat, lon = frame.to_wgs84(pos[:, 0], pos[:, 1])
    every = int(10 / dt)
    errs = {"cv": [], "rot": []}
    for horizon, key in ((0.0, "cv"), (60.0, "rot")):
        pipe = AisPipeline()
        reg = TargetRegistry(epoch_unix_s=T0, rot_horizon_s=horizon)
        for k in range(0, len(x) - every, every):
            truth = AisReport(257000001, T0 + k * dt, 1, float(pos[k, 0]), float(pos[k, 1]),
                              float(lat[k]), float(lon[k]), float(np.hypot(vn[k], ve[k])),
                              float(np.arctan2(ve[k], vn[k])), float(x[k, 2]), float(x[k, 5]), 0)
            reg.update_batch(pipe.feed(line(truth)))
            for j in range(1, every):
                snap = reg.extrapolate(k * dt + j * dt)
                errs[key].append((j * dt, float(np.hypot(*(snap.position_m[0] - pos[k + j])))))
    cv = np.array(errs["cv"])
    rot = np.array(errs["rot"])
    bound = 0.5 * U * r_abs * cv[:, 0] ** 2 + 0.5  # arc vs chord, + AIS resolution
    assert np.all(cv[:, 1] <= 1.1 * bound)
    assert cv[:, 1].max() > 0.5 * bound.max()  # the bound is tight, not vacuous
    assert rot[:, 1].max() < 0.35 * cv[:, 1].max()


def test_stale_by_reporting_interval_and_eviction() -> None:
    reg = TargetRegistry(epoch_unix_s=T0, evict_after_s=600.0)
    reg.update(report(257000001, sog_m_s=5.0))  # class A under way: 10 s
    reg.update(report(257000002, sog_m_s=3.0, msg_type=18))  # class B: 30 s
    reg.update(report(257000003, sog_m_s=0.0, nav_status=5))  # moored: 180 s
    snap = reg.extrapolate(60.0)
    assert dict(zip(snap.mmsi.tolist(), snap.stale.tolist())) == {
        257000001: True, 257000002: False, 257000003: False}
    snap = reg.extrapolate(100.0)
    assert snap.stale.tolist() == [True, True, False]
    assert len(reg.extrapolate(599.0)) == 3
    assert len(reg.extrapolate(601.0)) == 0 and reg.evicted == 3


def test_nominal_intervals() -> None:
    kn = 1852 / 3600
    got = nominal_report_interval_s(np.array([25, 18, 8, 0, 8, 1, np.nan]) * kn,
                                    np.array([0, 0, 0, 0, 1, 1, 0], dtype=bool),
                                    np.array([0, 0, 0, 1, -1, -1, -1]))
    assert got.tolist() == [2.0, 6.0, 10.0, 180.0, 30.0, 180.0, 10.0]


def test_nominal_intervals_compiled_as_the_table_reads_everywhere() -> None:
    """The compiled intervals against the table written as array expressions (the form
    they had before), on random speeds and the table's edges (2, 3, 14 and 23 kn exactly,
    NaN, ±inf), every class and navigational status, and a broadcast scalar."""
    kn = 1852 / 3600
    rng = np.random.default_rng(3)
    sog = np.concatenate([rng.uniform(0.0, 30.0, 2000),
                          [2.0, 3.0, 14.0, 23.0, np.nan, np.inf, -np.inf, 0.0]]) * kn
    n = sog.shape[0]
    class_b = rng.random(n) < 0.4
    nav = rng.integers(-1, 16, n)

    def table(sog_m_s, cb, status):
        sog_kn = np.nan_to_num(sog_m_s / kn, nan=10.0)
        a = np.where(sog_kn > 23.0, 2.0, np.where(sog_kn > 14.0, 6.0, 10.0))
        a = np.where((sog_kn <= 3.0) & ((status == 1) | (status == 5)), 180.0, a)
        return np.where(cb, np.where(sog_kn > 2.0, 30.0, 180.0), a)

    assert np.array_equal(nominal_report_interval_s(sog, class_b, nav),
                          table(sog, class_b, nav))
    got = nominal_report_interval_s(np.array([1.0, 8.0]) * kn, np.bool_(False), np.int64(5))
    assert got.tolist() == [180.0, 10.0]


def test_older_report_does_not_overwrite() -> None:
    reg = TargetRegistry(epoch_unix_s=T0)
    reg.update(report(t=T0 + 10))
    reg.update(report(t=T0, lat=63.47))
    assert reg.ignored_older == 1
    assert reg.extrapolate(10.0).age_s[0] == 0.0


def test_memory_is_bounded_under_mmsi_churn() -> None:
    reg = TargetRegistry(capacity=100, evict_after_s=1e9)
    rng = np.random.default_rng(3)
    for k in range(50):
        m = np.arange(200_000_000 + 1000 * k, 200_000_000 + 1000 * (k + 1), dtype=np.int64)
        z = np.zeros(1000)
        reg.update_batch(ReportBatch(m, z + k, np.ones(1000, dtype=np.int64),
                                     rng.normal(size=1000), rng.normal(size=1000), z, z, z, z, z,
                                     z, np.zeros(1000, dtype=np.int64), (None,) * 1000))
        for i in range(0, 1000, 97):
            reg.update_static(AisStatic(int(m[i]), float(k), 5, name=f"V{i}"))
        assert len(reg) <= 100
        assert len(reg._static) <= 200
    assert reg.evicted == 49 * 100  # each batch brings 1000 new vessels; the newest 100 stay
    snap = reg.extrapolate(50.0)
    assert len(snap) == len(reg) and len(set(snap.mmsi.tolist())) == len(snap)
    assert snap.mmsi.min() >= 200_049_000  # the newest batch won


def test_report_becomes_the_trackers_measurement() -> None:
    from asvtwin.tracking import AisMeasurement

    m = AisMeasurement.from_report(report(t=T0 + 12.5), epoch_unix_s=T0)
    assert (m.mmsi, m.t_s) == (257000001, 12.5)
    assert m.sog_m_s == 5.0 and m.cog_rad == pytest.approx(math.pi / 4)
    r = report(t=T0 + 1.0)
    assert (m.north_m, m.east_m) == (r.north_m, r.east_m)
    na = AisMeasurement.from_report(report(sog_m_s=None, cog_deg=None), epoch_unix_s=T0)
    assert math.isnan(na.sog_m_s) and math.isnan(na.cog_rad)  # "not available" as NaN


# ----------------------------------------------------------------------------- issue items 13-15
def test_staleness_follows_the_reporting_interval_without_a_floor() -> None:
    """Before: a 30 s floor kept a 25-kn ship (reporting every 2 s) fresh for 30 s; a class B
    without COG counted as stopped (3 min interval) and went stale only after 540 s."""
    reg = TargetRegistry(epoch_unix_s=T0)
    reg.update(report(mmsi=1, t=T0, sog_m_s=25 * KNOT_M_S))  # class A at 25 kn: 2 s
    reg.update(report(mmsi=2, t=T0, sog_m_s=10 * KNOT_M_S, cog_deg=None, msg_type=18))
    at = {t: dict(zip(s.mmsi.tolist(), s.stale.tolist()))
          for t in (5.9, 6.1, 89.0, 91.0) for s in [reg.extrapolate(t, evict=False)]}
    assert at[5.9][1] is False and at[6.1][1] is True  # 3 x 2 s
    assert at[89.0][2] is False and at[91.0][2] is True  # 3 x 30 s, SOG kept without COG
    snap = reg.extrapolate(10.0)
    i = snap.mmsi.tolist().index(2)
    assert snap.sog_m_s[i] == pytest.approx(10 * KNOT_M_S) and np.isnan(snap.cog_rad[i])
    assert not snap.velocity_known[i]  # no course: not moved, but its speed is known


def test_dead_reckoning_is_geodetic_at_the_edge_of_the_scene() -> None:
    """Before: dead reckoning in the origin's tangent plane was 41 m off after 600 s at the
    scene's edge. Oracle: pymap3d's rhumb line (loxodrome) on WGS84, projected exactly."""
    from pymap3d.lox import loxodrome_direct

    from asvtwin.geo import default_scene
    from asvtwin.sources.ais import AisPipeline, encode_report



    frame = default_scene().frame
    p = AisPipeline()
    reg = TargetRegistry(epoch_unix_s=T0)
    starts = [(63.43, 10.74, 0.0), (63.62, 9.86, 90.0), (63.66, 10.70, 225.0)]
    for k, (lat, lon, cog) in enumerate(starts):
        reg.update_batch(p.feed(line(report(mmsi=10 + k, t=T0, lat=lat, lon=lon, sog_m_s=10.0,
                                            cog_deg=cog, rot_rad_s=None))))
    assert p.stats.reports == 3
    snap = reg.extrapolate(600.0)
    for k, (lat, lon, cog) in enumerate(starts):
        r = p.feed(encode_report(report(lat=lat, lon=lon)), recv_time_s=T0)  # AIS resolution
        lat_q, lon_q = float(r.lat_deg[0]), float(r.lon_deg[0])
        sog_q = round(10.0 / KNOT_M_S, 1) * KNOT_M_S
        lat2, lon2 = loxodrome_direct(lat_q, lon_q, sog_q * 600.0, cog)
        truth = np.array(frame.to_ned(lat2, lon2), dtype=float)
        i = snap.mmsi.tolist().index(10 + k)
        assert np.linalg.norm(snap.position_m[i] - truth) < 0.05
        assert (snap.lat_deg[i], snap.lon_deg[i]) == pytest.approx((lat2, lon2), abs=1e-7)
        # the velocity in the scene's axes is turned by the meridian convergence: east of
        # the origin, a ship's north leans west (towards the pole on the origin's meridian)
        chi_frame = math.atan2(snap.velocity_m_s[i, 1], snap.velocity_m_s[i, 0])
        gamma = -math.radians(lon2 - frame.lon0_deg) * math.sin(math.radians(lat2))
        assert chi_frame == pytest.approx(math.radians(cog) + gamma - 2 * math.pi * (cog > 180),
                                          abs=2e-4)


def test_not_available_is_explicit_in_the_snapshot_and_the_table() -> None:
    """Before: COG 72.4 at SOG 0 showed as 0.0 (from the velocity vector), a known SOG was
    hidden when COG was missing, an unavailable heading showed as 0.0 or as the COG."""
    from rich.console import Console

    from asvtwin.cli.ais import _table

    reg = TargetRegistry(epoch_unix_s=T0)
    reg.update(report(mmsi=1, t=T0, sog_m_s=0.0, cog_deg=72.4, heading_deg=None))
    reg.update(report(mmsi=2, t=T0, sog_m_s=3.0, cog_deg=None, heading_deg=None))
    reg.update(report(mmsi=3, t=T0, sog_m_s=None, cog_deg=None, heading_deg=100.0))
    snap = reg.extrapolate(1.0)
    assert math.degrees(snap.cog_rad[0]) == pytest.approx(72.4)
    assert np.isnan(snap.true_heading_rad[:2]).all() and np.isnan(snap.sog_m_s[2])
    assert math.degrees(snap.true_heading_rad[2]) == pytest.approx(100.0)
    console = Console(width=200, record=True)
    console.print(_table(snap, "t", 10))
    rows = {ln.split("│")[1].strip(): [c.strip() for c in ln.split("│")[1:-1]]
            for ln in console.export_text().splitlines() if "│" in ln and "MMSI" not in ln}
    assert rows["1"][5:8] == ["0.0", "72.4", "-"]  # SOG, COG, HDG
    assert rows["2"][5:8] == ["5.8", "-", "-"]
    assert rows["3"][5:8] == ["-", "-", "100.0"]


def _numpy_dead_reckoning(U, chi, w, dt, horizon_s, lat, lon):  # type: ignore[no-untyped-def]
    """The registry's dead reckoning as NumPy arrays (the code the compiled kernels
    replaced), the reference they must reproduce."""
    from asvtwin.geo import WGS84_A_M, WGS84_F

    e2 = WGS84_F * (2.0 - WGS84_F)
    turning = np.abs(w) > 1e-5
    tau = np.where(turning, np.minimum(dt, horizon_s), 0.0)
    chi_end = chi + w * tau
    w_safe = np.where(turning, w, 1.0)
    arc_n = np.where(turning, U / w_safe * (np.sin(chi_end) - np.sin(chi)), 0.0)
    arc_e = np.where(turning, U / w_safe * (np.cos(chi) - np.cos(chi_end)), 0.0)
    run = U * (dt - tau)
    d_n = arc_n + run * np.cos(chi_end)
    d_e = arc_e + run * np.sin(chi_end)
    phi0 = np.radians(lat)
    phi1 = phi0
    for _ in range(3):
        phi_m = 0.5 * (phi0 + phi1)
        ww = 1.0 - e2 * np.sin(phi_m) ** 2
        M = WGS84_A_M * (1.0 - e2) / ww**1.5
        phi1 = phi0 + d_n / M
    N = WGS84_A_M / np.sqrt(ww)
    return d_n, d_e, chi_end, tau, np.degrees(phi1), lon + np.degrees(d_e / (N * np.cos(phi_m)))


def test_compiled_dead_reckoning_equals_the_numpy_formulas() -> None:
    """The compiled dead reckoning (turn, then straight on) and rhumb-line step give the
    NumPy formulas' numbers to 1e-12 for straight, turning and slowly turning targets,
    ages below and beyond the turn horizon, at Trondheim's latitude and near the pole."""
    from asvtwin.sources.ais.registry import dead_reckon, rhumb_destination

    rng = np.random.default_rng(4)
    n = 400
    U = rng.uniform(0.0, 15.0, n)
    chi = rng.uniform(-np.pi, np.pi, n)
    w = rng.choice([0.0, 1e-6, 0.01, -0.05], n) * rng.uniform(0.5, 1.5, n)
    dt = rng.uniform(0.0, 600.0, n)
    lat = rng.choice([63.44, 85.0, -40.0], n) + rng.uniform(-0.1, 0.1, n)
    lon = rng.uniform(-180.0, 179.0, n)
    ref = _numpy_dead_reckoning(U, chi, w, dt, 60.0, lat, lon)
    got = (*dead_reckon(U, chi, w, dt, 60.0), *rhumb_destination(lat, lon, *ref[:2]))
    for g, r in zip(got, ref, strict=True):
        np.testing.assert_allclose(g, r, rtol=1e-12, atol=1e-9)
    # broadcasting as before: one origin for many displacements, and scalars
    la, lo = rhumb_destination(63.44, 10.39, ref[0][:5], ref[1][:5])
    assert la.shape == (5,) and lo.shape == (5,)
    la0, lo0 = rhumb_destination(63.44, 10.39, 1000.0, 0.0)
    assert np.shape(la0) == () and 63.44 < float(la0) < 63.46 and float(lo0) == 10.39
