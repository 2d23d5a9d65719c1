"""AIS ingest benchmark: prints one JSON object.

- ``lines_per_s``: the whole ingest path, decode -> validate -> registry -> store (SQLite file
  in WAL mode), over a large synthetic log (fjord traffic x10 vessels, tag blocks, 5 %
  duplicate receptions), median of ``--repeats`` runs, each on fresh objects, wall time
  including the store's final ``close()``;
- ``lines_per_cpu_s`` / ``cpu_overhead_ratio``: the same from ``time.process_time()`` (user +
  system CPU of the whole process, every thread), i.e. the cost on one core without the time
  spent waiting for fsync; ``store_bytes_per_report``: database size after close;
- ``pyais_decode_lines_per_s``: bare pyais (``IterMessages`` + ``decode()``) over the same
  lines in the same run, and the ``overhead_ratio`` between the two (also as the median of
  back-to-back pairs and from the best runs, which are steadier on a shared machine), with and
  without the SQLite store;
- ``pyais_decode_path``: the same ingest with ``AisPipeline(batch_decode=False)``, i.e. every
  message decoded by pyais one at a time: what the pipeline's checks cost on top of pyais.

What each side does, on the same lines (every line has a tag block; about 5 % are a second
reception of the same transmission; type 5 messages take two sentences; the output's
``log`` says how many of each):

- **ours**: per line, the tag block parsed and its checksum checked (cached per distinct tag),
  the sentence checksum checked, the fields, fill bits and 6-bit alphabet checked, fragments
  assembled with a timeout, duplicates dropped, the position reports decoded (one-sentence
  types 1/2/3/18 by the numpy batch decoder, checked against pyais in the tests; the rest by
  pyais), MMSI, time and position validated, projected to NED; then the target registry and
  the SQLite store (one transaction per batch, closed inside the timing);
- **bare pyais**: ``IterMessages`` parses each line (tag block split off, not checked; the
  sentence checksum not verified), assembles multi-sentence messages and ``decode()`` decodes
  every message, duplicates included; nothing is validated, projected or stored.
- ``replay_memory``: traced memory (tracemalloc) of the registry alone and of everything
  (pipeline, registry, source) every 5 min of stream time during a 1-hour file replay paced
  at 100x (36 s of wall time; ``--quick`` replays 10 min), its growth from the 5-minute mark
  to the end (sampled every minute), plus the peak under MMSI churn (100 000 distinct MMSIs,
  capacity 4096).

Nothing connects to the network. Run: ``python benchmarks/ais.py [--quick]``.
"""

from __future__ import annotations

import argparse
import asyncio
import dataclasses
import json
import logging
import statistics
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np
from pyais.stream import IterMessages

from asvtwin.geo import default_scene
from asvtwin.sources.ais import (
    AisPipeline,
    FileReplaySource,
    ReportBatch,
    SyntheticTraffic,
    TargetRegistry,
    default_fleet,
)
from asvtwin.sources.history import SqliteHistory

START_UNIX_S = 1_732_100_400.0  # 2024-11-20 11:00 UTC


def big_fleet(copies: int) -> list:
    """The default fleet repeated with new MMSIs and spread start positions."""
    fleet = []
    for k in range(copies):
        for v in default_fleet():
            fleet.append(dataclasses.replace(
                v, mmsi=v.mmsi + 1000 * k, name=f"{v.name[:16]} {k}",
                start_fraction=(v.start_fraction + 0.097 * k) % 1.0))
    return fleet


def make_log(duration_s: float, copies: int, seed: int = 7) -> list[bytes]:
    traffic = SyntheticTraffic(big_fleet(copies), rng=np.random.default_rng(seed),
                               start_unix_s=START_UNIX_S, duplicate_probability=0.05)
    return [line.encode("ascii") for line in traffic.lines(duration_s)]


def ingest(lines: list[bytes], db_path: Path | None, chunk: int = 1024, *,
           batch_decode: bool = True) -> tuple[float, float, int]:
    """Time decode -> validate -> registry -> store (skipped when db_path is None).

    Returns wall time [s], CPU time of this process [s] (``time.process_time``: user + system,
    all threads, so nothing can hide in a background thread or in the kernel's write calls)
    and the number of accepted reports. The store is closed (committed) inside the timing.
    """
    scene = default_scene()
    pipeline = AisPipeline(scene, batch_decode=batch_decode)
    registry = TargetRegistry(epoch_unix_s=START_UNIX_S)
    store = SqliteHistory(db_path) if db_path is not None else None
    n = 0
    c0 = time.process_time()
    t0 = time.perf_counter()
    for i in range(0, len(lines), chunk):
        batch = pipeline.feed_batch(lines[i:i + chunk])
        registry.update_batch(batch)
        if store is not None:
            store.append_batch(batch)
        n += len(batch)
    if store is not None:
        store.close()
    return time.perf_counter() - t0, time.process_time() - c0, n


def bare_pyais(lines: list[bytes]) -> tuple[float, float]:
    """Wall and CPU time [s] of bare pyais decoding of ``lines``."""
    c0 = time.process_time()
    t0 = time.perf_counter()
    for msg in IterMessages(lines):
        msg.decode()
    return time.perf_counter() - t0, time.process_time() - c0


def replay_memory(lines: list[bytes], log_path: Path, duration_s: float) -> dict[str, object]:
    log_path.write_bytes(b"\n".join(lines) + b"\n")
    pipeline = AisPipeline(default_scene())
    registry = TargetRegistry(epoch_unix_s=START_UNIX_S)
    samples: list[int] = []
    registry_bytes: list[int] = []
    only_registry = [tracemalloc.Filter(True, "*/sources/ais/registry.py")]

    async def run() -> float:
        src = FileReplaySource(log_path, speed=100.0, pipeline=pipeline)
        next_mark = START_UNIX_S
        t0 = time.perf_counter()
        async for batch in src.batches():
            registry.update_batch(batch)
            t = pipeline.latest_time_unix_s
            if t is not None and t >= next_mark:
                registry.extrapolate(t - START_UNIX_S)
                samples.append(tracemalloc.get_traced_memory()[0])
                snap = tracemalloc.take_snapshot().filter_traces(only_registry)
                registry_bytes.append(sum(s.size for s in snap.statistics("filename")))
                next_mark += 60.0
        return time.perf_counter() - t0

    tracemalloc.start()
    wall = asyncio.run(run())
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    # churn: 100 000 distinct MMSIs through a 4096-slot registry
    tracemalloc.start()
    reg = TargetRegistry(capacity=4096)
    rng = np.random.default_rng(1)
    base = None
    for k in range(100):
        m = np.arange(k * 1000, (k + 1) * 1000, dtype=np.int64) + 200_000_000
        z = np.zeros(1000)
        b = ReportBatch(m, z + k * 10.0, np.ones(1000, dtype=np.int64), rng.normal(0, 1e3, 1000),
                        rng.normal(0, 1e3, 1000), z, z, z + 5.0, z, z, z,
                        np.zeros(1000, dtype=np.int64), (None,) * 1000)
        reg.update_batch(b)
        if k == 10:
            base = tracemalloc.get_traced_memory()[0]
    churn_end, churn_peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    # growth from the 5-minute mark (the fleet's first reports allocate) to the end
    first = samples[5] if len(samples) > 6 else None
    return {
        "stream_duration_s": duration_s,
        "speed": 100.0,
        "wall_s": round(wall, 2),
        "targets": len(registry),
        "registry_traced_bytes_every_300_s": registry_bytes[::5],
        "all_traced_bytes_every_300_s": samples[::5],
        "all_traced_bytes_last": samples[-1],
        "traced_growth_after_first_5_min_bytes": None if first is None else samples[-1] - first,
        "traced_peak_bytes": peak,
        "churn_100k_mmsi_capacity_4096": {
            "targets": len(reg), "evicted": reg.evicted,
            "traced_bytes_after_10k": base, "traced_bytes_after_100k": churn_end,
            "traced_peak_bytes": churn_peak,
        },
    }


def _against_bare(n: int, wall: list[float], cpu: list[float], bare: list[float],
                  bare_cpu: list[float]) -> dict[str, float]:
    """Rates of one variant [lines/s] and its ratios to bare pyais, pair by pair."""
    return {
        "lines_per_s": round(n / statistics.median(wall)),
        "lines_per_cpu_s": round(n / statistics.median(cpu)),
        "overhead_ratio_median_of_pairs": round(statistics.median(
            o / b for o, b in zip(wall, bare)), 3),
        "cpu_overhead_ratio_median_of_pairs": round(statistics.median(
            o / b for o, b in zip(cpu, bare_cpu)), 3),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller log, 10-minute replay")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    logging.disable(logging.WARNING)  # the log's duplicates would be reported once each
    copies = 10
    log_s = 1800.0 if args.quick else 4 * 3600.0
    t0 = time.perf_counter()
    lines = make_log(log_s, copies)
    gen_s = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        ingest(lines[:2000], Path(tmp) / "warm.sqlite")  # warm-up (imports, numba, caches)
        bare_pyais(lines[:2000])
        ours, nostore, bare, n_reports = [], [], [], 0
        ours_cpu, nostore_cpu, bare_cpu = [], [], []
        slow, slow_cpu = [], []
        for k in range(args.repeats):  # interleaved, so each pair sees the same machine load
            dt, cpu, n_reports = ingest(lines, Path(tmp) / f"run{k}.sqlite")
            ours.append(dt)
            ours_cpu.append(cpu)
            dt, cpu = bare_pyais(lines)
            bare.append(dt)
            bare_cpu.append(cpu)
            dt, cpu, _ = ingest(lines, None)
            nostore.append(dt)
            nostore_cpu.append(cpu)
            dt, cpu, _ = ingest(lines, Path(tmp) / f"slow{k}.sqlite", batch_decode=False)
            slow.append(dt)
            slow_cpu.append(cpu)
            db_bytes = sum(f.stat().st_size for f in Path(tmp).glob(f"run{k}.sqlite*"))
        replay_s = 600.0 if args.quick else 3600.0
        hour = make_log(replay_s, copies, seed=11)
        memory = replay_memory(hour, Path(tmp) / "hour.nmea", replay_s)
    n = len(lines)
    census = AisPipeline(default_scene())
    census.feed_batch(lines)
    lps = n / statistics.median(ours)
    pyais_lps = n / statistics.median(bare)
    print(json.dumps({
        "lines": n,
        "reports": n_reports,
        "vessels": 5 * copies,
        "log_generation_s": round(gen_s, 2),
        "log": {"messages_by_type": {str(k): v for k, v in
                                     sorted(census.stats.messages_by_type.items())},
                "duplicates": census.stats.errors.get("duplicate", 0),
                "other_rejections": census.stats.total_errors
                - census.stats.errors.get("duplicate", 0)},
        "lines_per_s": round(lps),
        "lines_per_s_slowest_run": round(n / max(ours)),
        "pyais_decode_lines_per_s": round(pyais_lps),
        "overhead_ratio": round(pyais_lps / lps, 3),
        "overhead_ratio_median_of_pairs": round(statistics.median(
            o / b for o, b in zip(ours, bare)), 3),
        "overhead_ratio_best_runs": round(min(ours) / min(bare), 3),
        "lines_per_cpu_s": round(n / statistics.median(ours_cpu)),
        "pyais_decode_lines_per_cpu_s": round(n / statistics.median(bare_cpu)),
        "cpu_overhead_ratio": round(statistics.median(ours_cpu) / statistics.median(bare_cpu), 3),
        "cpu_overhead_ratio_median_of_pairs": round(statistics.median(
            o / b for o, b in zip(ours_cpu, bare_cpu)), 3),
        "store_bytes_per_report": round(db_bytes / n_reports, 1),
        "without_store": {**_against_bare(n, nostore, nostore_cpu, bare, bare_cpu),
                          "overhead_ratio_best_runs": round(min(nostore) / min(bare), 3)},
        "pyais_decode_path": _against_bare(n, slow, slow_cpu, bare, bare_cpu),
        "goal": {"lines_per_s": 20000, "overhead_ratio_max": 1.5},
        "repeats": args.repeats,
        "replay_memory": memory,
    }, indent=1))


if __name__ == "__main__":
    main()
