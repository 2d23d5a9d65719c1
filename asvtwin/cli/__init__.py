"""The ``asvtwin`` command.

Each area of the twin contributes its sub-commands from a module of this package
(``asvtwin/cli/<area>.py``) that defines ``register(subparsers) -> None``; each
sub-command sets ``func`` (a callable taking the parsed namespace and returning an exit
code) with ``parser.set_defaults(func=...)``. Heavy imports belong inside the handlers, so
``asvtwin --help`` stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence

from asvtwin import __version__

__all__ = ["build_parser", "main"]

#: Modules of this package that register sub-commands, in help order.
COMMAND_MODULES = (
    "run", "scenario", "replay", "sim", "ais", "weather", "figures", "psf", "observer",
    "train", "study", "whatif", "sweep",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="asvtwin",
        description="Digital twin of an autonomous surface vessel in the Trondheim Fjord.",
    )
    parser.add_argument("--version", action="version", version=f"asvtwin {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="more log output (-v info, -vv debug)")
    sub = parser.add_subparsers(title="commands", metavar="COMMAND")
    for name in COMMAND_MODULES:
        try:
            mod = importlib.import_module(f"asvtwin.cli.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"asvtwin.cli.{name}":
                continue  # that area has no commands yet
            raise
        mod.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=[logging.WARNING, logging.INFO, logging.DEBUG][min(args.verbose, 2)],
        format="%(levelname)s %(name)s: %(message)s",
    )
    func = getattr(args, "func", None)
    if func is None:
        parser.print_help()
        return 2
    return int(func(args) or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
