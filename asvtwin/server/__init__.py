"""The local server: snapshots over a WebSocket, controls over REST, the offline viewer.

``serve(twin_or_recording_or_feed)`` blocks and prints the viewer's URL; ``create_app``
gives the ASGI app; :class:`SyntheticFeed` is a feed with its own traffic (tests, benchmark).
See ``docs/viewer.md``.
"""

from __future__ import annotations

from asvtwin.server.app import ServerThread, create_app, scene_document, serve
from asvtwin.server.feed import (
    ControlError,
    Frame,
    RecordingFeed,
    SnapshotFeed,
    TwinFeed,
    as_feed,
)
from asvtwin.server.synthetic import SyntheticFeed

__all__ = [
    "ControlError",
    "Frame",
    "RecordingFeed",
    "ServerThread",
    "SnapshotFeed",
    "SyntheticFeed",
    "TwinFeed",
    "as_feed",
    "create_app",
    "scene_document",
    "serve",
]
