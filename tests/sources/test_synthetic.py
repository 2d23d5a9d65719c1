"""Synthetic fjord traffic: routes in water, the vessel model, NMEA round trip to the registry."""

from __future__ import annotations

import asyncio
import itertools
import math
from collections import defaultdict

import numpy as np
import pytest

from asvtwin.geo import default_scene
from asvtwin.sources.ais import (
    AisPipeline,
    AisReport,
    AisStatic,
    SyntheticAisSource,
    SyntheticTraffic,
    TargetRegistry,
    default_fleet,
    tag_time,
)
from asvtwin.units import KNOT_M_S

from .conftest import T0


@pytest.fixture(scope="module")
def half_hour():
    traffic = SyntheticTraffic(rng=np.random.default_rng(5), start_unix_s=T0,
                               duplicate_probability=0.2)
    return list(traffic.run(1800.0))


def test_routes_are_in_water_and_in_the_scene() -> None:
    scene = default_scene()
    kinds = {v.ship_type for v in default_fleet()}
    assert {30, 37, 60} <= kinds  # fishing, pleasure craft, passenger (ferries, coastal)
    for v in default_fleet():
        ll = np.array(v.route_latlon)
        assert all(scene.bounds.contains(la, lo) for la, lo in ll)
        n, e = scene.frame.to_ned(ll[:, 0], ll[:, 1])
        wp = np.column_stack([n, e])
        pts = np.concatenate([a + (b - a) * np.linspace(0, 1, 300)[:, None]
                              for a, b in itertools.pairwise(wp)])
        assert not scene.land.contains(pts).any(), v.name
        assert scene.land.distance_to_shore(pts).min() > 200.0, v.name


def test_simulated_vessels_stay_in_water_at_their_speed() -> None:
    traffic = SyntheticTraffic(rng=np.random.default_rng(0), start_unix_s=T0).traffic
    scene = traffic.scene
    pos, sog = [], []
    for k in range(int(2 * 3600 / traffic.sim.dt_s)):
        traffic.step()
        if k % 20 == 0:
            p, s, *_ = traffic.kinematics()
            pos.append(p)
            sog.append(s)
    pos, sog = np.array(pos), np.array(sog)
    for i, v in enumerate(traffic.fleet):
        assert not scene.land.contains(pos[:, i]).any(), v.name
        assert scene.land.distance_to_shore(pos[:, i]).min() > 100.0, v.name
        assert sog[:, i].max() == pytest.approx(v.cruise_speed_m_s, rel=0.05), v.name
        assert np.all(np.isfinite(pos[:, i]))


def test_round_trip_ground_truth_to_registry(half_hour) -> None:
    pipe = AisPipeline()
    batch = pipe.feed_batch([x.line for x in half_hour])
    reg = TargetRegistry(epoch_unix_s=T0)
    reg.update_batch(batch)
    truth: dict[int, AisReport] = {}
    for x in half_hour:
        if isinstance(x.truth, AisReport):
            truth[x.truth.mmsi] = x.truth
    # a message heard by both stations is one duplicate (however many fragments it has)
    heard: dict[tuple[int, str], int] = defaultdict(int)
    for x in half_hour:
        fields = x.line[x.line.index("!"):].split(",")
        if fields[2] == "1":
            heard[(id(x.truth), fields[5])] += 1
    assert pipe.stats.errors == {"duplicate": sum(c - 1 for c in heard.values())}
    assert pipe.stats.errors["duplicate"] > 20
    # bounded state: the dedup memory holds the last two dedup windows (2 x 30 s) only
    recent = sum(1 for x in half_hour if x.t_unix_s >= half_hour[-1].t_unix_s - 60.0)
    assert len(pipe.duplicates) <= recent
    t_last = max(t.t_unix_s for t in truth.values()) - T0
    snap = reg.extrapolate(t_last)
    assert sorted(snap.mmsi.tolist()) == sorted(v.mmsi for v in default_fleet())
    latest = {r.mmsi: r for r in batch.reports()}
    for mmsi, t in truth.items():
        r = latest[mmsi]
        assert r.t_unix_s == t.t_unix_s
        assert math.hypot(r.north_m - t.north_m, r.east_m - t.east_m) < 0.25
        assert abs(r.sog_m_s - t.sog_m_s) <= 0.05 * KNOT_M_S + 1e-9
        if t.sog_m_s > 0.5:
            assert abs(math.remainder(r.cog_rad - t.cog_rad, 2 * math.pi)) <= math.radians(0.051)
        assert abs(math.remainder(r.heading_rad - t.heading_rad, 2 * math.pi)) <= math.radians(0.5)
        i = snap.mmsi.tolist().index(mmsi)
        dt = t_last - (t.t_unix_s - T0)
        assert snap.age_s[i] == pytest.approx(dt)
    for v in default_fleet():
        s = reg.static(v.mmsi)
        assert s is not None and s.name == v.name and s.ship_type == v.ship_type
        assert s.length_m == pytest.approx(1.255 * v.scale, abs=1.0)


def test_reporting_intervals_follow_the_standard(half_hour) -> None:
    times: dict[int, list[float]] = defaultdict(list)
    static_types: dict[int, set[int]] = defaultdict(set)
    for x in half_hour:
        if isinstance(x.truth, AisReport):
            if not times[x.truth.mmsi] or times[x.truth.mmsi][-1] != x.t_unix_s:
                times[x.truth.mmsi].append(x.t_unix_s)
        elif isinstance(x.truth, AisStatic):
            static_types[x.truth.mmsi].add(x.truth.msg_type)
    for v in default_fleet():
        gaps = set(np.diff(times[v.mmsi]).tolist())
        if v.ais_class == "B":
            assert gaps <= {30.0, 180.0} and static_types[v.mmsi] == {24}
        else:
            assert gaps <= {2.0, 3.0, 6.0, 10.0, 180.0} and static_types[v.mmsi] == {5}
            assert 10.0 in gaps


def test_same_seed_same_feed_and_tagged_like_the_coastal_feed() -> None:
    a = list(SyntheticTraffic(rng=np.random.default_rng(9), start_unix_s=T0).lines(300))
    b = list(SyntheticTraffic(rng=np.random.default_rng(9), start_unix_s=T0).lines(300))
    c = list(SyntheticTraffic(rng=np.random.default_rng(10), start_unix_s=T0).lines(300))
    assert a == b and a != c
    assert all(x.startswith("\\s:257900") and "!ABVDM," in x for x in a)
    assert [tag_time(x.encode()) for x in a] == sorted(tag_time(x.encode()) for x in a)


def test_synthetic_source_runs_the_real_pipeline() -> None:
    src = SyntheticAisSource(SyntheticTraffic(rng=np.random.default_rng(1), start_unix_s=T0),
                             speed=None, duration_s=120.0)

    async def collect():
        return [m async for m in src]

    msgs = asyncio.run(collect())
    assert {m.mmsi for m in msgs if isinstance(m, AisReport)} == {v.mmsi for v in default_fleet()}
    assert src.status().stats.reports == sum(isinstance(m, AisReport) for m in msgs)
    assert not src.status().connected
