"""``asvtwin figures <area>``: reproduce the paper's figures as PNG files.

Areas register here; each writes its PNGs into ``--out`` (default ``out/figures/<area>``).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from asvtwin.cli.argtypes import out_dir

__all__ = ["register"]


def _tracking(args: argparse.Namespace) -> int:
    from asvtwin.plots.tracking import make_tracking_figures

    out = Path(args.out) if args.out else out_dir("figures") / "tracking"
    for path in make_tracking_figures(out, seed=args.seed):
        print(path)
    return 0


def register(subparsers: Any) -> None:
    """Add ``figures`` and its per-area sub-commands."""
    parser = subparsers.add_parser("figures", help="reproduce the paper's figures as PNG files",
                                   description="Reproduce the paper's figures as PNG files.")
    areas = parser.add_subparsers(title="areas", metavar="AREA")
    parser.set_defaults(func=lambda _args: (parser.print_help(), 2)[1])
    tr = areas.add_parser("tracking", help="ellipse fits, multi-target LiDAR, prediction cone, near-coast scene",
                          description="Rectangle fit without/with noise, multi-target ellipses over LiDAR points, "
                                      "a predicted path with its widening 2-sigma cone, and a near-coast scene.")
    tr.add_argument("--out", metavar="DIR", default=None, help="output directory (default: out/figures/tracking)")
    tr.add_argument("--seed", type=int, default=0, help="random seed of the simulated scenes (default: 0)")
    tr.set_defaults(func=_tracking)
