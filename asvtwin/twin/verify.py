"""Checking a recording by re-running it from its raw inputs and seed.

The twin is deterministic given its scenario, seed and inputs: the NMEA lines it received
and the operator's commands, both recorded with the tick they arrived at. Re-running
(:meth:`asvtwin.twin.runtime.Twin.from_recording`) must give the same snapshots, field by
field, except the wall-time measurements (component timings, solve times, the clock),
which :func:`asvtwin.twin.runtime.comparable` leaves out.
"""

from __future__ import annotations

import os
from typing import Any

import orjson

from asvtwin.twin.replay import SNAPSHOT_TOPIC, Recording
from asvtwin.twin.snapshot import Snapshot

__all__ = ["first_difference", "verify_recording"]


def first_difference(a: Any, b: Any, path: str = "") -> str | None:
    """The path of the first differing field of two decoded JSON values (None: equal)."""
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                return f"{path}.{k}"
            d = first_difference(a[k], b[k], f"{path}.{k}")
            if d is not None:
                return d
        return None
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return f"{path} (length {len(a)} vs {len(b)})"
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            d = first_difference(x, y, f"{path}[{i}]")
            if d is not None:
                return d
        return None
    return None if a == b else path


def verify_recording(path: str | os.PathLike[str], **twin_kwargs: Any) -> dict[str, Any]:
    """Re-run ``path`` from its raw inputs and compare every recorded snapshot.

    Returns ``{"compared", "identical", "first_t_s", "first_field"}``.
    """
    from asvtwin.twin.runtime import Twin, comparable

    rec = Recording(path)
    recorded = {round(t, 6): data for t, data in rec.iter_messages(topic=SNAPSHOT_TOPIC)}
    twin = Twin.from_recording(path, **twin_kwargs)
    fresh: dict[float, bytes] = {}

    def keep(snap: Snapshot, data: bytes) -> None:
        fresh[round(snap.t_s, 6)] = data

    twin.on_snapshot = keep
    twin.run(rec.duration_s + twin.dt_s)
    compared = 0
    for t in sorted(recorded):
        if t not in fresh:
            return {"compared": compared, "identical": False, "first_t_s": t,
                    "first_field": "(no snapshot at this time in the re-run)"}
        a, b = comparable(recorded[t]), comparable(fresh[t])
        d = first_difference(a, b)
        compared += 1
        if d is not None:
            return {"compared": compared, "identical": False, "first_t_s": t,
                    "first_field": d, "recorded": _at(a, d), "rerun": _at(b, d)}
    return {"compared": compared, "identical": compared > 0, "first_t_s": None,
            "first_field": None}


def _at(d: Any, path: str) -> Any:
    """The value at a path from :func:`first_difference` (best effort, for messages)."""
    try:
        cur = d
        for part in path.replace("[", ".[").split(".")[1:]:
            if part.startswith("["):
                cur = cur[int(part.strip("[]").split(" ")[0])]
            else:
                cur = cur[part.split(" ")[0]]
        return orjson.loads(orjson.dumps(cur))
    except (KeyError, IndexError, ValueError, TypeError):
        return None
