"""Viewer and server benchmark: prints one JSON object.

- ``viewer_fps``: frames presented per second (the display compositor's draw-and-swap,
  read from a Chrome trace: frames that reached the screen, not animation-frame callbacks)
  by the viewer page in headless Chromium (Debian's, software WebGL: Mesa's llvmpipe when
  installed, else SwiftShader, see tests/web/chromium.py; ``viewer_webgl_renderer`` names
  the one used; device pixel ratio 1, 1500 x 950 px) with 200 targets streaming at 10 Hz,
  while a view is moved every frame as a user's drag would move it: the chart panned
  (``viewer_fps_chart``) and the 3-D camera orbiting the own ship (``viewer_fps_3d``);
  ``viewer_fps`` is the lower of the two. ``viewer_fps_data_only`` is the page left
  alone (it draws on demand: about one frame per snapshot). Each phase also reports the
  page's own counts per second (chart renders and data updates, 3-D renders, snapshots)
  and the browser's CPU time per presented frame (all its processes, from /proc): on a
  loaded machine the wall time is mostly waiting for a core, the CPU time is not, so
  ``2 cores x 1000 / viewer_cpu_ms_per_frame_*`` bounds the frame rate a quiet 2-core
  machine could reach. ``main_thread_ms_per_s`` in each phase is the page's own
  JavaScript time per second by part (snapshot parsing, target derivation, chart and 3-D
  updates, 3-D render calls, table, status panel). When llvmpipe is used, the same is measured with SwiftShader
  (``viewer_swiftshader``) right after, for comparison.
- ``ws_clients_held``: the most concurrent WebSocket clients at 10 Hz (of 5, 10, 20, 30,
  40) for which the feed loop's median tick time stayed within 10 % of the no-client
  medians measured just before and after (interleaved) and every client still got >= 90 % of its
  10 Hz. Every client is sent the same bytes, encoded once per snapshot. The feed is the synthetic one (50
  targets, one snapshot per tick at 10 Hz) in the server's process, as ``asvtwin run``
  runs the twin; the clients run in another process.
- ``snapshot_bytes``: the 200-target snapshot on the wire (JSON); also msgpack, and the
  real twin's default scenario.

The machine is shared: ``load_avg_1min`` is recorded with the numbers, which move with it.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from asvtwin.server import ServerThread, SyntheticFeed
from tests.web.chromium import CHROMIUM, launch

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


def clients_held(levels=(5, 10, 20, 30, 40), hold_s: float = 6.0) -> dict[str, object]:
    """The most clients (of ``levels``) served at 10 Hz with the feed's median tick time
    within 10 % of the no-client medians measured just before and just after that level
    (interleaved, so a change in the machine's load between levels does not count as the
    clients' cost)."""
    feed = SyntheticFeed(50, seed=1, tick_hz=10.0)
    rows = []
    with ServerThread(feed) as srv:
        time.sleep(2.0)
        held = 0
        for n in levels:
            base = tick_ms_median(feed, 4.0)
            proc = subprocess.Popen([sys.executable, str(CLIENTS), srv.url.replace("http", "ws") + "ws",
                                     str(n), "10", str(hold_s), "1"], stdout=subprocess.PIPE, text=True)
            end = time.monotonic() + 60
            while len(srv.hub.clients) < n and time.monotonic() < end:
                time.sleep(0.02)
            tick = tick_ms_median(feed, hold_s - 2.0)
            out, _ = proc.communicate(timeout=120)
            res = json.loads(out.splitlines()[-1])
            base = 0.5 * (base + tick_ms_median(feed, 4.0))  # no clients, before and after
            rate_min = min(res["messages"]) / hold_s if res["messages"] else 0.0
            ok = res["ok"] == n and tick <= 1.1 * base and rate_min >= 9.0
            rows.append({"clients": n, "base_tick_ms": round(base, 3), "tick_ms": round(tick, 3),
                         "ratio": round(tick / base, 3), "rate_hz_min": round(rate_min, 2),
                         "ok": ok})
            if ok:
                held = n
            else:
                break
    return {"ws_clients_held": held, "ws_levels": rows}


# Each animation frame, move one view as a user's drag would: the chart pans (follow off),
# or the 3-D camera orbits the own ship. Snapshots keep arriving at 10 Hz meanwhile and
# are drawn as they come. Resolves with the page's own counters over `ms`.
_DRIVE = """([view, ms]) => new Promise((resolve) => {
    const V = asvtwinViewer, c0 = V.chart.renders, u0 = V.chart.updates, r0 = V.view3d.frames,
          s0 = V.snapshots, t0 = performance.now(), ms0 = {...V.ms};
    let raf = 0, k = 0;
    const f = (now) => {
        raf++;
        if (view === 'chart') V.map.panBy([(k++ % 200) < 100 ? 3 : -3, 0], {duration: 0});
        else if (view === '3d') V.view.orbitBy(0.02);
        if (now - t0 < ms) requestAnimationFrame(f);
        else { const s = (now - t0) / 1000;
            resolve({s, raf: raf / s, chart_renders: (V.chart.renders - c0) / s,
                     chart_updates: (V.chart.updates - u0) / s, renders_3d: (V.view3d.frames - r0) / s,
                     snapshots: (V.snapshots - s0) / s, targets: V.targets, errors: V.errors,
                     main_thread_ms_per_s: Object.fromEntries(Object.entries(V.ms).map(
                         ([k, v]) => [k, Math.round((v - ms0[k]) / s * 10) / 10]))}); } };
    requestAnimationFrame(f); })"""


def _tree_cpu_s() -> float:
    """CPU time [s] (user + system) of this process's descendants (the Playwright driver and
    every Chromium process), read from /proc: the cost of a frame apart from waiting for a
    core, which on a loaded machine is most of the wall time."""
    me = os.getpid()
    stats: dict[int, tuple[int, float]] = {}
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            f = (d / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        stats[int(d.name)] = (int(f[1]), (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK"))
    kids: dict[int, list[int]] = {}
    for pid, (ppid, _) in stats.items():
        kids.setdefault(ppid, []).append(pid)
    total, todo = 0.0, list(kids.get(me, []))
    while todo:
        pid = todo.pop()
        total += stats[pid][1]
        todo.extend(kids.get(pid, []))
    return total


def _presented(trace_path: Path) -> int:
    """Frames the display compositor drew and swapped (``Display::DrawAndSwap``): the
    frames that reached the screen, not animation-frame callbacks."""
    ev = json.loads(trace_path.read_text())
    ev = ev["traceEvents"] if isinstance(ev, dict) else ev
    return sum(1 for e in ev if e.get("name") == "Display::DrawAndSwap" and e.get("ph") in ("X", "B"))


def viewer_fps(n_targets: int = 200, seconds: float = 8.0, gl: str | None = None) -> dict[str, object]:
    """Frames presented per second with ``n_targets`` targets streaming at 10 Hz, for each
    view driven by a simulated drag (chart: pan; 3-D: orbit) and for the page left alone
    (data only), with the software WebGL ``gl`` (``llvmpipe``, ``swiftshader``; default:
    llvmpipe when Mesa has it). Device pixel ratio 1, 1500 x 950 px window."""
    if CHROMIUM is None:
        return {"viewer_fps": None, "viewer_error": "chromium not installed"}
    import tempfile

    from playwright.sync_api import sync_playwright

    feed = SyntheticFeed(n_targets, seed=2, tick_hz=10.0)
    out: dict[str, object] = {}
    with ServerThread(feed) as srv, sync_playwright() as pw, \
            tempfile.TemporaryDirectory() as tmp:
        browser, renderer = launch(pw, gl)
        page = browser.new_page(viewport={"width": 1500, "height": 950}, device_scale_factor=1)
        page.route("**/*", lambda r: r.continue_() if r.request.url.startswith(srv.url)
                   else r.abort())
        page.goto(srv.url)
        page.wait_for_function("window.asvtwinViewer && asvtwinViewer.ready && "
                               "asvtwinViewer.chart.updates > 1", timeout=180_000)
        page.wait_for_timeout(3000)
        page.evaluate("""() => { const c = document.getElementById('chk-follow'); c.checked = false;
                         c.dispatchEvent(new Event('change')); }""")
        for view in ("chart", "3d", "data"):
            trace = Path(tmp) / f"{view}.json"
            browser.start_tracing(page=page, path=str(trace), categories=["viz"])
            cpu0 = _tree_cpu_s()
            res = page.evaluate(_DRIVE, [view, seconds * 1000])
            cpu1 = _tree_cpu_s()
            browser.stop_tracing()
            frames = _presented(trace)
            res["presented_fps"] = frames / res["s"]
            res["browser_cpu_ms_per_frame"] = 1e3 * (cpu1 - cpu0) / max(frames, 1)
            res["browser_cpu_cores"] = (cpu1 - cpu0) / res["s"]
            out[view] = {k: (round(v, 2) if isinstance(v, float) else v) for k, v in res.items()}
        browser.close()
    fps_chart, fps_3d = out["chart"]["presented_fps"], out["3d"]["presented_fps"]
    return {"viewer_fps": min(fps_chart, fps_3d), "viewer_fps_chart": fps_chart,
            "viewer_fps_3d": fps_3d, "viewer_fps_data_only": out["data"]["presented_fps"],
            "viewer_cpu_ms_per_frame_chart": out["chart"]["browser_cpu_ms_per_frame"],
            "viewer_cpu_ms_per_frame_3d": out["3d"]["browser_cpu_ms_per_frame"],
            "viewer_targets": out["chart"]["targets"], "viewer_webgl_renderer": renderer,
            "viewer_phases": out}


def main() -> None:
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--viewer-only", action="store_true",
                    help="only the frame rate (no snapshot sizes, no WebSocket clients)")
    ap.add_argument("--gl", choices=("llvmpipe", "swiftshader"), default=None,
                    help="software WebGL for viewer_fps (default: llvmpipe when Mesa has it)")
    ap.add_argument("--seconds", type=float, default=8.0, help="length of each viewer phase [s]")
    args = ap.parse_args()
    out: dict[str, object] = {"load_avg_1min_start": os.getloadavg()[0]}
    if not args.viewer_only:
        sizes = snapshot_sizes()
        out["snapshot_bytes"] = sizes["synthetic_200_json"]
        out["snapshot_bytes_detail"] = sizes
        out.update(clients_held())
    out.update(viewer_fps(seconds=args.seconds, gl=args.gl))
    if args.gl is None and "llvmpipe" in str(out.get("viewer_webgl_renderer")):
        # the same with Chromium's own software WebGL, for comparison
        ref = viewer_fps(seconds=args.seconds, gl="swiftshader")
        out["viewer_swiftshader"] = {k: v for k, v in ref.items() if k != "viewer_phases"}
    out["load_avg_1min_end"] = os.getloadavg()[0]
    out["note"] = ("shared 2-core machine: numbers move with the load average (software WebGL "
                   "rasterises on the CPU, in several threads, so a loaded machine slows it "
                   "most); viewer_fps = min(chart panned, 3-D orbiting) frames presented/s")
    print(json.dumps(out))


if __name__ == "__main__":
    main()
