"""``asvtwin sweep FILES… --param NAME=V1,V2… --seeds N``: scenario × parameter × seed grids.

Each cell is one headless twin run (``asvtwin run``'s); cells run in a local process pool
(``--workers``, default 2) or on Ray (``--ray ADDRESS`` of an existing cluster, or
``--ray local``), with the same results for the same seeds. Finished cells are kept under
``--out`` and not rerun when the sweep is started again (resumable). Results go to
``results.parquet`` and ``report.html`` (collision rate and closest-approach distribution
per parameter, the worst runs linked to their recordings).

``--spec FILE`` reads the sweep from YAML instead: ``scenarios: [...]``,
``params: {NAME: [values]}``, ``seeds: N``, ``duration_s: S``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from asvtwin.cli.argtypes import out_dir, positive_float, positive_int

__all__ = ["register"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "sweep", help="run scenario × parameter × seed grids (local pool or Ray)",
        description=__doc__.split("\n\n", 1)[1] if __doc__ else None,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("files", nargs="*", metavar="FILE",
                   help="scenario files or library names")
    p.add_argument("--spec", type=Path, default=None, metavar="FILE",
                   help="read the sweep from a YAML file")
    p.add_argument("--param", action="append", default=[], metavar="NAME=V1,V2",
                   help="a scenario field (dotted path, e.g. environment.current_speed_m_s) "
                        "and its values (repeatable)")
    p.add_argument("--seeds", type=positive_int, default=1, metavar="N",
                   help="seeds per cell: the scenario's seed, +1, ... (default: 1)")
    p.add_argument("--duration", type=positive_float, default=None, metavar="S",
                   help="simulated seconds per run (default: each scenario's)")
    p.add_argument("--workers", type=positive_int, default=2, metavar="K",
                   help="local processes or Ray CPUs (default: %(default)s)")
    p.add_argument("--ray", default=None, metavar="ADDRESS",
                   help="run on Ray: an existing cluster's address, or 'local'")
    p.add_argument("--out", type=Path, default=out_dir("sweep"), metavar="DIR",
                   help="output directory (default: %(default)s)")
    p.set_defaults(func=sweep)


def sweep(args: argparse.Namespace) -> int:
    from asvtwin.cli import EXIT_OK
    from asvtwin.errors import ScenarioError
    from asvtwin.whatif.report import write_parquet, write_report
    from asvtwin.whatif.sweep import SweepSpec, load_sweep_spec, parse_param, rows_of, run_cells

    if args.spec is not None:
        if args.files or args.param:
            raise ScenarioError("give either --spec FILE or FILES with --param, not both")
        spec = load_sweep_spec(args.spec)
    else:
        params = tuple((n, tuple(v)) for n, v in (parse_param(t) for t in args.param))
        spec = SweepSpec(tuple(args.files), params, args.seeds, args.duration)
    cells = spec.cells()
    tty = sys.stderr.isatty()

    def progress(done: int, total: int, skipped: int) -> None:
        end = "\n" if (done == total or not tty) else ""
        print(f"\rsweep: {done}/{total} runs done ({skipped} from a previous run)",
              end=end, file=sys.stderr, flush=True)

    summaries = run_cells(cells, args.out, backend="ray" if args.ray else "local",
                          workers=args.workers, ray_address=args.ray, progress=progress)
    rows = rows_of(cells, summaries, args.out)
    pq = write_parquet(rows, args.out / "results.parquet")
    html = write_report(rows, args.out / "report.html")
    bad = sum(1 for r in rows if (r["collisions"] or 0) > 0)
    print(f"{len(rows)} runs, {bad} with a collision; {pq}, {html}")
    return EXIT_OK
