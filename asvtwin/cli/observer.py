"""``asvtwin observer``: the diagnostic twin's validation report."""

from __future__ import annotations

import argparse
from typing import Any

from asvtwin.cli.argtypes import out_dir, positive_float

__all__ = ["register"]


def register(subparsers: Any) -> None:
    """Add ``observer report`` to the ``asvtwin`` command."""
    p = subparsers.add_parser("observer", help="disturbance observer and fault diagnosis",
                              description="Disturbance observer and actuator fault "
                              "diagnosis (capability level 2).")
    sub = p.add_subparsers(title="observer commands", metavar="COMMAND")
    r = sub.add_parser(
        "report", help="validate the observer and the fault detector; write table + plot",
        description="Run the seeded validation (step, ramp and environment disturbances, "
        "with and without sensor noise; the 50 % thrust-loss fault suite) and write "
        "observer_report.md/.json/.png.")
    r.add_argument("--out", default=str(out_dir("observer")), metavar="DIR",
                   help="output directory (default: %(default)s)")
    r.add_argument("--vessel", action="append", choices=("cybership2",
                   "cybership2_full_scale"),
                   help="vessel parameter set (repeatable; default: both)")
    r.add_argument("--seed", type=int, default=1, help="seed of the observer runs")
    r.add_argument("--no-faults", action="store_true", help="skip the fault suite")
    r.add_argument("--fault-free-hours", type=positive_float, default=10.0, metavar="H",
                   help="length of the fault-free runs for the false-alarm rate [h]")
    r.set_defaults(func=_report)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])


def _report(args: argparse.Namespace) -> int:
    from asvtwin.observer.report import write_report

    vessels = args.vessel or ["cybership2", "cybership2_full_scale"]
    paths = write_report(args.out, vessels, seed=args.seed, faults=not args.no_faults,
                         fault_free_hours=args.fault_free_hours)
    print(paths["md"].read_text())
    for kind, path in paths.items():
        print(f"wrote {kind}: {path}")
    return 0
