"""The server against the real twin (the embedded default scenario) and a real recording:
snapshots stream, controls reach the twin, the twin keeps its tick rate with twenty
clients, and a recording replays with pause, speed and seek."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import httpx
import jsonschema
import orjson
import pytest
from starlette.testclient import TestClient

from asvtwin.scenarios import default_scenario
from asvtwin.server import RecordingFeed, ServerThread, create_app
from asvtwin.twin import Clock, Twin
from asvtwin.twin.replay import Recording
from asvtwin.twin.snapshot import decode, json_schema

CLIENTS = Path(__file__).with_name("wsclients.py")


def snapshot(srv: ServerThread) -> dict:
    return decode(httpx.get(srv.url + "api/snapshot", timeout=10).content)


def wait_for(pred, timeout_s: float = 30.0, every_s: float = 0.1):
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        value = pred()
        if value:
            return value
        time.sleep(every_s)
    raise AssertionError("condition not met in time")


def ticks_per_s(twin: Twin, seconds: float) -> float:
    t0, n0 = time.perf_counter(), twin.tick
    time.sleep(seconds)
    return (twin.tick - n0) / (time.perf_counter() - t0)


@pytest.fixture(scope="module")
def live():
    sc = default_scenario()
    twin = Twin(sc, clock=Clock("1", start_time_utc=sc.start_time_utc), record_path=None)
    with ServerThread(twin) as srv:  # the server starts the twin's loop and stops it
        wait_for(lambda: twin.tick > 5, timeout_s=300)  # a cold numba cache compiles first
        yield srv, twin
    twin.close()


def test_live_twin_streams_and_obeys_controls(live):
    srv, twin = live
    s = snapshot(srv)
    assert s["scenario"] == "default" and s["own"]["vessel"] == "cybership2_full_scale"
    jsonschema.validate(s, json_schema())
    httpx.post(srv.url + "api/control/pause", json={}).raise_for_status()
    s1 = wait_for(lambda: (x := snapshot(srv))["clock"]["paused"] and x)
    time.sleep(0.6)
    assert snapshot(srv)["t_s"] == s1["t_s"]  # paused: time stands still
    httpx.post(srv.url + "api/control/step", json={"n_ticks": 4}).raise_for_status()
    wait_for(lambda: twin.tick >= round(s1["t_s"] / twin.dt_s) + 4)
    httpx.post(srv.url + "api/control/resume", json={}).raise_for_status()
    httpx.post(srv.url + "api/control/filter", json={"enabled": False}).raise_for_status()
    wait_for(lambda: snapshot(srv)["filter"]["enabled"] is False)
    httpx.post(srv.url + "api/control/filter", json={"enabled": True}).raise_for_status()
    httpx.post(srv.url + "api/control/wind", json={"speed_m_s": 14.0, "from_deg": 90.0}
               ).raise_for_status()
    n = len(snapshot(srv)["truth"]["ids"])
    r = httpx.post(srv.url + "api/control/inject", json={"spec": {
        "name": "PROBE", "mmsi": 257999999, "start": {"north_m": 600.0, "east_m": 300.0},
        "heading_deg": 180.0, "speed_kn": 6.0, "length_m": 40.0, "beam_m": 9.0}})
    assert r.status_code == 200, r.text
    s2 = wait_for(lambda: (x := snapshot(srv)) and len(x["truth"]["ids"]) == n + 1 and x)
    assert "PROBE" in s2["truth"]["names"]
    # the wind reaches the world's environment (the snapshot's weather shows the forecast)
    wait_for(lambda: twin.world.env.config.wind.speed_m_s == 14.0)
    # the scenario schema's own limits apply to injected vessels (top speed of the hull)
    r = httpx.post(srv.url + "api/control/inject", json={"spec": {
        "name": "TOOFAST", "start": {"north_m": 600.0, "east_m": 300.0},
        "heading_deg": 0.0, "speed_kn": 45.0, "length_m": 10.0, "beam_m": 3.0}})
    assert r.status_code == 409 and "speed_kn" in r.json()["error"]


def test_live_twin_keeps_its_tick_rate_with_twenty_clients(live):
    srv, twin = live
    nominal = 1.0 / twin.dt_s  # speed 1: real time
    base = ticks_per_s(twin, 2.0)
    proc = subprocess.Popen([sys.executable, str(CLIENTS), srv.url.replace("http", "ws") + "ws",
                             "20", "10", "6", "1"], stdout=subprocess.PIPE, text=True)
    wait_for(lambda: len(srv.hub.clients) == 20, timeout_s=60, every_s=0.05)
    loaded = ticks_per_s(twin, 3.0)
    out, _ = proc.communicate(timeout=120)
    res = json.loads(out.splitlines()[0])
    assert res["ok"] == 20 and min(res["messages"]) >= 5, res  # snapshots are 5 Hz in this scenario
    assert base >= 0.9 * nominal, f"twin ran at {base:.1f} of {nominal:.0f} ticks/s alone"
    assert loaded >= 0.9 * base, f"{loaded:.1f} ticks/s with 20 clients vs {base:.1f} alone"


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    sc = default_scenario()
    path = tmp_path_factory.mktemp("rec") / "run.mcap"
    twin = Twin(sc, clock=Clock("max", start_time_utc=sc.start_time_utc), record_path=path)
    twin.run(6.0)
    return Recording(path)


class FakeClock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_recording_replays_with_pause_speed_and_seek(recording):
    clock = FakeClock()
    feed = RecordingFeed(recording, clock=clock)
    assert feed.duration_s == pytest.approx(recording.duration_s)
    assert feed.duration_s > 5.0
    first = feed.frame()
    assert first.data == recording.message_at(0.0)
    clock.t += 2.0
    assert feed.frame().data == recording.message_at(2.0)
    assert feed.frame().t_s == pytest.approx(2.0, abs=0.21)  # snapshots every 0.2 s
    feed.control("speed", {"factor": 2.0})
    clock.t += 1.0
    assert feed.frame().t_s == pytest.approx(4.0, abs=0.21)
    feed.control("pause", {})
    clock.t += 5.0
    assert feed.frame().t_s == pytest.approx(4.0, abs=0.21)
    feed.control("seek", {"t_s": 1.0})  # back in time: the stream reopens
    assert feed.frame().data == recording.message_at(1.0)
    feed.control("resume", {})
    clock.t += 0.5
    assert feed.frame().data == recording.message_at(2.0)
    with pytest.raises(ValueError, match="seek time"):
        feed.control("seek", {"t_s": 1e6})


def test_recording_served_over_http(recording):
    app = create_app(recording)  # a Recording is served through RecordingFeed
    with TestClient(app, base_url="http://127.0.0.1", client=("127.0.0.1", 5000)) as c:
        info = c.get("/api/info").json()
        assert info["kind"] == "replay" and info["duration_s"] > 5.0
        assert c.post("/api/control/seek", json={"t_s": 3.0}).json()["t_s"] == pytest.approx(3.0, abs=0.1)
        r = c.post("/api/control/inject", json={"spec": {
            "name": "X", "start": {"north_m": 0, "east_m": 0}, "heading_deg": 0, "speed_kn": 1}})
        assert r.status_code == 409 and "replay" in r.json()["error"]
        s = orjson.loads(c.get("/api/snapshot").content)
        assert s["schema"] == "asvtwin.snapshot/1"
