"""POST /api/whatif on the viewer's server (in-process ASGI client, synthetic feed)."""

from __future__ import annotations

import pytest
from starlette.testclient import TestClient

from asvtwin.server import SyntheticFeed, create_app
from asvtwin.twin.snapshot import decode
from asvtwin.whatif import fork


@pytest.fixture(scope="module")
def client():
    feed = SyntheticFeed(4, seed=2)
    feed.tick()
    feed.start = lambda: None
    feed.stop = lambda: None
    app = create_app(feed)
    with TestClient(app, base_url="http://127.0.0.1", client=("127.0.0.1", 50000)) as c:
        c.feed = feed
        yield c


def test_whatif_answers_about_the_served_snapshot(client):
    body = {"alternatives": ["route+filter_off", "starboard:20+filter_off"], "rollouts": 3,
            "horizon_s": 10.0, "seed": 4, "ghosts": 2}
    r = client.post("/api/whatif", json=body)
    assert r.status_code == 200, r.text
    ans = r.json()
    snap = decode(client.feed.frame().data)
    assert ans["t_s"] == pytest.approx(snap["t_s"])
    assert [a["label"] for a in ans["alternatives"]] == body["alternatives"]
    assert all(a["rollouts"] == 3 for a in ans["alternatives"])
    assert len(ans["ghosts"]) == 2 * 2
    g = ans["ghosts"][0]["positions_m"]
    own = fork(client.feed.frame().data).own_state
    assert g[0] == pytest.approx(own[:2].round(1).tolist(), abs=0.06)
    assert ans["recommendation"]["label"] in body["alternatives"]
    # the same question, the same answer
    again = client.post("/api/whatif", json=body).json()
    assert again["alternatives"] == ans["alternatives"]


@pytest.mark.parametrize(("body", "status", "words"), [
    ({"alternatives": ["hard_a_port"]}, 422, "unknown name 'hard_a_port'"),
    ({"rollouts": 0}, 422, "rollouts"),
    ({"rollout": 5}, 422, "rollout: Extra inputs are not permitted"),
])
def test_bad_questions_are_refused_with_a_reason(client, body, status, words):
    r = client.post("/api/whatif", json=body)
    assert r.status_code == status
    assert words in r.text
