"""A real recording of the twin (default scenario, 6 s) replayed by the server: pause,
speed, step and seek on a wall clock, and served over HTTP."""

from __future__ import annotations

import orjson
import pytest
from starlette.testclient import TestClient

from asvtwin.scenarios import default_scenario
from asvtwin.server import RecordingFeed, create_app
from asvtwin.twin import Clock, Twin
from asvtwin.twin.replay import Recording


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
