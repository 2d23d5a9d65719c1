"""The server's REST and WebSocket API against the synthetic feed (in-process ASGI client):
controls act, bad requests are refused with a 4xx and a reason and counted, non-local
requests need the token, the scene document matches an independent projection, and the
snapshot on the wire is the contract's encoding."""

from __future__ import annotations

import math

import jsonschema
import msgpack
import numpy as np
import orjson
import pymap3d
import pytest
import shapely
from shapely.geometry import Polygon, shape
from starlette.testclient import TestClient

from asvtwin.geo import default_scene
from asvtwin.server import SyntheticFeed, create_app
from asvtwin.twin.snapshot import decode, encode, json_schema

LOCAL = ("127.0.0.1", 50000)
#: A peer that is not this machine, for the access checks: Starlette's own default client
#: name, not an address (TestClient calls the app in-process; nothing is resolved or sent)
REMOTE = ("testclient", 4000)


@pytest.fixture(scope="module")
def feed():
    f = SyntheticFeed(8, seed=3)
    f.tick()  # one snapshot without running the loop (tests drive ticks themselves)
    return f


@pytest.fixture
def client(feed):
    app = create_app(feed)
    feed.start = lambda: None  # keep the loop off: ticks are driven by the tests
    feed.stop = lambda: None
    with TestClient(app, base_url="http://127.0.0.1", client=LOCAL) as c:
        c.hub = app.hub
        yield c


def refused(c) -> int:
    return c.get("/api/stats").json()["counters"].get("refused", 0)


def test_controls_act_on_the_feed(client, feed):
    assert client.post("/api/control/pause", json={}).json() == {"ok": True, "action": "pause"}
    assert feed.paused
    client.post("/api/control/resume", json={})
    assert not feed.paused
    client.post("/api/control/speed", json={"factor": 2.5})
    assert feed.speed == 2.5
    client.post("/api/control/speed", json={"factor": "max"})
    assert feed.speed == "max"
    client.post("/api/control/filter", json={"enabled": False})
    assert feed.filter_enabled is False
    client.post("/api/control/filter", json={"enabled": True})
    client.post("/api/control/step", json={"n_ticks": 3})
    assert feed.paused and feed._pending_steps == 3
    route = [[100.0, 200.0], [900.0, -300.0]]
    client.post("/api/control/route", json={"waypoints_ned": route})
    np.testing.assert_array_equal(feed.route, route)
    n = len(feed.tgt_pos)
    r = client.post("/api/control/inject", json={"spec": {
        "name": "PROBE", "mmsi": 257999999, "start": {"lat": 63.45, "lon": 10.39},
        "heading_deg": 90.0, "speed_kn": 10.0}})
    assert r.status_code == 200, r.text
    assert len(feed.tgt_pos) == n + 1
    # lat/lon start converted to the scene frame (independent check with pymap3d)
    north, east, _ = pymap3d.geodetic2ned(63.45, 10.39, 0.0, 63.446, 10.39, 0.0)
    np.testing.assert_allclose(feed.tgt_pos[-1], [north, east], atol=1e-3)
    np.testing.assert_allclose(feed.tgt_vel[-1], [0.0, 10 * 1852 / 3600], atol=1e-9)
    client.post("/api/control/wind", json={"speed_m_s": 12.0, "from_deg": 270.0})
    assert feed.wind == (12.0, math.radians(270.0))
    stats = client.get("/api/stats").json()["counters"]
    assert stats["control_pause"] == 1 and stats["control_inject"] == 1
    assert stats.get("refused", 0) == 0


@pytest.mark.parametrize(("path", "kwargs", "status", "reason"), [
    ("/api/control/speed", {"content": b"{bad", "headers": {"content-type": "application/json"}},
     400, "malformed JSON"),
    ("/api/control/speed", {"json": [1, 2]}, 400, "JSON object"),
    ("/api/control/speed", {"json": {"factor": -1}}, 422, "factor"),
    ("/api/control/speed", {"json": {"factor": 1e9}}, 422, "factor"),
    ("/api/control/speed", {"json": {"factor": 1, "extra": 2}}, 422, "extra"),
    ("/api/control/wind", {"json": {"speed_m_s": 70, "from_deg": 10}}, 422, "speed_m_s"),
    ("/api/control/wind", {"content": b'{"speed_m_s": NaN, "from_deg": 1}',
                           "headers": {"content-type": "application/json"}}, 400, "malformed"),
    ("/api/control/route", {"json": {"waypoints_ned": []}}, 422, "waypoints_ned"),
    ("/api/control/route", {"json": {"waypoints_ned": [[0, 2e6]]}}, 422, "outside"),
    ("/api/control/step", {"json": {"n_ticks": 0}}, 422, "n_ticks"),
    ("/api/control/inject", {"json": {"spec": {"name": "X", "start": {"lat": 95, "lon": 0},
                                               "heading_deg": 0, "speed_kn": 1}}}, 422, "lat"),
    ("/api/control/teleport", {"json": {}}, 404, "unknown action"),
    ("/api/control/seek", {"json": {"t_s": 3}}, 409, "not available on a synthetic feed"),
    ("/api/control/pause", {"content": b"{}", "headers": {"content-type": "text/plain"}},
     415, "application/json"),
    ("/api/control/route", {"content": b"[" + b"[1,2]," * 20000 + b"[1,2]]",
                            "headers": {"content-type": "application/json"}}, 413, "exceeds"),
])
def test_bad_requests_are_refused_with_a_reason_and_counted(client, path, kwargs, status, reason):
    before = refused(client)
    r = client.post(path, **kwargs)
    assert r.status_code == status, r.text
    assert reason in r.json()["error"]
    assert refused(client) == before + 1


def test_chunked_oversized_body_is_refused(client):
    def chunks():
        for _ in range(100):
            yield b" " * 1024  # no content-length: the guard counts bytes as they arrive
    before = refused(client)
    r = client.post("/api/control/pause", content=chunks(),
                    headers={"content-type": "application/json"})
    assert r.status_code == 413 and "exceeds" in r.json()["error"]
    assert refused(client) == before + 1


def test_non_local_requests_need_the_token(feed):
    app = create_app(feed)  # no token: local only
    with TestClient(app, base_url="http://127.0.0.1", client=REMOTE) as c:
        r = c.get("/api/info")
        assert r.status_code == 403 and "local-only" in r.json()["error"]
        assert c.post("/api/control/pause", json={}).status_code == 403
    app = create_app(feed, token="s3cret-token")
    with TestClient(app, base_url="http://127.0.0.1", client=REMOTE) as c:
        assert c.get("/api/info").status_code == 403
        assert c.get("/api/info", headers={"authorization": "Bearer wrong"}).status_code == 403
        assert c.get("/api/info", headers={"authorization": "Bearer s3cret-token"}).status_code == 200
        assert c.get("/api/info?token=s3cret-token").status_code == 200
        assert c.get("/api/info", headers={"x-asvtwin-token": "s3cret-token"}).status_code == 200
        assert app.hub.counters["refused_403"] == 2


def test_dns_rebinding_and_cross_site_websocket_are_refused(client):
    r = client.get("/api/info", headers={"host": "attacker.example:8765"})
    assert r.status_code == 403 and "DNS rebinding" in r.json()["error"]
    with (pytest.raises(Exception),  # noqa: B017 - starlette raises WebSocketDisconnect(1008)
          client.websocket_connect("ws://127.0.0.1/ws", headers={"origin": "http://attacker.example"})):
        pass
    assert client.hub.counters["refused_403"] >= 2


def test_no_endpoint_serves_a_path_outside_the_viewer(client):
    for path in ("/static/../../pyproject.toml", "/static/%2e%2e/%2e%2e/pyproject.toml",
                 "/static//etc/passwd", "/api/scene?path=/etc/passwd"):
        r = client.get(path)
        assert b"[project]" not in r.content and b"root:" not in r.content
    assert client.get("/static/js/main.js").status_code == 200
    assert client.get("/").headers["content-type"].startswith("text/html")


def test_snapshot_on_the_wire_is_the_contract_encoding(client, feed):
    data = client.get("/api/snapshot").content
    assert data == encode(feed.latest())
    jsonschema.validate(decode(data), json_schema())


def test_websocket_json_and_msgpack_carry_the_same_snapshot(client, feed):
    with client.websocket_connect("ws://127.0.0.1/ws?rate_hz=20") as ws:
        hello = orjson.loads(ws.receive_text())
        assert hello["type"] == "hello" and hello["schema"] == "asvtwin.snapshot/1"
        js = ws.receive_bytes()
    with client.websocket_connect("ws://127.0.0.1/ws?rate_hz=20&format=msgpack") as ws:
        ws.receive_text()
        mp = msgpack.unpackb(ws.receive_bytes())
    assert mp == orjson.loads(js) == decode(encode(feed.latest()))
    assert len(mp["tracks"]["ids"]) == len(feed.tgt_pos)


def test_websocket_bad_options_are_refused(client):
    for q in ("rate_hz=1000", "rate_hz=abc", "format=xml", "colour=red"):
        with (pytest.raises(Exception),  # noqa: B017 - closed with 1008 before accept
              client.websocket_connect(f"ws://127.0.0.1/ws?{q}")):
            pass
    with client.websocket_connect("ws://127.0.0.1/ws?rate_hz=5") as ws:
        ws.receive_text()
        ws.send_text('{"rate_hz": -4}')
        msgs = [ws.receive() for _ in range(2)]
        errors = [orjson.loads(m["text"]) for m in msgs if m.get("text")]
        assert any(e.get("type") == "error" and "rate_hz" in e["error"] for e in errors)


def test_scene_document_matches_an_independent_projection(client):
    doc = client.get("/api/scene").json()
    scene = default_scene()
    land_ll = shapely.union_all([shape(f["geometry"]) for f in doc["land"]["features"]])
    assert land_ll.symmetric_difference(scene.land_lonlat).area < 1e-12
    # land_ned: the same polygons projected by pymap3d (not asvtwin.geo) agree in area
    o = doc["origin"]
    polys = [Polygon(r[0], r[1:]) for r in doc["land_ned"]]
    ned_area = sum(p.area for p in polys)

    def proj(ring):
        ll = np.asarray(ring)
        n, e, _ = pymap3d.geodetic2ned(ll[:, 1], ll[:, 0], 0.0, o["lat_deg"], o["lon_deg"], 0.0)
        return np.column_stack([n, e])
    ref = sum(Polygon(proj(p.exterior.coords), [proj(i.coords) for i in p.interiors]).area
              for p in scene.land_lonlat.geoms)
    assert ned_area == pytest.approx(ref, rel=2e-3)
    # relief: zero on water, h = 400 tanh(d / 1500) inland, recomputed from the coast distance
    rl = doc["relief"]
    h = np.asarray(rl["heights_m"]).reshape(rl["rows"], rl["cols"])
    nn = np.linspace(*rl["north_m"], rl["rows"])
    ee = np.linspace(*rl["east_m"], rl["cols"])
    rng = np.random.default_rng(0)
    i, j = rng.integers(0, rl["rows"], 300), rng.integers(0, rl["cols"], 300)
    pts = np.column_stack([nn[i], ee[j]])
    inland = np.maximum(-scene.land.signed_distance(pts), 0.0)
    np.testing.assert_allclose(h[i, j], 400.0 * np.tanh(inland / 1500.0), atol=0.051)
    on_land = scene.land.contains(pts)
    assert (h[i, j][~on_land] == 0).all() and (h[i, j][on_land] >= 0).all()
    assert "no elevation model" in rl["note"]


def test_a_server_bound_beyond_loopback_gets_a_token(feed):
    from asvtwin.server.app import _make_server

    local = _make_server(feed, "127.0.0.1", 0, None, "error")
    assert local.asvtwin_token is None
    wide = _make_server(feed, "0.0.0.0", 0, None, "error")  # built, never started here
    assert isinstance(wide.asvtwin_token, str) and len(wide.asvtwin_token) >= 20
    assert _make_server(feed, "0.0.0.0", 0, "given", "error").asvtwin_token == "given"
