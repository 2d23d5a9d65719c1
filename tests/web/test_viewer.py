"""The viewer in a real browser: Debian's Chromium driven by Playwright (never a downloaded
browser), against the server on 127.0.0.1 with the synthetic feed. Checks that the chart,
the 3-D view, targets, cones, the filter's plan and the table are drawn (the page's
counters and pixels of its screenshots), that the controls act on the feed, that the
page's NED <-> WGS84 port matches the Python one, and that nothing is requested from any
address but 127.0.0.1. Screenshots go to ``out/test-artifacts/`` as ``synthetic-*.png``
(the documentation's pictures are the live twin's, test_live_twin.py)."""

from __future__ import annotations

import io
import math
import os
import time
from pathlib import Path
from urllib.parse import urlsplit

import numpy as np
import pytest

from asvtwin.server import RecordingFeed, ServerThread, SyntheticFeed
from asvtwin.twin.recorder import Recorder
from asvtwin.twin.replay import Recording
from asvtwin.twin.snapshot import encode
from tests.web.chromium import CHROMIUM, launch

playwright = pytest.importorskip("playwright.sync_api")
Image = pytest.importorskip("PIL.Image")

pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="Debian's chromium is not installed "
                                "(.ci/run installs it with apt)")
ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = ROOT / "out" / "test-artifacts"
DOC_IMG = ROOT / "docs" / "img"
N_TARGETS = 24
TIMEOUT_MS = 90_000  # software WebGL on a busy 2-core machine is slow to first paint
WAIT_MS = 60_000
# Playwright's actionability checks wait for animation frames, which software WebGL on a
# loaded machine delivers slowly: the controls are used with force=True (the page's own
# state then shows whether the click took effect)
F = {"force": True}


def choose(page, selector: str, value: str) -> None:
    """Set a <select> or <input> as a user would and fire its change event (Playwright's
    select_option waits on the page's frames, which SwiftShader delivers slowly)."""
    page.evaluate("""([sel, v]) => { const e = document.querySelector(sel);
        if (e.type === 'checkbox') e.checked = v === 'on'; else e.value = v;
        e.dispatchEvent(new Event('input', {bubbles: true}));
        e.dispatchEvent(new Event('change', {bubbles: true})); }""", [selector, value])


def save(png: bytes, name: str) -> np.ndarray:
    """Keep a screenshot as a test artefact; the live twin's (``viewer*.png``, from
    test_live_twin.py) also refresh docs/img/ with ``ASVTWIN_DOC_IMAGES=1``."""
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    (ARTIFACTS / name).write_bytes(png)
    if os.environ.get("ASVTWIN_DOC_IMAGES") and name.startswith("viewer"):
        (DOC_IMG / name).write_bytes(png)
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)


def count_colour(img: np.ndarray, rgb: tuple[int, int, int], tol: int = 30) -> int:
    return int((np.abs(img - np.array(rgb)).max(axis=2) <= tol).sum())


def local_only(url: str) -> bool:
    parts = urlsplit(url)
    return parts.scheme in ("data", "blob", "about") or parts.hostname == "127.0.0.1"


@pytest.fixture(scope="module")
def browser():
    with playwright.sync_playwright() as pw:
        b, _ = launch(pw)  # llvmpipe's software WebGL when Mesa has it, else SwiftShader
        yield b
        b.close()


def open_viewer(browser, url: str):
    """A page on ``url`` that aborts and records every request not to 127.0.0.1."""
    page = browser.new_page(viewport={"width": 1500, "height": 950})
    foreign: list[str] = []

    def guard(route):
        if local_only(route.request.url):
            route.continue_()
        else:
            foreign.append(route.request.url)
            route.abort()
    page.route("**/*", guard)
    page.on("websocket", lambda ws: None if local_only(ws.url) else foreign.append(ws.url))
    page.on("request", lambda r: None if local_only(r.url) else foreign.append(r.url))
    page.goto(url)
    page.wait_for_function("window.asvtwinViewer && asvtwinViewer.ready && "
                           "asvtwinViewer.chart.updates > 0 && asvtwinViewer.table.updates > 0",
                           timeout=TIMEOUT_MS)
    return page, foreign


def viewer(page) -> dict:
    return page.evaluate("({chart: asvtwinViewer.chart, view3d: asvtwinViewer.view3d, "
                         "table: asvtwinViewer.table, errors: asvtwinViewer.errors, "
                         "latest: asvtwinViewer.latest, targets: asvtwinViewer.targets})")


@pytest.fixture(scope="module")
def live(browser):
    feed = SyntheticFeed(N_TARGETS, seed=2, tick_hz=10.0)
    # a vessel head-on 700 m ahead: the plan turns red and the table raises an alarm
    psi = math.atan2(300.0, 600.0)
    feed.control("inject", {"spec": {"name": "HEAD-ON", "mmsi": 257888888, "length_m": 60.0,
                                     "beam_m": 12.0, "start": {"north_m": 700 * math.cos(psi),
                                                               "east_m": 700 * math.sin(psi)},
                                     "heading_deg": (math.degrees(psi) + 180.0) % 360.0,
                                     "speed_kn": 10.0}})
    with ServerThread(feed) as srv:
        time.sleep(0.3)
        feed.control("pause", {})  # a still picture for the drawing checks
        page, foreign = open_viewer(browser, srv.url)
        yield srv, feed, page, foreign
        page.close()
        assert not foreign, f"requests to other addresses than 127.0.0.1: {foreign}"


def test_chart_3d_table_and_status_are_drawn(live):
    _srv, feed, page, foreign = live
    page.wait_for_timeout(1500)  # MapLibre's worker finishing the first tiles
    v = viewer(page)
    n = len(feed.tgt_pos)
    assert v["errors"] == []
    assert v["chart"]["targets"] == n and v["chart"]["cones"] == n
    assert v["chart"]["planStages"] == 20 and v["chart"]["criticalStages"] >= 1
    assert v["chart"]["lidarPoints"] > 0
    assert v["view3d"]["frames"] >= 1 and v["view3d"]["hulls"] == n + 1
    assert v["view3d"]["terrainVertices"] > 10_000
    assert v["table"]["rows"] == n and v["table"]["dangerous"] >= 1
    save(page.screenshot(), "synthetic-viewer.png")  # first: element shots scroll the page
    chart = save(page.locator("#chart-pane").screenshot(), "synthetic-viewer-chart.png")
    assert count_colour(chart, (26, 154, 42)) > 30  # the plan, green
    assert count_colour(chart, (224, 20, 30)) > 30  # its critical stages and the alarm, red
    assert count_colour(chart, (216, 200, 154), tol=6) > 5000  # land
    view3d = save(page.locator("#view3d-pane").screenshot(), "synthetic-viewer-3d.png")
    assert count_colour(view3d, (224, 106, 16), tol=60) > 20  # the own ship's hull from astern
    assert view3d.std() > 10  # terrain, water and sky, not a blank canvas
    save(page.locator("#table-pane").screenshot(), "synthetic-viewer-table.png")
    status = page.locator("#status").inner_text()
    for level in ("L0", "L1", "L2", "L3", "L4", "L5"):
        assert level in status
    assert "synthetic" in status and "interventions" in status
    assert not foreign


def test_targets_are_drawn_where_maplibre_projects_them(live):
    """The chart's WebGL layer (its own matrix, shaders and symbol atlas) puts each target's
    symbol at the pixel MapLibre's own projection gives for the target's position, north-up
    and head-up (the chart turned), and names only the nearest and the dangerous targets."""
    _srv, _feed, page, foreign = live
    js = """() => { const V = asvtwinViewer, m = V.map, fr = V.frame, s = V.latest;
        const c = m.getCanvas();
        const pts = s.tracks.ids.map((id, i) => {
            const q = m.project(fr.toLonLat(s.tracks.mean[i][0], s.tracks.mean[i][1]));
            return [q.x, q.y]; });
        return {pts, w: c.clientWidth, h: c.clientHeight, bearing: m.getBearing(),
                labels: V.chart.labels, zoom: m.getZoom()}; }"""
    try:
        for orient in ("north", "head"):
            choose(page, "#sel-orient", orient)
            page.wait_for_function(f"asvtwinViewer.chart.bearing {'==' if orient == 'north' else '!='} 0",
                                   timeout=WAIT_MS)
            page.wait_for_timeout(500)
            st = page.evaluate(js)
            img = page.locator("#chart").screenshot()
            img = np.asarray(Image.open(io.BytesIO(img)).convert("RGB")).astype(int)
            inside = [(x, y) for x, y in st["pts"] if 12 < x < st["w"] - 12 and 12 < y < st["h"] - 12]
            assert len(inside) >= 3, st
            # a symbol's stroke (black, red, or grey when lost) within 8 px of the projected
            # point (a LiDAR-only track's circle has a radius of 5.7 px)
            hit = 0
            for x, y in inside:
                box = img[int(y) - 8:int(y) + 9, int(x) - 8:int(x) + 9]
                grey = (box.max(axis=2) < 140) & (box.max(axis=2) - box.min(axis=2) < 40)
                red = np.abs(box - np.array([224, 20, 30])).max(axis=2) < 40
                hit += (grey | red).sum() >= 3
            assert hit >= 0.9 * len(inside), (hit, len(inside), orient)
            # names: the nearest 20 and the dangerous ones, not all 24 targets on top of each other
            assert st["zoom"] >= 11.5 and 1 <= st["labels"] <= 20 + viewer(page)["table"]["dangerous"]
    finally:
        choose(page, "#sel-orient", "north")
    assert not foreign


def test_the_page_projects_like_asvtwin_geo(live):
    _srv, feed, page, _ = live
    rng = np.random.default_rng(1)
    ned = rng.uniform(-20_000, 20_000, size=(50, 2))
    lonlat = np.array(page.evaluate("pts => pts.map(p => asvtwinViewer.frame.toLonLat(p[0], p[1]))",
                                    ned.tolist()))
    ref = feed.scene().frame.points_to_lonlat(ned)
    np.testing.assert_allclose(lonlat, ref, atol=1e-9, rtol=0)
    back = np.array(page.evaluate("pts => pts.map(p => asvtwinViewer.frame.toNed(p[0], p[1]))",
                                  ref.tolist()))
    np.testing.assert_allclose(back, ned, atol=1e-4)


def test_table_sorts_and_alarms_until_acknowledged(live):
    _srv, feed, page, _ = live

    def column(i: int) -> list[float]:
        cells = page.locator(f"#targets tbody tr td:nth-child({i})").all_inner_texts()
        return [float(c) if c not in ("–", "") else math.inf for c in cells]
    page.click("#targets th[data-k=range]", **F)
    rng_nm = column(2)
    assert len(rng_nm) == len(feed.tgt_pos) and rng_nm == sorted(rng_nm)
    page.click("#targets th[data-k=range]", **F)
    assert column(2) == sorted(rng_nm, reverse=True)
    before = viewer(page)["table"]["unacked"]
    assert before >= 1
    page.locator("#targets tbody tr.danger button").first.click(**F)
    page.wait_for_function(f"asvtwinViewer.table.unacked == {before - 1}", timeout=WAIT_MS)
    assert page.locator("#targets tbody tr.danger.acked").count() >= 1


def test_controls_act_on_the_twin(live):
    _srv, feed, page, _ = live
    wait = page.wait_for_function
    page.click("#btn-pause", **F)  # the feed is paused: the button resumes
    wait("asvtwinViewer.latest && !asvtwinViewer.latest.clock.paused", timeout=WAIT_MS)
    t0 = viewer(page)["latest"]["t_s"]
    wait(f"asvtwinViewer.latest.t_s > {t0 + 0.5}", timeout=WAIT_MS)
    choose(page, "#sel-speed", "2")
    wait("asvtwinViewer.latest.clock.speed == 2", timeout=WAIT_MS)
    assert feed.speed == 2.0
    choose(page, "#chk-filter", "off")
    wait("asvtwinViewer.latest.filter.enabled === false && asvtwinViewer.chart.planStages == 0",
         timeout=WAIT_MS)
    choose(page, "#chk-filter", "on")
    wait("asvtwinViewer.latest.filter.enabled === true", timeout=WAIT_MS)
    choose(page, "#in-wind-speed", "15")
    choose(page, "#in-wind-from", "90")
    page.click("#btn-wind", **F)
    wait("asvtwinViewer.latest.weather.wind_speed_m_s == 15", timeout=WAIT_MS)
    assert feed.wind == (15.0, math.radians(90.0))
    n = len(feed.tgt_pos)
    page.click("#btn-inject", **F)
    box = page.locator("#chart").bounding_box()
    page.mouse.click(box["x"] + box["width"] * 0.5, box["y"] + box["height"] * 0.5)
    wait(f"asvtwinViewer.latest.tracks.ids.length == {n + 1}", timeout=WAIT_MS)
    assert feed.tgt_names[-1].startswith("INJECTED")
    page.click("#btn-route", **F)
    for fx, fy in ((0.3, 0.3), (0.7, 0.2)):
        page.mouse.click(box["x"] + box["width"] * fx, box["y"] + box["height"] * fy)
    page.click("#btn-route-send", **F)
    wait("asvtwinViewer.controls.route == 1", timeout=WAIT_MS)
    assert feed.route.shape == (2, 2)
    choose(page, "#sel-orient", "head")
    wait("Math.abs(asvtwinViewer.chart.bearing - asvtwinViewer.latest.own.state[2] * 180 / Math.PI"
         " % 360) < 1e-6", timeout=WAIT_MS)
    page.click("#btn-pause", **F)
    wait("asvtwinViewer.latest.clock.paused", timeout=WAIT_MS)
    assert feed.paused
    assert viewer(page)["errors"] == []


@pytest.fixture(scope="module")
def replay(browser, tmp_path_factory):
    feed = SyntheticFeed(6, seed=4)
    path = tmp_path_factory.mktemp("replay") / "run.mcap"
    rec = Recorder(path, scenario_json='{"name": "synthetic"}', seed=4)
    for _ in range(100):  # 10 s of snapshots
        s = feed.tick()
        rec.write("/twin/snapshot", s.t_s, encode(s))
    rec.close()
    with ServerThread(RecordingFeed(Recording(path))) as srv:
        page, foreign = open_viewer(browser, srv.url)
        yield srv, page, foreign
        page.close()


def test_replay_has_a_timeline_that_seeks(replay):
    srv, page, foreign = replay
    assert page.locator("#timeline").is_visible()
    assert float(page.get_attribute("#seek", "max")) == pytest.approx(10.0, abs=0.11)
    page.click("#btn-play", **F)  # pause the playback
    page.wait_for_function("asvtwinViewer.lastControl && asvtwinViewer.lastControl.status == 200",
                           timeout=WAIT_MS)
    assert page.evaluate("asvtwinViewer.lastControl.action") == "pause"
    paused_at = srv.feed.playback_time_s()
    # seek well away from where the pause stopped the playback: on a slow machine the page
    # opens ~2.5 s into the recording, and a target near that would be "reached" before the
    # seek was applied
    target = 7.5 if paused_at < 5.0 else 2.5
    page.evaluate("""(t) => { const s = document.getElementById('seek'); s.value = String(t);
                              s.dispatchEvent(new Event('change')); }""", target)
    page.wait_for_function("asvtwinViewer.lastControl.action == 'seek' "
                           "&& asvtwinViewer.lastControl.status == 200", timeout=WAIT_MS)
    page.wait_for_function(f"Math.abs(asvtwinViewer.latest.t_s - {target}) < 0.11",
                           timeout=WAIT_MS)
    assert srv.feed.playback_time_s() == pytest.approx(target, abs=1e-6)  # still paused
    save(page.locator("#timeline").screenshot(), "synthetic-viewer-timeline.png")
    assert not foreign


def test_whatif_draws_ghosts_and_the_answer(live):
    """A small what-if from the viewer's control (2 alternatives x 3 futures, 30 s): each
    future is drawn on the chart as a ghost in its alternative's colour, starting at the own
    ship, and the panel shows the probabilities and the recommendation in words."""
    _srv, feed, page, foreign = live
    if not feed.paused:
        page.click("#btn-pause", **F)
        page.wait_for_function("asvtwinViewer.latest.clock.paused", timeout=WAIT_MS)
    page.wait_for_timeout(500)
    before = save(page.locator("#chart-pane").screenshot(), "synthetic-viewer-whatif-before.png")
    page.click("#btn-whatif", **F)
    assert page.locator("#whatif-panel").is_visible()
    for value in ("route+filter_off", "keep_course"):
        choose(page, f".wi-alt[value='{value}']", "off")
    choose(page, "#wi-rollouts", "3")
    choose(page, "#wi-horizon", "30")
    page.click("#btn-whatif-ask", **F)
    page.wait_for_function("asvtwinViewer.whatif.asked >= 1", timeout=180_000)
    st = page.evaluate("asvtwinViewer.whatif")
    assert "error" not in st, st.get("error")
    ans = st["answer"]
    assert [a["label"] for a in ans["alternatives"]] == ["route", "starboard:30"]
    assert ans["rollouts"] == 3 and ans["horizon_s"] == 30
    assert len(ans["ghosts"]) == 6
    own = np.array(page.evaluate("asvtwinViewer.latest.own.state"))[:2]
    for g in ans["ghosts"]:
        pos = np.array(g["positions_m"])
        assert pos.shape[1] == 2 and len(pos) == len(ans["ghost_t_s"])
        assert np.hypot(*(pos[0] - own)) < 5.0  # each future starts at the own ship
    page.wait_for_function("asvtwinViewer.chart.ghosts == 6", timeout=WAIT_MS)
    # the lines in the chart's WebGL layer (built with the next snapshot drawn)
    q = "asvtwinViewer.chartView.drawnGhosts()"
    page.wait_for_function(f"{q}.length == 6", timeout=WAIT_MS)
    drawn = page.evaluate(q)
    # one colour per alternative, red (224, 20, 30) where that future collided
    colours = {a: {c for alt, c in drawn if alt == a} for a in ("route", "starboard:30")}
    collided = {g["alternative"] for g in ans["ghosts"] if g["collision"]}
    assert colours["route"] and colours["starboard:30"]
    if not collided:
        assert len(colours["route"]) == 1 and colours["route"] != colours["starboard:30"]
    panel = page.locator("#whatif-panel").inner_text()
    assert "route" in panel and "starboard:30" in panel
    assert ans["recommendation"]["label"] in panel and "collisions" in panel
    page.wait_for_timeout(800)
    after = save(page.locator("#chart-pane").screenshot(), "synthetic-viewer-whatif.png")
    assert (np.abs(after - before).max(axis=2) > 40).sum() > 200  # ghosts and panel drawn
    page.click("#btn-whatif-close", **F)
    page.wait_for_function("asvtwinViewer.chart.ghosts == 0", timeout=WAIT_MS)
    assert not foreign


def test_a_long_table_keeps_only_the_rows_in_view(browser):
    """200 targets: the table's DOM holds the rows in view and some more (virtualised), the
    scroll height is still the whole list's, and scrolling to the end shows the end of the
    sorted list."""
    feed = SyntheticFeed(200, seed=3, tick_hz=10.0)
    with ServerThread(feed) as srv:
        time.sleep(0.3)
        feed.control("pause", {})
        page, foreign = open_viewer(browser, srv.url)
        page.click("#targets th[data-k=range]", **F)  # ascending range
        box = """() => { const s = document.querySelector('.table-scroll'), top = s.getBoundingClientRect();
            const rows = [...document.querySelectorAll('#targets tbody tr:not(.pad)')];
            const seen = rows.filter((r) => { const b = r.getBoundingClientRect();
                return b.top >= top.top + 20 && b.bottom <= top.bottom + 1; });
            return {dom: rows.length, scroll: s.scrollHeight, view: s.clientHeight,
                    ranges: seen.map((r) => Number(r.cells[1].textContent)),
                    height: rows[0].getBoundingClientRect().height}; }"""
        head = page.evaluate(box)
        stats = viewer(page)["table"]
        n = stats["rows"]
        assert n >= 200 and 10 <= head["dom"] < 80 and stats["domRows"] == head["dom"]
        assert head["scroll"] >= n * head["height"]  # the spacers stand for the rest
        assert len(head["ranges"]) >= 5 and head["ranges"] == sorted(head["ranges"])
        page.evaluate("document.querySelector('.table-scroll').scrollTop = 1e7")
        page.wait_for_function(f"asvtwinViewer.table.first + asvtwinViewer.table.domRows == {n}",
                               timeout=WAIT_MS)
        tail = page.evaluate(box)
        assert len(tail["ranges"]) >= 5 and tail["ranges"] == sorted(tail["ranges"])
        assert min(tail["ranges"]) >= max(head["ranges"])
        assert tail["dom"] < 80
        page.close()
    assert not foreign
