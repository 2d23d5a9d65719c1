"""The twin: the runtime that joins every capability level, its clock, snapshots,
recording and replay.

The snapshot contract, the clock, the scheduler, the recorder and the replay reader import
light; the runtime (which pulls in the safety filter, the tracker and the observer) is
imported when first used: ``from asvtwin.twin import Twin``.

Examples
--------
>>> from asvtwin.twin import Clock, SCHEMA_ID
>>> Clock("x10").speed, SCHEMA_ID
(10.0, 'asvtwin.snapshot/1')
"""

from __future__ import annotations

import importlib
from typing import Any

from asvtwin.twin.clock import Clock, parse_speed
from asvtwin.twin.recorder import Recorder
from asvtwin.twin.replay import Recording
from asvtwin.twin.scheduler import Scheduler
from asvtwin.twin.snapshot import SCHEMA_ID, Snapshot, decode, encode, json_schema

__all__ = [
    "CONTROLLERS",
    "SCHEMA_ID",
    "Clock",
    "Recorder",
    "Recording",
    "RunSummary",
    "Scheduler",
    "Snapshot",
    "Twin",
    "comparable",
    "decode",
    "encode",
    "json_schema",
    "make_controller",
    "parse_speed",
    "run_scenario",
]

_LAZY = {
    "Twin": "asvtwin.twin.runtime",
    "run_scenario": "asvtwin.twin.runtime",
    "comparable": "asvtwin.twin.runtime",
    "RunSummary": "asvtwin.twin.summary",
    "CONTROLLERS": "asvtwin.twin.controllers",
    "make_controller": "asvtwin.twin.controllers",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'asvtwin.twin' has no attribute {name!r}")
