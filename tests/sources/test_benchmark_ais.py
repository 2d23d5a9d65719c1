"""The AIS benchmark's two sides run and do the same work: the ingest (pipeline, registry,
store) with and without the batch decoder accepts the same reports, and bare pyais decodes
every message of the same lines (a short log; the timing itself is the benchmark's job)."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

from pyais.stream import IterMessages

from asvtwin.sources.ais import AisPipeline
from asvtwin.sources.history import SqliteHistory

_PATH = Path(__file__).parents[2] / "benchmarks" / "ais.py"


def _bench() -> ModuleType:
    spec = importlib.util.spec_from_file_location("bench_ais", _PATH)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_both_sides_of_the_benchmark_handle_the_same_messages(tmp_path) -> None:
    b = _bench()
    lines = b.make_log(120.0, 1)
    wall, cpu, n = b.ingest(lines, tmp_path / "a.sqlite")
    assert wall > 0 and cpu > 0 and n > 50
    assert b.ingest(lines, tmp_path / "b.sqlite", batch_decode=False)[2] == n
    store = SqliteHistory(tmp_path / "a.sqlite", readonly=True)
    assert len(store.query_reports(AisPipeline().scene.frame)) == n  # all stored
    store.close()
    p = AisPipeline()
    p.feed_batch(lines)
    # bare pyais decodes every assembled message, the duplicate receptions included
    decoded = sum(1 for _ in IterMessages(lines))
    assert decoded == sum(p.stats.messages_by_type.values())
    assert p.stats.errors.get("duplicate", 0) > 0
    assert b.bare_pyais(lines)[0] > 0
