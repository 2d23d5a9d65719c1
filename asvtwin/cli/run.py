"""``asvtwin run``: the twin's main job.

Runs a scenario (the embedded default: the Trondheim Fjord, synthetic traffic through the
NMEA path, the weather fixture, the full-scale own ship under ``rl_psf``, the shipped
policy through the safety filter) with every component on. With ``--headless`` it runs
to the end and writes ``run.mcap`` (the recording) and ``summary.json`` into ``--out``,
printing the summary; without it, it serves the live twin to the browser viewer
(``asvtwin.server``) until Ctrl-C.

Exit codes: 0 the run met its criteria, 1 it did not, 2 bad input.
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import io
import json
import logging
import os
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any, TextIO

from asvtwin.cli.argtypes import PSF_BACKENDS, out_dir, positive_float, positive_int

__all__ = ["native_stdout_to_stderr", "register"]

_log = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "run",
        help="run the digital twin (default scenario: Trondheim Fjord, rl_psf); "
             "--headless writes a recording and a summary",
        description="Run the digital twin of a scenario: world, AIS through the NMEA "
                    "decoder, LiDAR, tracker, observer, controller and safety filter. "
                    "Headless: run to the end, write <out>/run.mcap and <out>/summary.json "
                    "and print the summary. Otherwise: serve the live twin to the browser "
                    "viewer until Ctrl-C.",
    )
    p.add_argument("--scenario", type=Path, default=None, metavar="FILE",
                   help="scenario YAML file, or a library name (default: the embedded "
                        "default scenario)")
    p.add_argument("--headless", action="store_true",
                   help="no viewer: run to the end, record and print the summary")
    p.add_argument("--duration", type=positive_float, default=None, metavar="S",
                   help="simulated seconds to run (default: the scenario's duration)")
    p.add_argument("--speed", default=None, metavar="X|max",
                   help="simulated seconds per wall second, or 'max' (default: max when "
                        "headless, 1 with the viewer)")
    p.add_argument("--seed", type=int, default=None, help="seed (default: the scenario's)")
    p.add_argument("--out", type=Path, default=out_dir("run"), metavar="DIR",
                   help="folder of run.mcap and summary.json (default: %(default)s)")
    p.add_argument("--no-record", action="store_true", help="do not write run.mcap")
    p.add_argument("--port", type=positive_int, default=8765, metavar="P",
                   help="viewer port on 127.0.0.1 (default: %(default)s)")
    p.add_argument("--psf-backend", default="auto", choices=PSF_BACKENDS,
                   help="safety filter backend (default: %(default)s)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=run)


def _flush_c_stdio() -> None:
    """Flush the C library's stdio buffers (text a native solver printf'd but not yet
    written): otherwise a block-buffered stdout writes it at exit, into the real stdout."""
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):  # pragma: no cover - no C library to reach
        pass


@contextlib.contextmanager
def native_stdout_to_stderr(enabled: bool = True) -> Iterator[TextIO]:
    """Keep stdout clean for machine-readable output (``--json``).

    Native libraries print on file descriptor 1 directly (acados' HPIPM: "QP solver
    returned error status 3"), past ``sys.stdout``. Inside the block fd 1 points at stderr,
    so everything printed there, native or Python, lands on stderr; the yielded text stream
    writes to the original stdout. Without ``enabled`` it yields ``sys.stdout`` and changes
    nothing. The descriptors are restored (and the C buffers flushed) on exit, also on
    errors.
    """
    if not enabled:
        yield sys.stdout
        return
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, io.UnsupportedOperation):
        # stdout is not a file (captured by a caller): native output cannot reach it
        yield sys.stdout
        return
    sys.stdout.flush()
    _flush_c_stdio()
    saved = os.dup(fd)
    real = os.fdopen(os.dup(saved), "w", encoding="utf-8", closefd=True)
    os.dup2(sys.stderr.fileno(), fd)
    try:
        yield real
    finally:
        sys.stdout.flush()
        _flush_c_stdio()
        real.flush()
        os.dup2(saved, fd)
        os.close(saved)
        real.close()


def load_scenario_arg(path: Path | None) -> Any:
    """The scenario named on the command line: a file, a library name, or the default."""
    from asvtwin.scenarios import default_scenario, load_any

    return default_scenario() if path is None else load_any(path)


def run(args: argparse.Namespace) -> int:
    from asvtwin.twin import Clock, Twin

    scenario = load_scenario_arg(args.scenario)
    speed = args.speed if args.speed is not None else ("max" if args.headless else "1")
    clock = Clock(speed, start_time_utc=scenario.start_time_utc)
    out: Path = args.out
    record = None if args.no_record else out / "run.mcap"
    if not args.headless:
        try:
            from asvtwin.server import serve
        except ImportError as exc:
            print(f"asvtwin run: the viewer server (asvtwin.server) is not available "
                  f"({exc}); use --headless", file=sys.stderr)
            return 2
        twin = Twin(scenario, seed=args.seed, clock=clock, record_path=record,
                    psf_backend=args.psf_backend)
        if record is not None:
            print(f"recording to {record}", flush=True)
        try:
            serve(twin, port=args.port)
        finally:
            twin.stop()
            twin.close()
        return 0
    with native_stdout_to_stderr(args.json) as stdout:
        summary = _run_headless(args, scenario, clock, record, speed)
        d = summary.to_dict()
        out.mkdir(parents=True, exist_ok=True)
        (out / "summary.json").write_text(json.dumps(d, indent=2) + "\n", encoding="utf-8")
        if args.json:
            print(json.dumps(d, indent=2), file=stdout, flush=True)
    if not args.json:
        print(summary.text())
        print(f"wrote {out / 'summary.json'}" + ("" if record is None else f" and {record}"))
    return 0 if summary.passed else 1


def _run_headless(args: argparse.Namespace, scenario: Any, clock: Any, record: Path | None,
                  speed: str) -> Any:
    from asvtwin.twin import Twin

    twin = Twin(scenario, seed=args.seed, clock=clock, record_path=record,
                psf_backend=args.psf_backend)
    total = float(args.duration if args.duration is not None else scenario.duration_s)

    def progress(t_s: float, end_s: float) -> None:
        print(f"  t = {t_s:7.1f} / {end_s:.0f} s", file=sys.stderr, flush=True)

    print(f"running {scenario.name!r} for {total:g} s (seed {twin.seed}, speed {speed}, "
          f"controller {scenario.own_ship.controller})", file=sys.stderr, flush=True)
    return twin.run(total, progress=progress)
