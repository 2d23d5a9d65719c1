"""The viewer against the real twin (``asvtwin run``'s embedded default: the Trondheim
harbour scene, transponders through the NMEA decoder, the full-scale own ship on the
safety filter) in Debian's Chromium. The twin runs ahead at full speed, then is paused:
a page opened on the paused twin must get its latest snapshot and draw it. The pictures
of docs/viewer.md come from here (``ASVTWIN_DOC_IMAGES=1``)."""

from __future__ import annotations

import time

import httpx
import numpy as np
import pytest

from tests.web.chromium import launch
from tests.web.test_viewer import CHROMIUM, TIMEOUT_MS, count_colour, local_only, save, viewer

playwright = pytest.importorskip("playwright.sync_api")
pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="Debian's chromium is not installed")

RUN_AHEAD_S = 45.0  # simulated seconds before the pictures: tracks and a plan exist


@pytest.fixture(scope="module")
def paused_twin():
    from asvtwin.scenarios import default_scenario
    from asvtwin.server import ServerThread
    from asvtwin.twin import Clock, Twin

    sc = default_scenario()
    twin = Twin(sc, clock=Clock("max", start_time_utc=sc.start_time_utc), record_path=None)
    with ServerThread(twin) as srv:
        end = time.monotonic() + 400  # a cold numba cache compiles first
        while twin.t_s < RUN_AHEAD_S:
            assert time.monotonic() < end, f"the twin reached only {twin.t_s:.0f} s"
            time.sleep(0.2)
        httpx.post(srv.url + "api/control/pause", json={}, timeout=10).raise_for_status()
        k = twin.tick
        time.sleep(1.0)
        assert twin.tick <= k + 1  # paused at the next tick boundary
        yield srv, twin
    twin.close()


def test_the_viewer_draws_the_paused_live_twin(paused_twin):
    srv, twin = paused_twin
    latest = twin.latest()
    with playwright.sync_playwright() as pw:
        browser, _ = launch(pw)
        page = browser.new_page(viewport={"width": 1500, "height": 950})
        foreign: list[str] = []
        page.route("**/*", lambda r: r.continue_() if local_only(r.request.url)
                   else (foreign.append(r.request.url), r.abort()))
        page.on("websocket", lambda ws: None if local_only(ws.url) else foreign.append(ws.url))
        page.goto(srv.url)
        page.wait_for_function("window.asvtwinViewer && asvtwinViewer.ready && "
                               "asvtwinViewer.chart.updates > 0 && asvtwinViewer.table.updates > 0",
                               timeout=TIMEOUT_MS)
        # zoomed out so that the twin's AIS targets (2-4 nm off) are on the chart
        page.evaluate("asvtwinViewer.map.jumpTo({zoom: 11.6})")
        page.wait_for_function("asvtwinViewer.chart.sourceMaxzoom == 8", timeout=60_000)
        page.wait_for_timeout(2500)  # MapLibre's worker finishing the tiles
        v = viewer(page)
        assert v["errors"] == []
        s = v["latest"]
        # the page shows the twin's latest snapshot although the twin ticks no more
        assert s["seq"] == latest.seq and s["clock"]["paused"] is True
        assert s["scenario"] == "default" and s["own"]["vessel"] == "cybership2_full_scale"
        n_tracks = len(s["tracks"]["ids"])
        assert n_tracks >= 1 and v["chart"]["cones"] == n_tracks
        assert v["chart"]["planStages"] == len(s["filter"]["plan"]) - 1 > 0
        assert v["table"]["rows"] == v["targets"] >= n_tracks
        assert v["view3d"]["hulls"] == v["targets"] + 1
        save(page.screenshot(), "viewer.png")
        chart = save(page.locator("#chart-pane").screenshot(), "viewer-chart.png")
        assert count_colour(chart, (26, 154, 42)) + count_colour(chart, (224, 20, 30)) > 30
        assert count_colour(chart, (216, 200, 154), tol=6) > 2000  # land
        view3d = save(page.locator("#view3d-pane").screenshot(), "viewer-3d.png")
        assert view3d.std() > 10
        save(page.locator("#table-pane").screenshot(), "viewer-table.png")
        status = page.locator("#status").inner_text()
        assert "synthetic" not in status.split("weather")[0]  # the scenario is the twin's
        assert np.isfinite(s["own"]["state"]).all()
        # a small what-if on the real twin (its land, its hull): ghosts from the own ship
        page.click("#btn-whatif", force=True)
        page.evaluate("""() => { for (const c of document.querySelectorAll('.wi-alt'))
                                   c.checked = ['route', 'starboard:30'].includes(c.value);
                                 document.getElementById('wi-rollouts').value = '4';
                                 document.getElementById('wi-horizon').value = '240'; }""")
        page.click("#btn-whatif-ask", force=True)
        page.wait_for_function("asvtwinViewer.whatif.asked >= 1", timeout=240_000)
        st = page.evaluate("asvtwinViewer.whatif")
        assert "error" not in st, st.get("error")
        assert len(st["answer"]["ghosts"]) == 8
        own = np.array(s["own"]["state"][:2])
        for g in st["answer"]["ghosts"]:
            assert np.hypot(*(np.array(g["positions_m"][0]) - own)) < 5.0
        page.wait_for_function("asvtwinViewer.chart.ghosts == 8", timeout=60_000)
        page.wait_for_timeout(1500)
        save(page.locator("#chart-pane").screenshot(), "viewer-whatif.png")
        browser.close()
    assert not foreign, f"requests to other addresses than 127.0.0.1: {foreign}"
