"""Sweeps: scenario files × parameter values × seeds, each cell one headless twin run.

A :class:`SweepSpec` names scenario files (or library names), parameters as dotted paths
into the scenario (``environment.current_speed_m_s``, ``own_ship.controller``,
``targets.0.speed_kn``) with their values, the number of seeds and optionally a
duration. Every cell is validated before anything runs (a bad path or value is refused
with the file, the field and the reason). Cells run through the runtime's
:func:`~asvtwin.twin.runtime.run_scenario` in a local process pool or on Ray; the result
of a cell depends only on its scenario and seed, so both backends give the same rows.

Resumable: each cell writes ``cells/<id>/summary.json`` (and ``run.mcap``) under the
output directory; a rerun loads the finished cells instead of running them again.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import orjson

from asvtwin.errors import MissingExtraError, ScenarioError

__all__ = ["Cell", "SweepSpec", "load_sweep_spec", "parse_param", "rows_of", "run_cells"]


@dataclass(frozen=True)
class Cell:
    """One run of a sweep: a scenario (as validated JSON), its parameter values, a seed."""

    source: str
    scenario_json: str
    params: tuple[tuple[str, Any], ...]
    seed: int
    duration_s: float | None

    @property
    def id(self) -> str:
        """Stable identity (file, parameters, seed, duration): names the cell's directory."""
        key = json.dumps([self.source, list(self.params), self.seed, self.duration_s],
                         default=str)
        return hashlib.sha1(key.encode()).hexdigest()[:12]


def _convert(text: str) -> Any:
    t = text.strip()
    if t.lower() in ("true", "false"):
        return t.lower() == "true"
    if t.lower() in ("null", "none"):
        return None
    for cast in (int, float):
        try:
            return cast(t)
        except ValueError:
            pass
    return t


def parse_param(text: str) -> tuple[str, list[Any]]:
    """``NAME=V1,V2,…`` → (name, values) (numbers, booleans and ``null`` converted).

    >>> parse_param("environment.current_speed_m_s=0,0.5")
    ('environment.current_speed_m_s', [0, 0.5])
    """
    name, sep, vals = text.partition("=")
    if not sep or not name.strip() or not vals.strip():
        raise ScenarioError(f"--param {text!r}: expected NAME=V1,V2,... (e.g. "
                            f"environment.current_speed_m_s=0,0.5)")
    return name.strip(), [_convert(v) for v in vals.split(",")]


def _set(doc: dict[str, Any], path: str, value: Any, label: str) -> None:
    keys = path.split(".")
    node: Any = doc
    for i, k in enumerate(keys):
        last = i == len(keys) - 1
        where = ".".join(keys[: i + 1])
        if isinstance(node, list):
            if not k.isdigit() or int(k) >= len(node):
                raise ScenarioError(f"{label}: parameter {path}: {where} is not an index "
                                    f"of a list of {len(node)} items")
            if last:
                node[int(k)] = value
            else:
                node = node[int(k)]
        elif isinstance(node, dict):
            if k not in node:
                raise ScenarioError(f"{label}: parameter {path}: no field {where!r}; "
                                    f"fields there: {', '.join(sorted(node))}")
            if last:
                node[k] = value
            else:
                node = node[k]
        else:
            raise ScenarioError(f"{label}: parameter {path}: {'.'.join(keys[:i])} is a "
                                f"value, not a section")


@dataclass(frozen=True)
class SweepSpec:
    """What to sweep (see the module docstring)."""

    files: tuple[str, ...]
    params: tuple[tuple[str, tuple[Any, ...]], ...] = ()
    seeds: int = 1
    duration_s: float | None = None
    label: str = "<command line>"

    def cells(self) -> list[Cell]:
        """Every cell, validated (raises ScenarioError naming file, field and reason)."""
        from asvtwin.scenarios import Scenario, load_any

        if not self.files:
            raise ScenarioError(f"{self.label}: no scenario files to sweep")
        if not (isinstance(self.seeds, int) and 1 <= self.seeds <= 100000):
            raise ScenarioError(f"{self.label}: seeds must be an integer in [1, 100000], "
                                f"actually: {self.seeds!r}")
        if self.duration_s is not None and not (math.isfinite(self.duration_s)
                                                and self.duration_s > 0):
            raise ScenarioError(f"{self.label}: duration_s must be > 0 [s], actually: "
                                f"{self.duration_s}")
        out = []
        names = [n for n, _ in self.params]
        for f in self.files:
            base = load_any(f)
            doc = base.model_dump(mode="json")
            for combo in itertools.product(*(v for _, v in self.params)):
                d = copy.deepcopy(doc)
                for name, value in zip(names, combo, strict=True):
                    _set(d, name, value, f"{self.label}: {f}")
                try:
                    sc = Scenario.model_validate(d)
                except Exception as exc:  # pydantic's ValidationError: say which cell
                    first = str(exc).splitlines()
                    raise ScenarioError(
                        f"{self.label}: {f} with {dict(zip(names, combo, strict=True))}: "
                        f"{' '.join(first[1:3]).strip() or first[0]}") from exc
                for k in range(self.seeds):
                    out.append(Cell(str(f), sc.model_dump_json(),
                                    tuple(zip(names, combo, strict=True)), sc.seed + k,
                                    self.duration_s))
        return out


def load_sweep_spec(path: str | Path) -> SweepSpec:
    """A sweep from a YAML file: ``scenarios: [files]``, ``params: {name: [values]}``,
    ``seeds: N``, ``duration_s: S`` (optional). Paths are relative to the file."""
    import yaml

    p = Path(path)
    try:
        doc = yaml.safe_load(p.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ScenarioError(f"{p}: cannot read the sweep file: {exc}") from exc
    if not isinstance(doc, dict):
        raise ScenarioError(f"{p}: a sweep file is a mapping with 'scenarios', 'params', "
                            f"'seeds'")
    extra = set(doc) - {"scenarios", "params", "seeds", "duration_s"}
    if extra:
        raise ScenarioError(f"{p}: field {min(extra)!r} is not allowed; allowed: "
                            f"scenarios, params, seeds, duration_s")
    files = doc.get("scenarios")
    if not isinstance(files, list) or not files or not all(isinstance(f, str) for f in files):
        raise ScenarioError(f"{p}: field 'scenarios' must be a non-empty list of files or "
                            f"library names, actually: {files!r}")
    params = doc.get("params") or {}
    if not isinstance(params, dict) or not all(isinstance(v, list) and v
                                               for v in params.values()):
        raise ScenarioError(f"{p}: field 'params' must map each name to a non-empty list "
                            f"of values, actually: {params!r}")
    seeds = doc.get("seeds", 1)
    if not isinstance(seeds, int) or isinstance(seeds, bool) or seeds < 1:
        raise ScenarioError(f"{p}: field 'seeds' must be an integer >= 1, actually: {seeds!r}")
    resolved = [str(p.parent / f) if (p.parent / f).exists() else f for f in files]
    dur = doc.get("duration_s")
    return SweepSpec(tuple(resolved), tuple((k, tuple(v)) for k, v in params.items()),
                     seeds, None if dur is None else float(dur), label=str(p))


def run_cell(cell: Cell, out_dir: str, psf_backend: str = "auto") -> dict[str, Any]:
    """Run one cell (in any process) and return its summary as a plain dict."""
    from asvtwin.scenarios import Scenario
    from asvtwin.twin.runtime import run_scenario

    d = Path(out_dir) / "cells" / cell.id
    sc = Scenario.model_validate_json(cell.scenario_json)
    s = run_scenario(sc, seed=cell.seed, duration_s=cell.duration_s, out_dir=d,
                     psf_backend=psf_backend).to_dict()
    (d / "cell.json").write_bytes(orjson.dumps({"source": cell.source, "params": cell.params,
                                                "seed": cell.seed}))
    return s


def _done(cell: Cell, out_dir: str) -> dict[str, Any] | None:
    d = Path(out_dir) / "cells" / cell.id
    if (d / "summary.json").exists() and (d / "cell.json").exists():
        out: dict[str, Any] = orjson.loads((d / "summary.json").read_bytes())
        return out
    return None


def run_cells(cells: list[Cell], out_dir: str | Path, *, backend: str = "local",
              workers: int = 2, ray_address: str | None = None, psf_backend: str = "auto",
              progress: Callable[[int, int, int], None] | None = None
              ) -> list[dict[str, Any]]:
    """Run the cells not yet finished under ``out_dir``; return every cell's summary in
    the cells' order. ``backend``: ``"local"`` (a process pool of ``workers``) or
    ``"ray"`` (``ray_address``: an existing cluster's address, or ``"local"`` to start
    one with ``workers`` CPUs). ``progress(done, total, skipped)`` after each cell."""
    out = str(out_dir)
    Path(out).mkdir(parents=True, exist_ok=True)
    results: dict[int, dict[str, Any]] = {}
    todo = []
    for i, c in enumerate(cells):
        r = _done(c, out)
        if r is None:
            todo.append(i)
        else:
            results[i] = r
    skipped = len(results)
    if progress:
        progress(len(results), len(cells), skipped)
    for i, r in _execute(cells, todo, out, backend, workers, ray_address, psf_backend):
        results[i] = r
        if progress:
            progress(len(results), len(cells), skipped)
    return [results[i] for i in range(len(cells))]


def _execute(cells: list[Cell], todo: list[int], out: str, backend: str, workers: int,
             ray_address: str | None, psf_backend: str) -> Iterator[tuple[int, dict[str, Any]]]:
    if not todo:
        return
    if backend == "ray":
        import os

        os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
        try:
            import ray
        except ImportError as exc:
            raise MissingExtraError("ray", "ray") from exc
        started = False
        if not ray.is_initialized():
            if ray_address in (None, "local"):
                ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
            else:
                ray.init(address=ray_address, log_to_driver=False)
            started = True
        try:
            remote = ray.remote(run_cell)
            refs = {remote.remote(cells[i], out, psf_backend): i for i in todo}
            pending = list(refs)
            while pending:
                ready, pending = ray.wait(pending, num_returns=1)
                yield refs[ready[0]], ray.get(ready[0])
        finally:
            if started:
                ray.shutdown()
        return
    if backend != "local":
        raise ScenarioError(f"sweep backend must be 'local' or 'ray', actually: {backend!r}")
    if workers <= 1:
        for i in todo:
            yield i, run_cell(cells[i], out, psf_backend)
        return
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as ex:
        futs = {ex.submit(run_cell, cells[i], out, psf_backend): i for i in todo}
        for fu in as_completed(futs):
            yield futs[fu], fu.result()


def rows_of(cells: list[Cell], summaries: list[dict[str, Any]], out_dir: str | Path
            ) -> list[dict[str, Any]]:
    """One flat row per cell (for Parquet and the report): file, parameters (as
    ``param.NAME``), seed, outcome and the path of its recording."""
    rows = []
    for c, s in zip(cells, summaries, strict=True):
        md = s.get("min_distance_targets_m") or {}
        finite = [v for v in md.values() if v is not None]
        row: dict[str, Any] = {
            "cell": c.id, "source": c.source, "scenario": s.get("scenario"), "seed": c.seed,
            "duration_s": s.get("duration_s"), "collisions": s.get("collisions"),
            "groundings": s.get("groundings"),
            "min_distance_m": min(finite) if finite else None,
            "min_distance_land_m": s.get("min_distance_land_m"),
            "interventions": s.get("interventions"), "filter_calls": s.get("filter_calls"),
            "passed": s.get("passed"), "goal_reached": s.get("goal_reached"),
            "recording": str(Path(out_dir) / "cells" / c.id / "run.mcap"),
        }
        for k, v in c.params:
            row[f"param.{k}"] = v
        rows.append(row)
    return rows
