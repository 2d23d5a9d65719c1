"""Simulated transponders: ITU-R M.1371 intervals, and lines pyais itself decodes to the truth."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pyais import decode

from asvtwin.geo import default_scene
from asvtwin.twin.transponders import Transponders
from asvtwin.units import KNOT_M_S


@pytest.fixture(scope="module")
def scene():
    return default_scene()


def _run(scene, speeds_kn, classes, duration_s=400.0, dt=0.5, gnss=(0.0, 0.0), seed=4):
    n = len(speeds_kn)
    tr = Transponders([257000001 + i for i in range(n)], classes, [f"V{i}" for i in range(n)],
                      [70] * n, [80.0] * n, [14.0] * n, frame=scene.frame,
                      epoch_unix_s=1_732_100_400.0, rng=np.random.default_rng(seed),
                      position_std_m=gnss[0], velocity_std_m_s=gnss[1])
    x = np.zeros((n, 6))
    x[:, 0] = 3000.0 + 100 * np.arange(n)
    x[:, 1] = -1500.0
    x[:, 2] = math.radians(30.0)
    x[:, 3] = np.asarray(speeds_kn) * KNOT_M_S
    times: dict[int, list[float]] = {257000001 + i: [] for i in range(n)}
    lines_all = []
    for k in range(int(duration_s / dt)):
        t = k * dt
        for line in tr.step(t, x):
            lines_all.append((t, x.copy(), line))
    for t, _, line in lines_all:
        body = line.split("\\")[-1]
        if body.split(",")[1] == "1":  # single-fragment sentences: dynamic reports
            msg = decode(body)
            if msg.msg_type in (1, 3, 18):
                times[msg.mmsi].append(t)
    return times, lines_all


def test_reporting_intervals_follow_itu_r_m1371(scene):
    times, _ = _run(scene, [10.0, 18.0, 25.0, 10.0], ["A", "A", "A", "B"])
    gaps = {m: set(np.round(np.diff(ts), 6)) for m, ts in times.items()}
    assert gaps[257000001] == {10.0}   # class A, 0-14 kn: 10 s
    assert gaps[257000002] == {6.0}    # class A, 14-23 kn: 6 s
    assert gaps[257000003] == {2.0}    # class A, > 23 kn: 2 s
    assert gaps[257000004] == {30.0}   # class B ("CS"), > 2 kn: 30 s


def test_lines_decode_to_the_truth_with_pyais(scene):
    _, lines = _run(scene, [10.0, 7.0], ["A", "B"], duration_s=200.0)
    checked = statics = 0
    frags: dict[int, list[str]] = {}
    for _, x, line in lines:
        tag, body = line[1:].split("\\", 1)
        assert tag.startswith("s:2579999,c:1732100") and "*" in tag
        parts = body.split(",")
        if parts[1] != "1":  # a two-fragment type 5
            frags.setdefault(int(parts[3] or 0), []).append(body)
            if len(frags[int(parts[3] or 0)]) == 2:
                m = decode(*frags.pop(int(parts[3] or 0)))
                assert m.msg_type == 5 and m.shipname == "V0" and m.to_bow + m.to_stern == 80
                statics += 1
            continue
        m = decode(body)
        if m.msg_type == 24:
            statics += 1
            continue
        i = m.mmsi - 257000001
        north, east = scene.frame.to_ned(m.lat, m.lon)
        # AIS positions are 1/10000 minute: ~0.19 m of latitude
        assert abs(float(north) - x[i, 0]) < 0.5 and abs(float(east) - x[i, 1]) < 0.5
        assert m.speed == pytest.approx(x[i, 3] / KNOT_M_S, abs=0.051)
        assert m.course == pytest.approx(30.0, abs=0.051)
        assert m.heading == 30
        checked += 1
    assert checked >= 25 and statics >= 2


def test_a_vessel_without_ais_and_a_dead_feed_send_nothing(scene):
    tr = Transponders([None, 257000009], [None, "A"], ["X", "Y"], [30, 30], [20.0, 20.0],
                      [5.0, 5.0], frame=scene.frame, epoch_unix_s=0.0,
                      rng=np.random.default_rng(1))
    x = np.zeros((2, 6))
    x[:, 0] = 3000.0
    sent = [decode(line.split("\\")[-1]).mmsi for k in range(60) for line in tr.step(k, x)
            if line.split("\\")[-1].split(",")[1] == "1"]
    assert set(sent) == {257000009}
    tr.alive = False
    assert all(tr.step(60.0 + k, x) == [] for k in range(60))


def _decoded_errors(scene, lines):
    """(north, east) position errors [m] and (v_n, v_e) velocity errors [m/s] of every
    decoded position report against the truth the transponder saw."""
    dp, dv = [], []
    for _, x, line in lines:
        body = line.split("\\")[-1]
        if body.split(",")[1] != "1":
            continue
        m = decode(body)
        if m.msg_type not in (1, 3, 18):
            continue
        i = m.mmsi - 257000001
        north, east = scene.frame.to_ned(m.lat, m.lon)
        dp.append((float(north) - x[i, 0], float(east) - x[i, 1]))
        sog = m.speed * KNOT_M_S
        cog = math.radians(m.course)
        v_true = x[i, 3] * np.array([math.cos(x[i, 2]), math.sin(x[i, 2])])
        dv.append((sog * math.cos(cog) - v_true[0], sog * math.sin(cog) - v_true[1]))
    return np.asarray(dp), np.asarray(dv)


def test_reports_carry_the_documented_gnss_error(scene):
    """Decoded positions scatter about the truth with the GNSS σ (4 m per axis by default):
    the sample variance of k errors lies inside the χ²(k) 99.9 % bounds, the mean inside
    its 4-σ bound; velocities likewise (0.05 m/s) on top of AIS's 0.1 kn / 0.1° rounding."""
    from scipy.stats import chi2

    from asvtwin.twin.transponders import GNSS_POSITION_STD_M, GNSS_VELOCITY_STD_M_S

    sigma_p, sigma_v = GNSS_POSITION_STD_M, GNSS_VELOCITY_STD_M_S
    _, lines = _run(scene, [10.0, 12.0, 18.0, 25.0], ["A", "A", "A", "A"], duration_s=900.0,
                    gnss=(sigma_p, sigma_v))
    dp, dv = _decoded_errors(scene, lines)
    k = dp.size
    assert k > 600
    # position: 1/10000' quantisation (≤ 0.1 m) is negligible against 4 m
    var = float(np.sum(dp ** 2))
    assert chi2.ppf(0.0005, k) < var / sigma_p**2 < chi2.ppf(0.9995, k)
    assert np.all(np.abs(dp.mean(axis=0)) < 4.0 * sigma_p / math.sqrt(len(dp)))
    # velocity: SOG rounding 0.1 kn (σ 0.015 m/s) and COG rounding 0.1° add a little
    sig_v_tot = math.hypot(sigma_v, 0.0514 / math.sqrt(12.0))
    var_v = float(np.sum(dv ** 2))
    assert chi2.ppf(0.0005, dv.size) < var_v / sig_v_tot**2 < chi2.ppf(0.9995, dv.size) * 1.1
    # seeded: the same seed gives the same lines, another seed other errors
    _, again = _run(scene, [10.0, 12.0, 18.0, 25.0], ["A"] * 4, duration_s=900.0,
                    gnss=(sigma_p, sigma_v))
    assert [ln for _, _, ln in again] == [ln for _, _, ln in lines]
    _, other = _run(scene, [10.0, 12.0, 18.0, 25.0], ["A"] * 4, duration_s=900.0,
                    gnss=(sigma_p, sigma_v), seed=5)
    assert not np.allclose(_decoded_errors(scene, other)[0][:50], dp[:50])


def test_gnss_error_must_be_finite_and_non_negative(scene):
    from asvtwin.errors import ParameterError

    with pytest.raises(ParameterError, match="position_std_m must be finite and >= 0"):
        Transponders([1], ["A"], ["X"], [30], [20.0], [5.0], frame=scene.frame,
                     epoch_unix_s=0.0, rng=np.random.default_rng(1), position_std_m=-1.0)


def test_gnss_error_is_froude_scaled_for_a_model_scale_own_ship():
    """4 m / 0.05 m/s at full scale; a 1.255 m model gets 4 × 1.255/87.85 m = 5.7 cm and
    0.05 √(1.255/87.85) m/s; a value in the scenario is taken as written."""
    from asvtwin.twin.runtime import gnss_error

    from .conftest import scenario

    full = scenario()
    assert gnss_error(full, 87.85) == pytest.approx((4.0, 0.05))
    s = 1.255 / 87.85
    assert gnss_error(full, 1.255) == pytest.approx((4.0 * s, 0.05 * math.sqrt(s)))
    set_ = scenario(ais={"mode": "synthetic", "gnss_position_std_m": 2.5,
                         "gnss_velocity_std_m_s": 0.0})
    assert gnss_error(set_, 1.255) == (2.5, 0.0)
