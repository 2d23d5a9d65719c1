"""The ``asvtwin`` command.

Each area of the twin contributes its sub-commands from a module of this package
(``asvtwin/cli/<area>.py``) that defines ``register(subparsers) -> None``; each
sub-command sets ``func`` (a callable taking the parsed namespace and returning an exit
code) with ``parser.set_defaults(func=...)``. Heavy imports belong inside the handlers, so
``asvtwin --help`` stays fast.

Handlers raise :class:`~asvtwin.errors.AsvTwinError` (or let an ``OSError`` through) for
bad input; :func:`main` is the one place that turns those into a one-line message on
stderr and an exit code. Exit codes (documented in docs/cli.md):

===  =====================================================================
 0   success
 1   the command ran, and what it checked failed (a run's criteria, a study's goal)
 2   bad input: usage, an argument out of range, a bad file, an I/O error
130  interrupted (Ctrl-C)
141  the reader of stdout went away (``asvtwin ... --json | head``); nothing printed
===  =====================================================================
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import re
import sys
import traceback
from collections.abc import Sequence

from asvtwin import __version__
from asvtwin.errors import AsvTwinError

__all__ = [
    "EXIT_BROKEN_PIPE",
    "EXIT_CHECK_FAILED",
    "EXIT_ERROR",
    "EXIT_INTERRUPTED",
    "EXIT_OK",
    "build_parser",
    "main",
]

#: Exit codes of the ``asvtwin`` command (one convention for every sub-command).
EXIT_OK = 0
EXIT_CHECK_FAILED = 1
EXIT_ERROR = 2
EXIT_INTERRUPTED = 130
EXIT_BROKEN_PIPE = 141

#: Modules of this package that register sub-commands, in help order.
COMMAND_MODULES = (
    "run", "scenario", "replay", "sim", "ais", "weather", "figures", "psf", "observer",
    "train", "study", "whatif", "sweep",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="asvtwin",
        description="Digital twin of an autonomous surface vessel in the Trondheim Fjord.",
        epilog="Exit codes: 0 success, 1 a checked criterion failed, 2 bad input or I/O "
               "error (one line on stderr), 130 interrupted.",
    )
    parser.add_argument("--version", action="version", version=f"asvtwin {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="more log output (-v info, -vv debug; -v also shows the "
                             "traceback of an error)")
    sub = parser.add_subparsers(title="commands", metavar="COMMAND")
    for name in COMMAND_MODULES:
        try:
            mod = importlib.import_module(f"asvtwin.cli.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"asvtwin.cli.{name}":
                continue  # that area has no commands yet
            raise
        mod.register(sub)
    _add_verbose_everywhere(parser)
    return parser


_REST_ROLE = re.compile(r":(?:func|class|mod|meth|attr|data|exc):`~?([^`]+)`")


def _plain(text: str | None) -> str | None:
    """Help text for a terminal: reST roles and double backticks removed."""
    if not text:
        return text
    return _REST_ROLE.sub(r"\1", text).replace("``", "'")


def _add_verbose_everywhere(parser: argparse.ArgumentParser) -> None:
    """Accept ``-v`` after the sub-command too (``asvtwin sim -v``), record each
    sub-command's name for error messages, and strip reST markup from the help texts.

    The sub-parsers' ``-v`` has no default (``SUPPRESS``), so it never resets a ``-v``
    given before the sub-command."""
    parser.description = _plain(parser.description)
    for action in parser._actions:
        action.help = _plain(action.help)
        if not isinstance(action, argparse._SubParsersAction):
            continue
        seen: set[int] = set()
        for sub in action.choices.values():
            if id(sub) in seen:  # aliases share one parser
                continue
            seen.add(id(sub))
            free = [s for s in ("-v", "--verbose") if s not in sub._option_string_actions]
            if len(free) == 2:  # a command's own -v or --verbose wins
                sub.add_argument(*free, action="count", default=argparse.SUPPRESS,
                                 help="more log output (-v info, -vv debug)")
            sub.set_defaults(_command=sub.prog.removeprefix("asvtwin").strip())
            _add_verbose_everywhere(sub)


def _one_line(exc: BaseException) -> str:
    """The exception's message on one line (multi-line messages joined with '; ')."""
    text = str(exc).strip() or type(exc).__name__
    if isinstance(exc, OSError) and exc.filename is not None and exc.strerror:
        text = f"{exc.strerror}: {exc.filename}"
        if exc.filename2 is not None:
            text += f" -> {exc.filename2}"
    return "; ".join(line.strip() for line in text.splitlines() if line.strip())


def _hint(exc: BaseException, command: str) -> str:
    """What to do next: the error's own ``hint`` attribute when it has one."""
    hint = getattr(exc, "hint", None)
    if hint:
        return str(hint)
    if isinstance(exc, FileExistsError):
        return "choose another path, or move the file that is in the way"
    if isinstance(exc, (FileNotFoundError, NotADirectoryError, IsADirectoryError)):
        return "check the path"
    if isinstance(exc, PermissionError):
        return "check the permissions of the path"
    where = f"'asvtwin {command} --help'" if command else "'asvtwin --help'"
    return f"see {where}; -v shows the traceback"


def _silence_stdout() -> None:
    """Point stdout at /dev/null so the interpreter's final flush cannot raise again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):  # stdout is not a real file (pytest capture)
        pass


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command; return its exit code (see the module docstring).

    The one error boundary: an :class:`~asvtwin.errors.AsvTwinError` (bad input the
    package recognised) or an ``OSError`` (a file or a socket) prints one line on stderr,
    ``asvtwin <command>: error: <what> (hint: <what to do>)``, and returns 2; with ``-v``
    the traceback follows. A closed pipe (``asvtwin ... --json | head``) ends quietly.
    Anything else is a bug and keeps its traceback.
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=[logging.WARNING, logging.INFO, logging.DEBUG][min(args.verbose, 2)],
        format="%(levelname)s %(name)s: %(message)s",
    )
    func = getattr(args, "func", None)
    if func is None:
        parser.print_help(sys.stderr)
        return EXIT_ERROR
    command = getattr(args, "_command", "")
    prefix = f"asvtwin {command}" if command else "asvtwin"
    from asvtwin.cli.progress import compile_notice

    try:
        with compile_notice():
            return int(func(args) or 0)
    except BrokenPipeError:
        _silence_stdout()
        return EXIT_BROKEN_PIPE
    except KeyboardInterrupt:
        print(f"{prefix}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except (AsvTwinError, OSError) as exc:
        print(f"{prefix}: error: {_one_line(exc)} (hint: {_hint(exc, command)})",
              file=sys.stderr)
        if args.verbose:
            traceback.print_exception(exc, file=sys.stderr)
        return EXIT_ERROR


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
