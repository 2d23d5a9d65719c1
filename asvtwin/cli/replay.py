"""``asvtwin replay FILE``: a recorded run back.

``--headless`` prints the run's summary (and how much of the file is readable, when it was
cut short by a full disk); without it the recording is served to the browser viewer
(``asvtwin.server``) with pause, speed, step and seek. ``--verify`` re-runs the recording
from its raw inputs and seed and checks that every snapshot comes out the same.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from asvtwin.cli.argtypes import positive_int

__all__ = ["register"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "replay",
        help="a recorded run: print its summary (--headless) or serve it to the viewer",
        description="Open a recording written by 'asvtwin run' (MCAP). --headless prints "
                    "the summary; otherwise the recording is served to the browser viewer.",
    )
    p.add_argument("file", type=Path, metavar="FILE", help="the .mcap recording")
    p.add_argument("--headless", action="store_true", help="print the summary, no viewer")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.add_argument("--verify", action="store_true",
                   help="re-run from the recorded raw inputs and seed and compare every "
                        "snapshot (exit 1 on a difference)")
    p.add_argument("--port", type=positive_int, default=8765, metavar="P",
                   help="viewer port on 127.0.0.1 (default: %(default)s)")
    p.set_defaults(func=replay)


def replay(args: argparse.Namespace) -> int:
    from asvtwin.twin import Recording

    rec = Recording(args.file)
    if not args.headless and not args.verify:
        try:
            from asvtwin.server import serve
        except ImportError as exc:
            print(f"asvtwin replay: the viewer server (asvtwin.server) is not available "
                  f"({exc}); use --headless", file=sys.stderr)
            return 2
        serve(rec, port=args.port)
        return 0
    info: dict[str, Any] = {"file": str(rec.path), "scenario": (rec.scenario or {}).get("name"),
            "seed": rec.seed, "duration_s": rec.duration_s, "truncated": rec.truncated,
            "damage": rec.damage, "summary": rec.summary}
    code = 0
    if args.verify:
        from asvtwin.twin.verify import verify_recording

        diff = verify_recording(rec.path)
        info["verify"] = diff
        code = 0 if diff["identical"] else 1
    if args.json:
        print(json.dumps(info, indent=2))
        return code
    print(f"{rec.path}: scenario {info['scenario']!r}, seed {rec.seed}, "
          f"{rec.duration_s:.1f} s of snapshots")
    if rec.truncated:
        print(f"the file was cut short ({rec.damage}); readable up to t = {rec.duration_s:.1f} s")
    s = rec.summary
    if s is None:
        print("no summary in the file (the run did not finish writing it)")
    else:
        from asvtwin.twin.summary import RunSummary

        fields = {k: v for k, v in s.items() if k in RunSummary.__dataclass_fields__}
        for k in ("min_distance_land_m", "max_cte_m", "realtime_factor"):
            if fields.get(k) is None:
                fields[k] = float("nan")
        print(RunSummary(**fields).text())
    if args.verify:
        d = info["verify"]
        print(f"verify: {d['compared']} snapshots re-run from the raw inputs; "
              + ("identical" if d["identical"] else f"first difference at t = {d['first_t_s']} s "
                 f"in {d['first_field']}"))
    return code
