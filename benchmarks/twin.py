"""Benchmark of the whole twin, headless; prints one JSON object.

The embedded default scenario (Trondheim Fjord, full-scale own ship under ``rl_psf``, the
shipped policy through the safety filter; ``--controller los_psf`` runs LOS guidance
through the filter instead, and the JSON says which ran;
synthetic AIS through the NMEA decoder, weather fixture) plus ``--extra-targets`` (50)
vessels placed at random on open water within 3 km of the own ship (seeded; a mix of
class A, class B and no transponder; constant velocity or a two-leg route), every
component on (AIS, LiDAR, tracker, observer and fault detector, controller, safety filter,
snapshots) and recording on (MCAP in a temporary folder), each at the default scenario's
rate (the JSON's ``sim_hz`` and ``filter_hz``: the world at 10 Hz, the filter at 0.25 Hz,
once per 4.18 s stage of the 88 m hull's plan; docs/twin.md, "The safety filter's rate").

- ``realtime_factor``: simulated seconds per wall second over the measured run
  (``--duration``, 3600 s: one simulated hour) after a warm-up (``--warmup``, 20 s: the
  solver's cold start); ``realtime_factor_cpu`` the same per second of this process's CPU
  time (what one idle core would give: the number to compare on a shared, loaded
  machine); ``realtime_factor_windows`` the same over each tenth of the run (the slowest
  is where the filter works hardest: the extra targets start 1 km or more away and only
  come within LiDAR range after a few minutes, so a short window at the start measures a
  twin with nothing to do);
- ``ms_per_tick``: wall time per tick of every component over the measured run
  (``unscheduled``: the rest of the tick, the loop and the transponders' NMEA encoding), and
  ``share``: each component's fraction of the tick (where the time goes); ``tick_ms`` and
  ``tick_cpu_ms`` the whole tick in wall and CPU time;
- ``snapshot_bytes``: median size of one encoded snapshot (and p95);
- ``recording_mb_per_h``: MCAP bytes written per *simulated* hour (zstd chunks);
- ``memory_growth_mb``: resident memory at the end of the measured run minus at its start
  (both after a garbage collection; goal: flat, < 10 MB over the hour).

The machine is shared: run it alone for numbers that mean something.
The scene: each extra target starts at least 1 km from the own ship (see
:func:`extra_targets`); the JSON also reports the run's safety (collisions, fallbacks,
closest approach) over the whole run, warm-up included.

Run: ``python benchmarks/twin.py [--extra-targets 50] [--duration 3600]``; ``--quick``:
a 300 s run. (Until 2026-12-01 the speed was measured over the first 120 s after the
warm-up and the memory over a separate hour after it: that window had no vessel in LiDAR
range, and its ``realtime_factor`` was 3 to 6 times the hour's.)
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from asvtwin.cli.argtypes import CONTROLLERS


def _rss_mb() -> float:
    """Current resident set size [MB] (Linux /proc; ru_maxrss elsewhere)."""
    try:
        with open("/proc/self/statm") as f:
            pages = int(f.read().split()[1])
        return pages * resource.getpagesize() / 2**20
    except OSError:  # pragma: no cover - not Linux
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def extra_targets(scenario, n: int, seed: int, *, min_start_m: float = 1000.0,
                  min_spacing_m: float = 200.0):  # type: ignore[no-untyped-def]
    """``n`` targets on open water within 3 km of the own ship (seeded).

    Each starts at least ``min_start_m`` from the own ship's start (the full-scale own
    ship needs d_safe 88 m plus a braking distance of up to 527 m: a target spawned
    closer, or on top of it, is a collision the benchmark made, not one the twin could
    avoid), at least ``min_spacing_m`` from every other target and 300 m from land.
    Targets keep their course (constant velocity or a looped two-leg route) and do not
    give way: the own ship's filter must keep clear of them all."""
    from asvtwin.scenarios import TargetSpec, resolve_scene, top_speed_m_s
    from asvtwin.units import KNOT_M_S

    rng = np.random.default_rng(seed)
    scene = resolve_scene(scenario)
    p0 = scenario.own_ship.start.to_ned(scene.frame)
    out = []
    starts: list[np.ndarray] = []
    while len(out) < n:
        p = p0 + rng.uniform(-3000.0, 3000.0, 2)
        if scene.land.signed_distance(p[None])[0] < 300.0:
            continue
        if np.hypot(*(p - p0)) < min_start_m:
            continue
        if any(np.hypot(*(p - q)) < min_spacing_m for q in starts):
            continue
        k = len(out)
        length = float(rng.uniform(15.0, 150.0))
        top_kn = top_speed_m_s(length) / KNOT_M_S
        cls = ("A", "B", None)[k % 3]
        spec = {"name": f"EXTRA{k:02d}", "mmsi": 257_500_000 + k if cls else None,
                "ais_class": cls, "vessel_type": "cargo", "length_m": round(length, 1),
                "beam_m": round(length / 6.0, 1),
                "start": {"north_m": float(p[0]), "east_m": float(p[1])},
                "heading_deg": float(rng.uniform(0.0, 360.0)),
                "speed_kn": round(float(min(rng.uniform(2.0, 8.0), 0.9 * top_kn)), 1)}
        if k % 2:
            d = rng.uniform(-800.0, 800.0, (2, 2))
            wps = [p + d[0], p + d[0] + d[1]]
            if (scene.land.signed_distance(np.asarray(wps)) < 200.0).any():
                continue
            spec["behaviour"] = {"kind": "waypoints", "loop": True, "route": [
                {"north_m": float(w[0]), "east_m": float(w[1])} for w in wps]}
        out.append(TargetSpec.model_validate(spec))
        starts.append(p)
    return out


def main(argv: list[str] | None = None) -> dict[str, object]:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--extra-targets", type=int, default=50)
    ap.add_argument("--duration", type=float, default=3600.0,
                    help="measured simulated s (speed and memory)")
    ap.add_argument("--warmup", type=float, default=20.0, help="simulated s not measured")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--quick", action="store_true", help="a short check: a 300 s run")
    ap.add_argument("--controller", default=None, choices=CONTROLLERS,
                    help="the own ship's controller (default: the default scenario's)")
    args = ap.parse_args(argv)
    if args.quick:
        args.duration = 300.0
    if not (args.duration > 0 and args.warmup >= 0):
        ap.error("--duration must be > 0 and --warmup >= 0 [simulated s]")

    from asvtwin.scenarios import default_scenario
    from asvtwin.twin import Twin

    base = default_scenario()
    if args.controller is not None:
        base = base.with_controller(args.controller)
    targets = list(base.targets) + extra_targets(base, args.extra_targets, args.seed)
    total = args.warmup + args.duration
    scenario = base.model_copy(update={"targets": targets, "duration_s": max(total, 1.0)})
    scenario = type(base).model_validate(scenario.model_dump(mode="json"))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.mcap"
        t_build = time.perf_counter()
        twin = Twin(scenario, record_path=path)
        build_s = time.perf_counter() - t_build
        sizes: list[int] = []
        twin.on_snapshot = lambda s, b: sizes.append(len(b))
        n_warm = round(args.warmup / twin.dt_s)
        for _ in range(n_warm):
            twin.step()
        sch = twin.scheduler
        names = [h.name for h in sch.health()]
        ms0 = {n: sch.stats(n).total_ms for n in names}
        bytes0 = twin.recorder.bytes_written if twin.recorder else 0
        sizes.clear()
        import gc

        gc.collect()
        rss0 = _rss_mb()
        n_meas = round(args.duration / twin.dt_s)
        n_win = max(1, n_meas // 10)
        windows: list[float] = []
        t0, c0 = time.perf_counter(), time.process_time()
        tw = t0
        for k in range(1, n_meas + 1):
            twin.step()
            if k % n_win == 0:
                now = time.perf_counter()
                windows.append(n_win * twin.dt_s / (now - tw))
                tw = now
                print(f"{k * twin.dt_s:.0f} of {args.duration:.0f} simulated s: "
                      f"{windows[-1]:.1f}x real time, rss {_rss_mb() - rss0:+.1f} MB",
                      file=sys.stderr, flush=True)
        wall = time.perf_counter() - t0
        cpu = time.process_time() - c0
        gc.collect()
        mem = _rss_mb() - rss0
        bytes1 = twin.recorder.bytes_written if twin.recorder else 0
        ms = {n: (sch.stats(n).total_ms - ms0[n]) / n_meas for n in names}
        tick_ms = 1e3 * wall / n_meas
        # what no component's timer holds: the loop itself, the transponders' NMEA
        # encoding (outside the "ais" component), commands, bookkeeping
        ms["unscheduled"] = max(tick_ms - sum(ms.values()), 0.0)
        twin.close()
        summary = twin.summary()
    sim_s = n_meas * twin.dt_s
    sz = np.asarray(sizes) if sizes else np.zeros(1)
    out: dict[str, object] = {
        "realtime_factor": round(sim_s / wall, 2),
        "realtime_factor_cpu": round(sim_s / cpu, 2),
        "realtime_factor_windows": [round(w, 2) for w in windows],
        "targets": len(targets),
        "controller": scenario.own_ship.controller,
        "sim_hz": scenario.rates.sim_hz,
        "filter_hz": scenario.rates.filter_hz,
        "tick_ms": round(tick_ms, 3),
        "tick_cpu_ms": round(1e3 * cpu / n_meas, 3),
        "ms_per_tick": {k: round(v, 4) for k, v in sorted(ms.items(), key=lambda kv: -kv[1])},
        "share": {k: round(v / tick_ms, 3) for k, v in sorted(ms.items(), key=lambda kv: -kv[1])},
        "snapshot_bytes": int(np.median(sz)),
        "snapshot_bytes_p95": int(np.percentile(sz, 95)),
        "recording_mb_per_h": round((bytes1 - bytes0) / 2**20 * 3600.0 / sim_s, 2),
        "memory_growth_mb": round(mem, 2),
        "build_s": round(build_s, 2),
        # safety over the whole run (warm-up and measurement)
        "run_sim_s": round(summary.duration_s, 1),
        "filter_calls": summary.filter_calls,
        "fallbacks": summary.fallbacks,
        "fallback_rate": round(sum(summary.fallbacks.values()) / max(summary.filter_calls, 1),
                               4),
        "collisions": summary.collisions,
        "groundings": summary.groundings,
        "min_distance_targets_m": round(min(summary.min_distance_targets_m.values(),
                                            default=float("nan")), 1),
        "measured_sim_s": sim_s,
        "load_average_1min": round(float(__import__("os").getloadavg()[0]), 2),
    }
    print(json.dumps(out))
    return out


def _quiet_stdout_main() -> dict[str, object]:
    """Run :func:`main` with file descriptor 1 pointed at stderr (a solver's C library
    prints its warnings to stdout), then print the one JSON object on the real stdout."""
    import io
    import os

    sys.stdout.flush()
    saved = os.dup(1)
    os.dup2(2, 1)
    buf = io.StringIO()
    real, sys.stdout = sys.stdout, buf
    try:
        out = main()
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)
        sys.stdout = real
    print(buf.getvalue().strip().splitlines()[-1])
    return out


if __name__ == "__main__":
    sys.exit(0 if _quiet_stdout_main() else 1)
