"""``asvtwin scenario``: check, list, export the schema of, and run scenario files.

- ``asvtwin scenario check FILE...``: validate files (or library names); each problem is
  reported with the file, the line, the field and the allowed range. Exit 0 when every
  file is valid, 2 otherwise.
- ``asvtwin scenario list [--json]``: the scenarios shipped with the package.
- ``asvtwin scenario schema [--out FILE]``: the JSON Schema of a scenario file, for editors
  (e.g. the YAML language server: ``# yaml-language-server: $schema=scenario.schema.json``).
- ``asvtwin scenario run FILE [--json] [--duration S] [--seed N] [--out DIR]
  [--controller NAME]``: run it headless through the twin; exit 0 when every criterion
  passed, 1 when one failed. ``--controller`` replaces the own ship's controller, so one
  scenario compares ``los_psf`` with ``rl_psf`` (docs/rl.md).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

from asvtwin.cli.argtypes import CONTROLLERS, PSF_BACKENDS, positive_float

__all__ = ["register"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("scenario", help="check, list, run scenario files; export their schema",
                       description="Scenario files (YAML): validate, list the library, export "
                                   "the JSON Schema, run one headless.")
    s = p.add_subparsers(title="scenario commands", metavar="COMMAND")

    c = s.add_parser("check", help="validate scenario files (or library names)",
                     description="Validate scenario files against the schema and the scene's "
                                 "coast; report every problem with file, line, field and "
                                 "allowed range.")
    c.add_argument("files", nargs="+", metavar="FILE", help="scenario YAML file or library name")
    c.add_argument("--json", action="store_true", help="print the results as JSON")
    c.set_defaults(func=_check)

    ls = s.add_parser("list", help="the scenarios shipped with the package",
                      description="List the scenario library: name, own ship, targets, "
                                  "duration and the expected outcome.")
    ls.add_argument("--json", action="store_true", help="print the list as JSON")
    ls.set_defaults(func=_list)

    sc = s.add_parser("schema", help="print the JSON Schema of a scenario file",
                      description="The JSON Schema (draft 2020-12) of a scenario file.")
    sc.add_argument("--out", type=Path, default=None, metavar="FILE",
                    help="write it to FILE instead of stdout")
    sc.set_defaults(func=_schema)

    r = s.add_parser("run", help="run a scenario headless and print its summary",
                     description="Run a scenario through the twin (world, AIS, LiDAR, tracker, "
                                 "observer, controller, safety filter) as fast as possible; "
                                 "print the summary and check the scenario's criteria.")
    r.add_argument("file", metavar="FILE", help="scenario YAML file or library name")
    r.add_argument("--json", action="store_true", help="print the summary as JSON")
    r.add_argument("--duration", type=positive_float, default=None, metavar="S",
                   help="simulated seconds (default: the scenario's duration_s)")
    r.add_argument("--seed", type=int, default=None, metavar="N",
                   help="seed (default: the scenario's seed)")
    r.add_argument("--out", type=Path, default=None, metavar="DIR",
                   help="write run.mcap and summary.json into DIR (default: nothing written)")
    r.add_argument("--no-record", action="store_true", help="with --out: no run.mcap")
    r.add_argument("--psf-backend", default="auto", choices=PSF_BACKENDS,
                   help="safety filter backend (default: %(default)s)")
    r.add_argument("--controller", default=None, choices=CONTROLLERS,
                   help="replace the own ship's controller (default: the scenario's)")
    r.set_defaults(func=_run)
    p.set_defaults(func=lambda args: (p.print_help(sys.stderr), 2)[1])


def _overview(s: Any) -> dict[str, Any]:
    """Facts of a scenario worth a line: own ship, route length and time, targets."""
    import numpy as np

    from asvtwin.scenarios import resolve_scene
    from asvtwin.units import KNOT_M_S

    frame = resolve_scene(s).frame
    own = s.own_ship
    pts = np.array([p.to_ned(frame) for p in [own.start, *own.route]])
    route_m = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()) if len(pts) > 1 else 0.0
    return {
        "name": s.name,
        "vessel": own.vessel,
        "controller": own.controller,
        "targets": len(s.targets),
        "route_m": round(route_m, 1),
        "route_time_s": round(route_m / (own.cruise_speed_kn * KNOT_M_S), 1),
        "duration_s": s.duration_s,
        "seed": s.seed,
        "ais": s.ais.mode,
        "weather": s.weather.mode,
        "description": " ".join(s.description.split()),
    }


def _check(args: argparse.Namespace) -> int:
    from asvtwin.errors import ScenarioError
    from asvtwin.scenarios import load_any

    results = []
    for ref in args.files:
        try:
            s = load_any(ref)
        except ScenarioError as exc:
            results.append({"file": ref, "ok": False, "error": str(exc)})
            if not args.json:
                print(f"asvtwin scenario check: {exc}", file=sys.stderr)
            continue
        info = _overview(s)
        results.append({"file": ref, "ok": True, **info})
        if not args.json:
            spare = info["duration_s"] - info["route_time_s"]
            print(f"{ref}: ok: {info['name']}, {info['vessel']} under {info['controller']}, "
                  f"{info['targets']} target(s), route {info['route_m']:.0f} m "
                  f"({info['route_time_s']:.0f} s at cruise speed, run {info['duration_s']:g} s"
                  f"{', route cannot be completed' if spare < 0 and s.own_ship.route else ''})")
    if args.json:
        print(json.dumps(results, indent=2))
    return 0 if all(r["ok"] for r in results) else 2


def _list(args: argparse.Namespace) -> int:
    from asvtwin.scenarios import library_names, load_library

    rows = [_overview(load_library(n)) for n in library_names()]
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    width = max(len(r["name"]) for r in rows)
    for r in rows:
        print(f"{r['name']:<{width}}  {r['vessel']:<21} {r['controller']:<8} "
              f"{r['targets']} target(s)  {r['duration_s']:>6g} s")
        print(f"{'':<{width}}  {r['description']}")
    return 0


def _schema(args: argparse.Namespace) -> int:
    from asvtwin.scenarios import scenario_json_schema

    text = json.dumps(scenario_json_schema(), indent=2) + "\n"
    if args.out is None:
        sys.stdout.write(text)
    else:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text, encoding="utf-8")
        print(f"wrote {args.out}", file=sys.stderr)
    return 0


class _Progress:
    """Simulated time on stderr every 10 % (only when stderr is a terminal)."""

    def __init__(self) -> None:
        self.last = -1
        self.tty = sys.stderr.isatty()

    def __call__(self, t_s: float, end_s: float) -> None:
        if not self.tty or not (end_s > 0 and math.isfinite(end_s)):
            return
        tenth = int(10 * t_s / end_s)
        if tenth > self.last:
            self.last = tenth
            print(f"\r  {t_s:7.0f} / {end_s:.0f} s simulated", end="", file=sys.stderr,
                  flush=True)

    def close(self) -> None:
        if self.tty and self.last >= 0:
            print(file=sys.stderr)


def _run(args: argparse.Namespace) -> int:
    from asvtwin.scenarios import load_any

    scenario = load_any(args.file)
    if args.controller is not None:
        scenario = scenario.with_controller(args.controller)
    from asvtwin.cli.run import native_stdout_to_stderr
    from asvtwin.twin.runtime import run_scenario  # heavy: only once the file is valid

    seed = scenario.seed if args.seed is None else args.seed
    progress = _Progress()
    # --json: native solver messages (acados) go to stderr, only the JSON to stdout
    with native_stdout_to_stderr(args.json) as stdout:
        try:
            summary = run_scenario(scenario, seed=seed, duration_s=args.duration,
                                   out_dir=args.out, record=not args.no_record,
                                   psf_backend=args.psf_backend, progress=progress)
        finally:
            progress.close()
        if args.json:
            print(json.dumps(summary.to_dict(), indent=2), file=stdout, flush=True)
    if not args.json:
        print(summary.text())
    return 0 if summary.passed else 1
