"""The server against the real twin (the embedded default scenario): snapshots stream,
controls reach the twin, and the twin keeps its tick rate with twenty clients. (The replay
of a real recording is in test_replay_feed.py: a second twin solving in another thread of
this process at the same time crashed inside acados.)"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import httpx
import jsonschema
import pytest

from asvtwin.scenarios import default_scenario
from asvtwin.server import ServerThread
from asvtwin.twin import Clock, Twin
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


def stands_still(twin: Twin, dwell_s: float = 0.5) -> bool:
    """True when the twin did not tick during ``dwell_s`` (it is paused)."""
    k = twin.tick
    time.sleep(dwell_s)
    return twin.tick == k


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
    try:
        wait_for(lambda: stands_still(twin))  # paused: the twin's time stands still
        t1 = snapshot(srv)["t_s"]
        time.sleep(0.5)
        assert snapshot(srv)["t_s"] == t1
        k = twin.tick
        httpx.post(srv.url + "api/control/step", json={"n_ticks": 4}).raise_for_status()
        wait_for(lambda: twin.tick > k)  # the step reached the twin's clock ...
        wait_for(lambda: stands_still(twin))  # ... and it is paused again after it
    finally:
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


def _ws_snapshot(ws, timeout_s: float = 30.0) -> dict:
    """The next snapshot (binary message) on ``ws``, skipping text messages."""
    end = time.monotonic() + timeout_s
    while True:
        msg = ws.recv(timeout=max(0.1, end - time.monotonic()))
        if isinstance(msg, bytes):
            return decode(msg)


def test_a_client_connecting_to_a_paused_twin_gets_its_latest_snapshot(live):
    """Paused, the twin ticks no more; a viewer that connects then still gets the twin's
    latest snapshot at once (with the paused clock), and a control applied while paused
    reaches the connected clients although seq and time stand still."""
    from websockets.sync.client import connect

    srv, twin = live
    httpx.post(srv.url + "api/control/pause", json={}).raise_for_status()
    try:
        wait_for(lambda: stands_still(twin))
        tick = twin.tick
        url = srv.url.replace("http", "ws") + "ws?rate_hz=10"
        with connect(url, max_size=None, open_timeout=30) as ws:
            s = _ws_snapshot(ws)
            latest = twin.latest()
            assert s["seq"] == latest.seq and s["t_s"] == pytest.approx(latest.t_s)
            assert s["clock"]["paused"] is True
            assert twin.tick == tick  # nothing ticked to make that snapshot
            enabled = s["filter"]["enabled"]
            httpx.post(srv.url + "api/control/filter", json={"enabled": not enabled}
                       ).raise_for_status()
            s2 = wait_for(lambda: (x := _ws_snapshot(ws)) and x["filter"]["enabled"] is not enabled
                          and x)
            assert s2["seq"] == s["seq"] and s2["t_s"] == s["t_s"]  # still paused
            httpx.post(srv.url + "api/control/filter", json={"enabled": enabled}
                       ).raise_for_status()
            wait_for(lambda: _ws_snapshot(ws)["filter"]["enabled"] is enabled)
        assert twin.tick == tick
    finally:
        httpx.post(srv.url + "api/control/resume", json={}).raise_for_status()


def test_live_twin_keeps_its_tick_rate_with_twenty_clients(live):
    srv, twin = live
    nominal = 1.0 / twin.dt_s  # speed 1: real time
    # settled first: re-enabling the filter (previous test) rebuilds its solver
    base = wait_for(lambda: (r := ticks_per_s(twin, 2.0)) >= 0.9 * nominal and r, timeout_s=180)
    proc = subprocess.Popen([sys.executable, str(CLIENTS), srv.url.replace("http", "ws") + "ws",
                             "20", "10", "6", "1"], stdout=subprocess.PIPE, text=True)
    wait_for(lambda: len(srv.hub.clients) == 20, timeout_s=60, every_s=0.05)
    loaded = ticks_per_s(twin, 3.0)
    out, _ = proc.communicate(timeout=120)
    res = json.loads(out.splitlines()[0])
    assert res["ok"] == 20 and min(res["messages"]) >= 5, res  # snapshots are 5 Hz in this scenario
    assert base >= 0.9 * nominal, f"twin ran at {base:.1f} of {nominal:.0f} ticks/s alone"
    assert loaded >= 0.9 * base, f"{loaded:.1f} ticks/s with 20 clients vs {base:.1f} alone"
