"""``asvtwin observer``: the diagnostic twin's validation report."""

from __future__ import annotations

import argparse
from typing import Any

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
    r.add_argument("--out", default="observer_report", metavar="DIR",
                   help="output directory (default: %(default)s)")
    r.add_argument("--vessel", action="append", metavar="NAME",
                   help="vessel parameter set (repeatable; default: cybership2 and "
                   "cybership2_fullscale)")
    r.add_argument("--seed", type=int, default=1, help="seed of the observer runs")
    r.add_argument("--no-faults", action="store_true", help="skip the fault suite")
    r.add_argument("--fault-free-hours", type=float, default=10.0, metavar="H",
                   help="length of the fault-free runs for the false-alarm rate")
    r.set_defaults(func=_report)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])


def _report(args: argparse.Namespace) -> int:
    from asvtwin.errors import AsvTwinError
    from asvtwin.observer.report import write_report

    vessels = args.vessel or ["cybership2", "cybership2_fullscale"]
    try:
        paths = write_report(args.out, vessels, seed=args.seed, faults=not args.no_faults,
                             fault_free_hours=args.fault_free_hours)
    except AsvTwinError as exc:
        print(f"error: {exc}")
        return 2
    print(paths["md"].read_text())
    for kind, path in paths.items():
        print(f"wrote {kind}: {path}")
    return 0
