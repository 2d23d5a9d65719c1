"""Viewer and server benchmark: prints one JSON object.

- ``viewer_fps``: animation frames per second of the viewer page in headless Chromium
  (Debian's, software WebGL through SwiftShader) with 200 targets streaming at 10 Hz,
  measured over 10 s with ``requestAnimationFrame``; beside it the chart updates, 3-D
  renders and snapshots the page handled per second.
- ``ws_clients_held``: the most concurrent WebSocket clients at 10 Hz (of 0, 5, 10, 20, 40)
  for which the feed loop's median tick time stayed within 10 % of the no-client baseline
  and every client still got >= 90 % of its 10 Hz. The feed is the synthetic one (50
  targets, one snapshot per tick at 10 Hz) in the server's process, as ``asvtwin run``
  runs the twin; the clients run in another process.
- ``snapshot_bytes``: the 200-target snapshot on the wire (JSON); also msgpack, and the
  real twin's default scenario.

The machine is shared: ``load_avg_1min`` is recorded with the numbers, which move with it.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from asvtwin.server import ServerThread, SyntheticFeed

CLIENTS = ROOT / "tests" / "server" / "wsclients.py"


def snapshot_sizes() -> dict[str, int]:
    f = SyntheticFeed(200, seed=0)
    f.tick()
    fr = f.frame()
    out = {"synthetic_200_json": len(fr.data), "synthetic_200_msgpack": len(fr.msgpack())}
    try:
        from asvtwin.scenarios import default_scenario
        from asvtwin.twin import Clock, Twin

        sc = default_scenario()
        twin = Twin(sc, clock=Clock("max", start_time_utc=sc.start_time_utc), record_path=None)
        for _ in range(40):
            twin.step()
        out["twin_default_json"] = len(twin.latest_bytes() or b"")
        twin.close()
    except Exception as exc:  # noqa: BLE001 - reported, not fatal
        out["twin_default_error"] = repr(exc)[:200]
    return out


def tick_ms_median(feed: SyntheticFeed, seconds: float) -> float:
    t0 = time.perf_counter()
    time.sleep(seconds)
    return feed.tick_stats(since=t0)["tick_ms_median"]


def clients_held(levels=(0, 5, 10, 20, 40), hold_s: float = 6.0) -> dict[str, object]:
    feed = SyntheticFeed(50, seed=1, tick_hz=10.0)
    rows = []
    with ServerThread(feed) as srv:
        time.sleep(2.0)
        base = tick_ms_median(feed, 4.0)
        held = 0
        for n in levels:
            if n == 0:
                rows.append({"clients": 0, "tick_ms": base, "rate_hz_min": None})
                continue
            proc = subprocess.Popen([sys.executable, str(CLIENTS), srv.url.replace("http", "ws") + "ws",
                                     str(n), "10", str(hold_s), "1"], stdout=subprocess.PIPE, text=True)
            end = time.monotonic() + 60
            while len(srv.hub.clients) < n and time.monotonic() < end:
                time.sleep(0.02)
            tick = tick_ms_median(feed, hold_s - 2.0)
            out, _ = proc.communicate(timeout=120)
            res = json.loads(out.splitlines()[-1])
            rate_min = min(res["messages"]) / hold_s if res["messages"] else 0.0
            ok = res["ok"] == n and tick <= 1.1 * base and rate_min >= 9.0
            rows.append({"clients": n, "tick_ms": round(tick, 3), "rate_hz_min": round(rate_min, 2),
                         "ok": ok})
            if ok:
                held = n
            else:
                break
    return {"ws_clients_held": held, "ws_baseline_tick_ms": round(base, 3), "ws_levels": rows}


def viewer_fps(n_targets: int = 200, seconds: float = 10.0) -> dict[str, object]:
    chromium = shutil.which("chromium")
    if chromium is None:
        return {"viewer_fps": None, "viewer_error": "chromium not installed"}
    from playwright.sync_api import sync_playwright

    feed = SyntheticFeed(n_targets, seed=2, tick_hz=10.0)
    with ServerThread(feed) as srv, sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=chromium)
        page = browser.new_page(viewport={"width": 1500, "height": 950})
        page.route("**/*", lambda r: r.continue_() if r.request.url.startswith(srv.url)
                   else r.abort())
        page.goto(srv.url)
        page.wait_for_function("window.asvtwinViewer && asvtwinViewer.ready && "
                               "asvtwinViewer.chart.updates > 1", timeout=180_000)
        page.wait_for_timeout(3000)
        res = page.evaluate("""(ms) => new Promise((resolve) => {
            const V = asvtwinViewer, c0 = V.chart.updates, r0 = V.view3d.frames, s0 = V.snapshots;
            let n = 0; const t0 = performance.now();
            const f = (now) => { n++; if (now - t0 < ms) requestAnimationFrame(f); else {
                const s = (now - t0) / 1000;
                resolve({fps: n / s, chart: (V.chart.updates - c0) / s, r3d: (V.view3d.frames - r0) / s,
                         snaps: (V.snapshots - s0) / s, targets: V.targets, errors: V.errors}); } };
            requestAnimationFrame(f); })""", seconds * 1000)
        browser.close()
    return {"viewer_fps": round(res["fps"], 2), "viewer_chart_updates_per_s": round(res["chart"], 2),
            "viewer_3d_renders_per_s": round(res["r3d"], 2),
            "viewer_snapshots_per_s": round(res["snaps"], 2), "viewer_targets": res["targets"],
            "viewer_errors": res["errors"]}


def main() -> None:
    out: dict[str, object] = {"load_avg_1min_start": os.getloadavg()[0]}
    sizes = snapshot_sizes()
    out["snapshot_bytes"] = sizes["synthetic_200_json"]
    out["snapshot_bytes_detail"] = sizes
    out.update(clients_held())
    out.update(viewer_fps())
    out["load_avg_1min_end"] = os.getloadavg()[0]
    out["note"] = ("shared 2-core machine: numbers move with the load average; viewer_fps is "
                   "requestAnimationFrame callbacks per second (the chart and 3-D view redraw "
                   "on new data, at most 5 per second)")
    print(json.dumps(out))


if __name__ == "__main__":
    main()
