"""AIS from outside the simulation: a live feed (``ais.mode: live``, TCP and UDP on
127.0.0.1, served by the test) and a target replayed from an AIS log by MMSI
(``behaviour: ais_replay``, a log the test writes)."""

from __future__ import annotations

import math
import socket
import threading
import time

import numpy as np
import pytest

from asvtwin.errors import ScenarioError
from asvtwin.geo import default_scene
from asvtwin.sources.ais import AisReport, encode_report, tag_block
from asvtwin.twin import Clock, Twin
from asvtwin.twin.transponders import Transponders
from asvtwin.twin.verify import verify_recording

from .conftest import scenario

FAST = {"sim_hz": 5.0, "tracker_hz": 2.0, "observer_hz": 5.0, "controller_hz": 5.0,
        "filter_hz": 1.0, "snapshot_hz": 1.0}
MMSI = 257000055


def _line(t_unix: float, north_m: float, east_m: float) -> str:
    """A tagged type 1 report of vessel MMSI at (north, east), 5 m/s to the north."""
    scene = default_scene()
    lat, lon = scene.frame.to_wgs84(north_m, east_m)
    rep = AisReport(mmsi=MMSI, t_unix_s=float(int(t_unix)), msg_type=1, north_m=north_m,
                    east_m=east_m, lat_deg=float(lat), lon_deg=float(lon), sog_m_s=5.0,
                    cog_rad=0.0, heading_rad=0.0, rot_rad_s=0.0, nav_status=0)
    return tag_block(station="2579999", t_unix_s=t_unix) + encode_report(rep)


def _live_scenario(url: str, **changes):
    return scenario(rates=FAST, targets=[], ais={"mode": "live", "url": url},
                    sensors__lidar_rate_hz=1.0, **changes)


def _run_live(twin: Twin, seconds: float) -> list:
    snaps = []
    twin.on_snapshot = lambda s, b: snaps.append(s)
    twin.run(seconds)
    return snaps


def test_live_tcp_feed_reaches_the_picture_and_the_recording_reruns(tmp_path):
    srv = socket.create_server(("127.0.0.1", 0))
    port = srv.getsockname()[1]
    stop = threading.Event()

    def serve() -> None:
        conn, _ = srv.accept()
        t_start = int(time.time())
        with conn:
            k = 0
            while not stop.is_set():
                now = int(time.time())  # the vessel's position at the tag block's second
                conn.sendall((_line(now, 3300.0 + 5.0 * (now - t_start), -1600.0)
                              + "\r\n").encode())
                if k == 2:
                    conn.sendall(b"!AIVDM,1,1,,A,garbage,0*00\r\n")
                k += 1
                time.sleep(0.5)

    th = threading.Thread(target=serve, daemon=True)
    th.start()
    path = tmp_path / "live.mcap"
    twin = Twin(_live_scenario(f"tcp://127.0.0.1:{port}"), clock=Clock(1.0), record_path=path)
    w0 = time.time()
    try:
        snaps = _run_live(twin, 5.0)
    finally:
        stop.set()
        srv.close()
    wall_s = time.time() - w0
    s = twin.summary()
    assert s.counters["ais_reports"] >= 4, s.counters
    assert s.counters["ais_lines"] >= 5
    assert sum(v for k, v in s.counters.items() if k.startswith("ais_error_")) >= 1  # garbage
    last = snaps[-1]
    assert MMSI in last.ais.mmsi.tolist()
    i = last.ais.mmsi.tolist().index(MMSI)
    # dead-reckoned at 5 m/s from where the feed put it (on a loaded machine the run takes
    # longer than its 5 s: the bound is the wall time it took)
    assert 3300.0 <= last.ais.position_m[i, 0] < 3300.0 + 5.0 * (wall_s + 5.0)
    assert abs(last.ais.position_m[i, 1] - (-1600.0)) < 1.0
    assert abs(twin.epoch_unix_s - time.time()) < 60.0  # live: the epoch is now
    assert not twin.live.alive  # closed with the run
    # the live lines were recorded as raw input: a re-run reproduces the snapshots
    res = verify_recording(path)
    assert res["identical"], res


def test_live_udp_feed_on_localhost():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    twin = Twin(_live_scenario(f"udp://127.0.0.1:{port}"), clock=Clock(1.0))
    deadline = time.monotonic() + 20.0
    while not twin.live.connected and time.monotonic() < deadline:
        time.sleep(0.05)
    assert twin.live.connected
    stop = threading.Event()

    def send() -> None:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
            k, t_start = 0, int(time.time())
            while not stop.is_set():
                now = int(time.time())
                tx.sendto(_line(now, 3300.0 + 5.0 * (now - t_start), -1600.0).encode(),
                          ("127.0.0.1", port))
                k += 1
                time.sleep(0.4)

    th = threading.Thread(target=send, daemon=True)
    th.start()
    try:
        snaps = _run_live(twin, 4.0)
    finally:
        stop.set()
    assert twin.summary().counters["ais_reports"] >= 3
    assert MMSI in snaps[-1].ais.mmsi.tolist()


def test_live_feed_needs_real_time_and_a_valid_url():
    with pytest.raises(ScenarioError, match="real time.*speed 1"):
        Twin(_live_scenario("tcp://127.0.0.1:9"), clock=Clock("max"))
    with pytest.raises(ValueError, match="tcp://host:port"):
        _live_scenario("http://127.0.0.1:80")


# ---------------------------------------------------------------- ais_replay targets
def _write_log(tmp_path, scene):
    """300 s of two vessels' transponders (exact GNSS) as a tagged NMEA log: 257000077
    heads east at 3 m/s, 257000078 north at 2 m/s. Returns the path and the truth."""
    tr = Transponders([257000077, 257000078], ["A", "A"], ["LOGGED", "OTHER"], [70, 70],
                      [60.0, 40.0], [10.0, 8.0], frame=scene.frame,
                      epoch_unix_s=1_732_100_400.0, rng=np.random.default_rng(2),
                      position_std_m=0.0, velocity_std_m_s=0.0)
    x = np.array([[3600.0, -1900.0, math.pi / 2, 3.0, 0.0, 0.0],
                  [2600.0, -900.0, 0.0, 2.0, 0.0, 0.0]])
    lines = []
    for k in range(300):
        x[0, 1] = -1900.0 + 3.0 * k
        x[1, 0] = 2600.0 + 2.0 * k
        lines += tr.step(float(k), x)
    log = tmp_path / "harbour.nmea"
    log.write_text("\n".join(lines) + "\n")
    return log


def _replay_target(log, mmsi=257000077, name="LOGGED"):
    return {"name": name, "mmsi": mmsi, "ais_class": "A", "vessel_type": "cargo",
            "length_m": 60.0, "beam_m": 10.0,
            "behaviour": {"kind": "ais_replay", "file": str(log), "mmsi": mmsi}}


def test_a_target_replayed_from_an_ais_log_follows_the_log(tmp_path):
    scene = default_scene()
    log = _write_log(tmp_path, scene)
    twin = Twin(scenario(rates=FAST, targets=[_replay_target(log)],
                         sensors__lidar_rate_hz=1.0))
    t0_log = None
    from asvtwin.twin.ais_track import AisTrack, read_ais_log

    reports = read_ais_log(log, scene)
    track = AisTrack(reports, 257000077)
    t0_log = track.t_s[0]  # the vessel's first report, after the log's first line
    assert 0.0 <= t0_log < 10.0 and len(track) >= 25
    samples = []
    for _ in range(int(120.0 / twin.dt_s)):
        twin.step()
        samples.append((twin.t_s, twin.world.target_states[0].copy()))
    # the world's vessel is where the log says: the truth that made the log, shifted to
    # the log's time origin (its first line), within AIS's position resolution
    first_line_unix = float(np.min(reports.t_unix_s))
    for t, x in samples[::25]:
        if t < t0_log:
            continue
        k_true = t + (first_line_unix - 1_732_100_400.0)
        assert x[0] == pytest.approx(3600.0, abs=1.0)
        assert x[1] == pytest.approx(-1900.0 + 3.0 * k_true, abs=1.5)
        assert x[2] == pytest.approx(math.pi / 2, abs=0.01)
        assert x[3] == pytest.approx(3.0, abs=0.06)  # SOG at 0.1 kn resolution
    # its transponder speaks for it: the twin's AIS picture carries it by its MMSI
    assert 257000077 in twin.latest().ais.mmsi.tolist()
    assert twin.world.table.mmsi == [257000077]


def test_ais_replay_errors_name_the_file_and_the_mmsi(tmp_path):
    scene = default_scene()
    log = _write_log(tmp_path, scene)
    with pytest.raises(ScenarioError, match=r"MMSI 257000099 has no position report.*"
                                            r"257000077, 257000078"):
        Twin(scenario(rates=FAST, targets=[_replay_target(log, mmsi=257000099)]))
    untagged = tmp_path / "untagged.nmea"
    untagged.write_text("\n".join(ln.split("\\")[-1] for ln in log.read_text().splitlines()))
    with pytest.raises(ScenarioError, match="no valid position report with a tag-block time"):
        Twin(scenario(rates=FAST, targets=[_replay_target(untagged)]))
    with pytest.raises(ScenarioError, match="cannot read the AIS log"):
        Twin(scenario(rates=FAST, targets=[_replay_target(tmp_path / "missing.nmea")]))
