"""The world's targets: COLREG give-way turns to starboard, stand-on holds; waypoint routes;
an AIS log replayed into the twin (ais.mode file)."""

from __future__ import annotations

import math

import numpy as np

from asvtwin.geo import default_scene
from asvtwin.scenarios import TargetSpec
from asvtwin.twin import Twin
from asvtwin.twin.pilots import TargetPilots
from asvtwin.twin.transponders import Transponders
from asvtwin.twin.world import target_params

from .conftest import scenario


def _pilots(role: str) -> tuple[TargetPilots, np.ndarray]:
    p = TargetPilots(default_scene().frame)
    x0 = np.array([0.0, 0.0, 0.0, 2.5, 0.0, 0.0])  # northbound at 2.5 m/s
    spec = TargetSpec.model_validate({
        "name": "T", "mmsi": 257000001, "length_m": 80.0, "beam_m": 14.0,
        "start": {"north_m": 0.0, "east_m": 0.0}, "heading_deg": 0.0, "speed_kn": 5.0,
        "behaviour": {"kind": "colreg", "role": role}})
    p.add(spec, target_params(80.0), x0)
    return p, x0[None]


def test_give_way_vessel_turns_to_starboard_stand_on_holds():
    # own ship crossing from the target's starboard side, on a collision course
    own = np.array([1000.0, 1000.0, -math.pi / 2, 2.5, 0.0, 0.0])
    for role, turns in (("give_way", True), ("auto", True), ("stand_on", False)):
        p, x = _pilots(role)
        tau = p.tau(0.0, x, own)
        assert bool(tau[0, 2] > 0) is turns, role  # positive yaw moment: to starboard
        assert bool(p.giving_way[0]) is turns
    # own ship on the target's port side: "auto" stands on (rule 15)
    p, x = _pilots("auto")
    own_port = np.array([1000.0, -1000.0, math.pi / 2, 2.5, 0.0, 0.0])
    assert p.tau(0.0, x, own_port)[0, 2] == 0.0 and not p.giving_way[0]
    # once the CPA has passed, the give-way vessel resumes
    p, x = _pilots("give_way")
    p.tau(0.0, x, own)
    behind = np.array([-1000.0, 0.0, math.pi, 2.5, 0.0, 0.0])
    p.tau(1.0, x, behind)
    assert not p.giving_way[0]


def test_waypoint_targets_switch_legs_and_loop():
    p = TargetPilots(default_scene().frame)
    spec = TargetSpec.model_validate({
        "name": "W", "mmsi": None, "ais_class": None, "length_m": 20.0, "beam_m": 5.0,
        "start": {"north_m": 0.0, "east_m": 0.0}, "heading_deg": 0.0, "speed_kn": 4.0,
        "behaviour": {"kind": "waypoints", "loop": True,
                      "route": [{"north_m": 500.0, "east_m": 0.0},
                                {"north_m": 500.0, "east_m": 500.0}]}})
    x = np.array([[0.0, 0.0, 0.0, 2.0, 0.0, 0.0]])
    p.add(spec, target_params(20.0), x[0])
    p.tau(0.0, x, np.zeros(6))
    assert p.k[0] == 1
    x[0, :2] = [470.0, 0.0]  # inside the 40 m acceptance circle of the first waypoint
    p.tau(1.0, x, np.zeros(6))
    assert p.k[0] == 2
    x[0, :2] = [500.0, 470.0]  # end of the last leg: back to the first
    p.tau(2.0, x, np.zeros(6))
    assert p.k[0] == 1


def test_ais_log_replayed_into_the_twin(tmp_path):
    scene = default_scene()
    tr = Transponders([257000077], ["A"], ["LOGGED"], [70], [60.0], [10.0], frame=scene.frame,
                      epoch_unix_s=1_732_100_400.0, rng=np.random.default_rng(2))
    x = np.array([[3200.0, -1300.0, 0.0, 2.0, 0.0, 0.0]])
    lines = []
    for k in range(120):
        x[0, 0] += 1.0 * 2.0
        lines += tr.step(float(k), x)
    log = tmp_path / "feed.nmea"
    log.write_text("\n".join(lines) + "\n")
    twin = Twin(scenario(ais={"mode": "file", "path": str(log)}, targets=[],
                         criteria={"goal_reached": False}))
    snaps = []
    twin.on_snapshot = lambda s, b: snaps.append(s)
    twin.run(40.0)
    last = snaps[-1]
    assert last.ais.mmsi.tolist() == [257000077] and last.ais.names == ("LOGGED",)
    assert abs(last.ais.position_m[0, 0] - (3200.0 + 2.0 * 40)) < 25.0  # dead-reckoned
    assert twin.summary().counters["ais_reports"] >= 3
