"""What the server serves: a feed of snapshots plus the controls it accepts.

The server knows nothing of the twin's internals. It reads a :class:`SnapshotFeed`: the
newest snapshot (encoded once, shared by every client), the scene it lives in, and a
``control(action, payload)`` entry point. Three feeds exist:

- :class:`TwinFeed` adapts a running :class:`asvtwin.twin.runtime.Twin` (``asvtwin run``);
- :class:`RecordingFeed` plays an :class:`asvtwin.twin.replay.Recording` back with pause,
  speed and seek (``asvtwin replay FILE``);
- :class:`asvtwin.server.synthetic.SyntheticFeed` makes its own traffic (tests, benchmark).

Controls are validated by the server (``asvtwin.server.api``) before they reach a feed; a
feed raises :class:`ControlError` when it cannot honour one (a seek on a live
twin), which the server turns into HTTP 409 with the reason.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable

import numpy as np
import orjson

from asvtwin.errors import AsvTwinError
from asvtwin.geo import Scene, default_scene
from asvtwin.twin.snapshot import Snapshot, encode

__all__ = ["ControlError", "Frame", "RecordingFeed", "SnapshotFeed", "TwinFeed", "as_feed"]


class ControlError(AsvTwinError, ValueError):
    """A valid control request the feed cannot honour (a seek on a live twin, ...); the
    server answers HTTP 409 with this message."""

#: The actions a live twin understands (contract of ``Twin``'s thread-safe controls).
LIVE_ACTIONS: tuple[str, ...] = ("pause", "resume", "speed", "step", "filter", "route", "inject", "wind")
#: The actions a replay understands.
REPLAY_ACTIONS: tuple[str, ...] = ("pause", "resume", "speed", "step", "seek")


class Frame:
    """One snapshot on the wire: sequence number, time, the JSON bytes, and the
    snapshot's events (sent to clients in their own small queue, never dropped)."""

    __slots__ = ("_msgpack", "data", "events", "seq", "t_s")

    def __init__(self, seq: int, t_s: float, data: bytes, events: tuple[str, ...] = ()) -> None:
        self.seq = seq
        self.t_s = t_s
        self.data = data
        self.events = events
        self._msgpack: bytes | None = None

    def msgpack(self) -> bytes:
        """The same message as MessagePack (encoded once, on the first request)."""
        if self._msgpack is None:
            try:
                import msgpack
            except ImportError as exc:  # pragma: no cover - msgpack is a core dependency
                raise ControlError("msgpack is not installed; ask for format=json") from exc
            self._msgpack = msgpack.packb(orjson.loads(self.data), use_single_float=False)
        return self._msgpack


@runtime_checkable
class SnapshotFeed(Protocol):
    """The server's view of a twin or a replay.

    ``kind`` is ``"live"``, ``"replay"`` or ``"synthetic"``; ``actions`` the control
    actions it accepts; ``frame()`` the newest :class:`Frame` (or None before the first
    tick); ``control`` applies one validated action and returns a small JSON-able answer.
    ``start``/``stop`` run and end its loop (the server calls them at startup/shutdown).
    """

    kind: str
    actions: tuple[str, ...]

    def frame(self) -> Frame | None: ...

    def scene(self) -> Scene: ...

    def info(self) -> dict[str, Any]: ...

    def control(self, action: str, payload: dict[str, Any]) -> dict[str, Any]: ...

    def start(self) -> None: ...

    def stop(self) -> None: ...


class _EncodedCache:
    """Encode each snapshot once, whichever client asks first. Keyed by the snapshot
    object, not its ``seq``: a paused twin republishes its state (a control applied, the
    paused clock) under the same ``seq`` and time, and that snapshot must reach clients."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._frame: Frame | None = None
        self._snap: Snapshot | None = None

    def get(self, snap: Snapshot | None) -> Frame | None:
        if snap is None:
            return None
        with self._lock:
            if self._frame is None or self._snap is not snap:
                self._frame = Frame(snap.seq, float(snap.t_s), encode(snap), tuple(snap.events))
                self._snap = snap
            return self._frame

    def get_encoded(self, snap: Snapshot, data: bytes) -> Frame:
        with self._lock:
            if self._frame is None or self._frame.data is not data:
                self._frame = Frame(snap.seq, float(snap.t_s), data, tuple(snap.events))
            return self._frame


class TwinFeed:
    """A live :class:`~asvtwin.twin.runtime.Twin` as a feed (contract: ``latest()``,
    ``start_background()``/``stop()`` and the thread-safe controls)."""

    kind = "live"
    actions: tuple[str, ...] = LIVE_ACTIONS

    def __init__(self, twin: Any, *, scene: Scene | None = None, manage_loop: bool = True) -> None:
        self.twin = twin
        self._scene = scene
        self._cache = _EncodedCache()
        self._manage = manage_loop

    def frame(self) -> Frame | None:
        latest_bytes = getattr(self.twin, "latest_bytes", None)
        if latest_bytes is not None:
            # the twin's own encoding (the recorder's bytes): no second encode per tick. The
            # twin publishes snapshot and bytes together under its lock, so when the bytes
            # did not change around latest(), they belong to that snapshot.
            b1 = latest_bytes()
            snap = self.twin.latest()
            if b1 is not None and latest_bytes() is b1:
                return self._cache.get_encoded(snap, b1)
            return self._cache.get(snap)
        return self._cache.get(self.twin.latest())

    def scene(self) -> Scene:
        if self._scene is None:
            self._scene = getattr(self.twin, "scene", None) or default_scene()
        return self._scene

    def info(self) -> dict[str, Any]:
        scenario = getattr(self.twin, "scenario", None)
        return {"kind": self.kind, "actions": list(self.actions),
                "scenario": getattr(scenario, "name", ""), "duration_s": None}

    def start(self) -> None:
        if self._manage:
            self.twin.start_background()

    def stop(self) -> None:
        if self._manage:
            self.twin.stop()

    def control(self, action: str, payload: dict[str, Any]) -> dict[str, Any]:
        tw = self.twin
        if action == "pause":
            tw.pause()
        elif action == "resume":
            tw.resume()
        elif action == "speed":
            tw.set_speed(payload["factor"])
        elif action == "step":
            tw.step_once(int(payload["n_ticks"]))
        elif action == "filter":
            tw.set_filter_enabled(bool(payload["enabled"]))
        elif action == "route":
            tw.set_route(np.asarray(payload["waypoints_ned"], dtype=np.float64).reshape(-1, 2))
        elif action == "inject":
            tw.inject_vessel(_target_spec(payload["spec"]))
        elif action == "wind":
            tw.set_wind(float(payload["speed_m_s"]), float(payload["from_deg"]))
        else:
            raise ControlError(f"action {action!r} is not available on a live twin; "
                               f"allowed: {', '.join(self.actions)}")
        return {"ok": True, "action": action}


def _target_spec(spec: dict[str, Any]) -> Any:
    """The scenario schema's ``TargetSpec`` from a validated inject request."""
    try:
        from asvtwin.scenarios.schema import TargetSpec
    except ImportError as exc:
        raise ControlError("injecting a vessel needs asvtwin.scenarios (not available)") from exc
    try:
        return TargetSpec.model_validate(spec)
    except Exception as exc:  # pydantic.ValidationError: the scenario schema's own check
        raise ControlError(f"the vessel spec does not fit the scenario schema: {exc}") from exc


class RecordingFeed:
    """Plays a recording back on a wall clock: pause, speed, step and seek.

    The playback time is ``t = t_anchor + speed * (wall - wall_anchor)`` while playing; no
    thread is needed, each :meth:`frame` reads the message nearest before ``t`` from the
    recording (``Recording.message_at``), caching by time so clients share one message.
    ``clock`` returns wall seconds (``time.monotonic`` by default; tests pass their own).
    """

    kind = "replay"
    actions: tuple[str, ...] = REPLAY_ACTIONS

    def __init__(self, recording: Any, *, scene: Scene | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.recording = recording
        self._scene = scene
        self._clock = clock
        self._lock = threading.Lock()
        self.duration_s = float(recording.duration_s)
        self._speed = 1.0
        self._paused = False
        self._t_anchor = 0.0
        self._wall_anchor = clock()
        self._cursor: Any = None
        self._cursor_t = 0.0
        self._pending: tuple[float, bytes] | None = None
        self._current: Frame | None = None
        self._step_s = 0.1

    def _now_locked(self) -> float:
        if self._paused:
            t = self._t_anchor
        else:
            t = self._t_anchor + self._speed * (self._clock() - self._wall_anchor)
        return min(max(t, 0.0), self.duration_s)

    def playback_time_s(self) -> float:
        with self._lock:
            return self._now_locked()

    def _reanchor(self, t_s: float) -> None:
        self._t_anchor = min(max(t_s, 0.0), self.duration_s)
        self._wall_anchor = self._clock()

    def frame(self) -> Frame | None:
        t = self.playback_time_s()
        with self._lock:
            if self._cursor is None or t < self._cursor_t:
                # (re)open the stream at t (a seek back, or the first read): the message at
                # or before t comes from message_at, the later ones from one iterator
                self._cursor = self.recording.iter_messages(start_s=t)
                self._cursor_t = t
                self._pending = next(self._cursor, None)
                self._current = self._to_frame(self.recording.message_at(t))
            # forward play reads the file sequentially, never re-seeking
            while self._pending is not None and self._pending[0] <= t:
                self._current = self._to_frame(self._pending[1])
                self._pending = next(self._cursor, None)
            self._cursor_t = t
            return self._current

    @staticmethod
    def _to_frame(data: bytes) -> Frame:
        head = orjson.loads(data)
        return Frame(int(head.get("seq", 0)), float(head.get("t_s", 0.0)), bytes(data),
                     tuple(head.get("events", ())))

    def scene(self) -> Scene:
        if self._scene is None:
            self._scene = default_scene()
        return self._scene

    def info(self) -> dict[str, Any]:
        meta = getattr(self.recording, "metadata", {}) or {}
        scen = meta.get("scenario") if isinstance(meta, dict) else None
        name = scen.get("name", "") if isinstance(scen, dict) else getattr(scen, "name", "") or ""
        with self._lock:
            return {"kind": self.kind, "actions": list(self.actions), "scenario": name,
                    "duration_s": self.duration_s, "t_s": self._now_locked(),
                    "paused": self._paused, "speed": self._speed}

    def start(self) -> None:
        """Nothing to start: playback is computed from the wall clock at each frame."""

    def stop(self) -> None:
        """Nothing to stop: no thread or open stream outlives a frame."""

    def control(self, action: str, payload: dict[str, Any]) -> dict[str, Any]:
        with self._lock:
            now = self._now_locked()
            if action == "pause":
                self._reanchor(now)
                self._paused = True
            elif action == "resume":
                self._reanchor(now)
                self._paused = False
            elif action == "speed":
                factor = payload["factor"]
                if factor == "max":
                    raise ControlError("a replay plays at a finite speed; give a factor in (0, 1000]")
                self._reanchor(now)
                self._speed = float(factor)
            elif action == "step":
                self._reanchor(now + self._step_s * int(payload["n_ticks"]))
                self._cursor = None
                self._paused = True
            elif action == "seek":
                t = float(payload["t_s"])
                if not 0.0 <= t <= self.duration_s:
                    raise ControlError(f"seek time must be in [0, {self.duration_s:g}] s, actually: {t:g}")
                self._reanchor(t)
                self._cursor = None  # reopen the stream at the new time
            else:
                raise ControlError(f"action {action!r} is not available on a replay; "
                                   f"allowed: {', '.join(self.actions)}")
            return {"ok": True, "action": action, "t_s": self._now_locked()}


def as_feed(obj: Any) -> SnapshotFeed:
    """A feed for a feed, a ``Twin`` or a ``Recording`` (duck-typed on their contracts)."""
    if isinstance(obj, SnapshotFeed):
        return obj
    if hasattr(obj, "message_at") and hasattr(obj, "duration_s"):
        return RecordingFeed(obj)
    if hasattr(obj, "latest") and hasattr(obj, "start_background"):
        return TwinFeed(obj)
    raise TypeError(f"cannot serve {type(obj).__name__}: expected a SnapshotFeed, a Twin "
                    "(latest, start_background) or a Recording (message_at, duration_s)")
