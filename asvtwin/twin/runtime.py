"""The twin's runtime: one loop that joins every capability level, tick by tick.

Each tick at simulation time ``t`` (period ``1 / rates.sim_hz``):

1. operator commands queued since the last tick are applied (and recorded);
2. **sources** — the simulated targets' transponders broadcast NMEA lines when due
   (ITU-R M.1371 intervals), or a log replays them; the lines go through the real AIS
   pipeline into the registry and the tracker's queue (L1);
3. **LiDAR** scans the world (hulls and coast) at its rate;
4. **tracker** fuses the scan and the AIS reports (L3);
5. **observer** estimates τ_d from measured ν and the applied thrust; the fault detector
   watches the residuals (L2);
6. **controller** proposes u_L (L5); the **safety filter** (``*_psf``) turns it into u_0
   with the tracker's predictions as moving obstacles, the coast and d̂ (L4); between
   filter calls u_0 is held; a filter that raises is replaced by braking (never u_L);
7. a **snapshot** is built at its rate (immutable, encoded once) and recorded;
8. the world (ground truth, L0) advances by one step under u_0; the run is scored.

Every component runs through the :class:`~asvtwin.twin.scheduler.Scheduler`: timed, its
errors isolated and counted, its health in the snapshot; the loop never stops for one.
Only the :class:`~asvtwin.twin.clock.Clock` reads the wall clock. Controls from another
thread (the server) are queued and applied at the next tick boundary.

Determinism: every random draw comes from generators spawned from the seed, so the same
scenario, seed and commands give the same snapshots; :meth:`Twin.from_recording` re-runs a
recording from its raw inputs (NMEA lines and commands) and reproduces its snapshots up to
the wall-time measurements (:func:`comparable`).
"""

from __future__ import annotations

import logging
import math
import os
import threading
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import orjson
from numpy.typing import ArrayLike, NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.errors import ScenarioError, SourceError, StateError
from asvtwin.geo import Scene
from asvtwin.scenarios import Scenario, TargetSpec, resolve_scene
from asvtwin.sensors import Lidar, LidarConfig, LidarScan
from asvtwin.sources.ais.source import tag_time
from asvtwin.sources.weather import OfflineWeatherSource, WeatherForecast
from asvtwin.twin import assemble
from asvtwin.twin.clock import Clock
from asvtwin.twin.components import (
    AisInput,
    DisturbanceEstimator,
    FilterStage,
    Perception,
    tracker_config,
)
from asvtwin.twin.controllers import (
    GuidanceStatus,
    ManualController,
    RouteMonitor,
    make_controller,
    uses_filter,
)
from asvtwin.twin.live import LiveAisFeed
from asvtwin.twin.recorder import Recorder
from asvtwin.twin.scheduler import Scheduler
from asvtwin.twin.snapshot import (
    GroundTruth,
    ObserverState,
    OwnShip,
    Snapshot,
    WeatherState,
    encode,
    ro,
)
from asvtwin.twin.summary import RunMetrics, RunSummary
from asvtwin.twin.transponders import Transponders
from asvtwin.twin.world import FULL_SCALE_REFERENCE_M, World
from asvtwin.vessel import VesselParams, vessel_by_name

__all__ = ["TIMING_FIELDS", "Twin", "comparable", "gnss_error", "run_scenario"]

_log = logging.getLogger(__name__)

#: Snapshot fields that measure wall time (excluded when comparing runs).
TIMING_FIELDS = (("health",), ("filter", "solve_ms"), ("clock",))

_COMPONENTS = ("ais", "weather", "lidar", "tracker", "observer", "controller", "filter",
               "world", "scoring", "tracking_score", "snapshot", "recorder")


def comparable(message: bytes | dict[str, Any]) -> dict[str, Any]:
    """A decoded snapshot without its wall-time fields (:data:`TIMING_FIELDS`)."""
    d = orjson.loads(message) if isinstance(message, (bytes, str)) else dict(message)
    for path in TIMING_FIELDS:
        if len(path) == 1:
            d.pop(path[0], None)
        else:
            d[path[0]] = {k: v for k, v in d[path[0]].items() if k != path[1]}
    return d


def own_params(scenario: Scenario) -> VesselParams:
    """The own ship's parameters: with bounded astern thrust when the scenario allows it
    (:func:`asvtwin.vessel.actuators.with_astern`), forward-only otherwise."""
    import dataclasses

    p = vessel_by_name(scenario.own_ship.vessel)
    if scenario.own_ship.astern:
        from asvtwin.vessel.actuators import with_astern

        return with_astern(p)
    if p.actuators.tau_min[0] < 0:
        act = dataclasses.replace(p.actuators, tau_min=(0.0, *p.actuators.tau_min[1:]))
        p = dataclasses.replace(p, actuators=act)
    return p


def gnss_error(scenario: Scenario, own_length_m: float) -> tuple[float, float]:
    """The synthetic transponders' GNSS error (position σ [m], velocity σ [m/s]) per axis:
    the scenario's, or :data:`~asvtwin.twin.transponders.GNSS_POSITION_STD_M` and
    :data:`~asvtwin.twin.transponders.GNSS_VELOCITY_STD_M_S` Froude-scaled to the own
    ship's scale as the weather's wind is (lengths × s, speeds × √s, s = L / 87.85 m, at
    most 1): a model-scale scene is a basin whose positions come from motion capture, not
    a 4 m GNSS error on a 1.3 m hull."""
    from asvtwin.twin.transponders import GNSS_POSITION_STD_M, GNSS_VELOCITY_STD_M_S
    from asvtwin.twin.world import FULL_SCALE_REFERENCE_M

    s = min(1.0, own_length_m / FULL_SCALE_REFERENCE_M)
    a = scenario.ais
    pos = GNSS_POSITION_STD_M * s if a.gnss_position_std_m is None else a.gnss_position_std_m
    vel = (GNSS_VELOCITY_STD_M_S * math.sqrt(s) if a.gnss_velocity_std_m_s is None
           else a.gnss_velocity_std_m_s)
    return float(pos), float(vel)


#: (coast or not, tracker config) pairs whose perception path ran once in this process
_WARMED: set[tuple[bool, str]] = set()


def warm_perception(scene: Scene, config: Any, lidar: Lidar, start_ned: _F8,
                    dt_s: float) -> int | None:
    """Run a throw-away :class:`Perception` over a few scans of one synthetic vessel near
    ``start_ned``, once per process (per scene and tracker config), so that the compiled
    kernels of a target in LiDAR range (cluster fits, hull boxes, measurement pairing,
    about 10 MB of machine code loaded from numba's cache) are loaded while the twin is
    built rather than in the middle of the run, the first time a vessel comes within
    LiDAR range (t = 142.6 s in ``benchmarks/twin.py``'s scene: a 0.1-0.2 s tick and a
    +10 MB step in resident memory that the benchmark's memory hour counted as growth).
    The twin's own state and random generators are not touched (its own generator is not
    drawn from: the warm-up uses a fixed one), so runs and re-runs are unchanged.

    Returns the number of tracks the synthetic vessel gave (None when this scene kind and
    config were already warmed in this process, or the warm-up failed)."""
    key = (scene.land is None, repr(config))
    if key in _WARMED:
        return None
    _WARMED.add(key)
    try:
        rng = np.random.default_rng(0)
        p0 = np.asarray(start_ned, float)[:2]
        r = 0.3 * lidar.config.max_range_m
        # open water near the start (a vessel on land would give coast returns only)
        pos = p0
        for a in np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False):
            q = p0 + r * np.array([np.cos(a), np.sin(a)])
            if scene.land is None or scene.land.signed_distance(q[None])[0] > 50.0:
                pos = q
                break
        own = np.array([p0[0], p0[1], 0.0, 0.0, 0.0, 0.0])
        # a 40 m vessel at 2 m/s for a full-scale LiDAR (500 m), a tenth of the range at
        # model scale (30 m: a 3 m vessel at 0.5 m/s), Froude-scaled speed
        length = min(40.0, 0.1 * lidar.config.max_range_m)
        speed = 2.0 * math.sqrt(length / 40.0)
        perc = Perception(scene, config)
        for k in range(12):
            t = (k + 1) * dt_s
            tgt = np.array([[pos[0] + speed * t, pos[1], 0.0, speed, 0.0, 0.0]])
            scan = lidar.scan(own, tgt, np.array([length]), np.array([length / 5.0]),
                              scene.land, rng, t_s=t)
            tracks = perc.step(t, scan, ())
            assemble.ellipses_part(perc.ellipses())
            assemble.tracks_part(tracks, t, own, np.linspace(0.0, 60.0, 7), config.q)
        return len(tracks)
    except Exception as exc:  # noqa: BLE001 - a warm-up never stops the twin
        _log.warning("perception warm-up failed (kernels load at first use): %s", exc)
        return None


class Twin:
    """The digital twin of one scenario: world, sensors, estimators, controller, filter.

    Parameters
    ----------
    scenario : Scenario
    seed : int, optional
        Seed of every random draw; the scenario's by default.
    clock : Clock, optional
        Pacing; ``Clock("max")`` (as fast as possible) by default.
    record_path : path or binary stream, optional
        Record the run to this MCAP file.
    psf_backend : str
        Safety filter backend (``"auto"``: the fastest installed).
    record_max_bytes : int, optional
        Stop recording (as on a full disk) past this file size.
    record_chunk_bytes : int
        MCAP chunk size (the unit that survives a crash or full disk).
    inputs : RecordedInputs, optional
        Raw inputs of a recording to replay instead of the live sources (see
        :meth:`from_recording`).
    ais_evict_after_s : float
        An AIS target not heard for this long leaves the twin's picture [s] (it is shown
        stale after three reporting intervals, at least 30 s).
    epoch_unix_s : float, optional
        UNIX time of simulation time 0 [s]: the scenario's ``start_time_utc`` by default,
        the wall time at the start for a live AIS feed (which needs a clock at speed 1).
    """

    def __init__(self, scenario: Scenario, *, seed: int | None = None, clock: Clock | None = None,
                 record_path: str | Path | Any | None = None, psf_backend: str = "auto",
                 record_max_bytes: int | None = None, record_chunk_bytes: int = 1 << 20,
                 inputs: RecordedInputs | None = None, ais_evict_after_s: float = 300.0,
                 epoch_unix_s: float | None = None) -> None:
        self.scenario = scenario
        self.seed = int(scenario.seed if seed is None else seed)
        self.clock = clock or Clock("max", start_time_utc=scenario.start_time_utc)
        if self.clock.start_time_utc is None:
            self.clock.start_time_utc = scenario.start_time_utc
        self.scene: Scene = resolve_scene(scenario)
        # simulation time 0 in UNIX time: the scenario's start, or for a live AIS feed the
        # wall time now (the feed's tag-block times are real); a re-run passes the
        # recording's epoch
        # (set again at the end of the construction for a live feed)
        live = scenario.ais.mode == "live" and inputs is None and epoch_unix_s is None
        if epoch_unix_s is not None:
            self.epoch_unix_s = float(epoch_unix_s)
        else:
            self.epoch_unix_s = scenario.start_time_utc.timestamp()
        seeds = np.random.SeedSequence(self.seed).spawn(5)
        rng_env, rng_lidar, rng_ais, rng_nav, _ = (np.random.default_rng(s) for s in seeds)
        rates = scenario.rates
        self.dt_s = 1.0 / rates.sim_hz
        self.params = own_params(scenario)
        self._inputs = inputs
        self._events_early: list[str] = []
        self._extra_lines: list[str] = []
        self._file_i = 0
        self._fault_seen: list[str] = []
        self._wind_set: tuple[float, float] | None = None  # (speed m/s, from rad) by set_wind
        self._weather_cache: tuple[int, Any] | None = None
        # ---- sources at the edge: weather first (the world's wind may come from it)
        self.weather, self.weather_source = self._open_weather()
        self.world = World(scenario, self.scene, self.params, dt_s=self.dt_s, rng=rng_env,
                           weather_wind=self._wind_from_weather(0.0),
                           pilot_period_s=1.0 / rates.controller_hz)
        t = self.world.table
        gnss_std = gnss_error(scenario, self.params.length)
        self.transponders = Transponders(
            t.mmsi, t.ais_class, t.names, t.ship_type, t.length_m, t.beam_m,
            frame=self.scene.frame, epoch_unix_s=self.epoch_unix_s, rng=rng_ais,
            position_std_m=gnss_std[0], velocity_std_m_s=gnss_std[1])
        self.ais_mode = scenario.ais.mode
        self._file_lines = self._open_ais_file() if self.ais_mode == "file" else None
        self.live: LiveAisFeed | None = None
        if self.ais_mode == "live" and inputs is None and self.clock.speed != 1.0:
            # (a re-run has the lines recorded and runs at any speed)
            raise ScenarioError(
                f"ais.mode 'live' ({scenario.ais.url}) runs in real time: the clock must "
                f"run at speed 1 (asvtwin run --speed 1), actually: {self.clock.speed}")
        self.ais_feed_alive = self.ais_mode in ("synthetic", "file", "live")
        self.ais = AisInput(self.scene, epoch_unix_s=self.epoch_unix_s,
                            evict_after_s=ais_evict_after_s)
        # ---- the twin's own components
        s = scenario.sensors
        self.lidar = Lidar(LidarConfig(n_rays=s.lidar_rays, max_range_m=s.lidar_range_m,
                                       range_std_m=s.lidar_noise_m))
        self._rng_lidar = rng_lidar
        self.perception = Perception(self.scene, tracker_config(self.params.length,
                                                                FULL_SCALE_REFERENCE_M))
        warm_perception(self.scene, self.perception.tracker.config, self.lidar,
                        scenario.own_ship.start.to_ned(self.scene.frame),
                        1.0 / rates.tracker_hz)
        self.estimator = DisturbanceEstimator(self.params, dt_s=1.0 / rates.observer_hz,
                                              rng=rng_nav)
        self.controller_name = scenario.own_ship.controller
        self.controller = make_controller(self.controller_name, self.params, scenario.own_ship)
        # progress along the route for every controller (the LOS controller keeps its own;
        # the policy and manual thrust are scored by the twin's monitor)
        self._own_monitor = getattr(self.controller, "monitor", None) is None
        self.route_monitor: RouteMonitor = getattr(self.controller, "monitor", None) or \
            RouteMonitor(scenario.own_ship.lookahead, scenario.own_ship.acceptance_radius)
        self.psf_backend = psf_backend
        self.filter_enabled = uses_filter(self.controller_name)
        self.filter: FilterStage | None = None
        if self.filter_enabled:
            self.filter = FilterStage(self.params, self.scene, backend=psf_backend,
                                      tracker_q=self.perception.tracker.config.q)
        start = scenario.own_ship.start.to_ned(self.scene.frame)
        self.route = np.vstack([start[None]] + [p.to_ned(self.scene.frame)[None]
                                                for p in scenario.own_ship.route])
        # ---- scheduler
        self.scheduler = sch = Scheduler(self.clock)
        periods = {"ais": 0.0, "weather": 60.0, "lidar": 1.0 / s.lidar_rate_hz,
                   "tracker": 1.0 / rates.tracker_hz, "observer": 1.0 / rates.observer_hz,
                   "controller": 1.0 / rates.controller_hz, "filter": 1.0 / rates.filter_hz,
                   "world": 0.0, "scoring": max(self.dt_s, 0.2),
                   # tracking scored against truth once a second: successive errors of a
                   # track 0.1 s apart are nearly the same sample (NEES χ² bounds assume
                   # independent samples), and scoring every tracker update cost 14 % of
                   # the tick
                   "tracking_score": max(1.0 / rates.tracker_hz, 1.0),
                   "snapshot": 1.0 / rates.snapshot_hz,
                   "recorder": 1.0 / rates.snapshot_hz}
        for name in _COMPONENTS:
            sch.add(name, periods[name])
        # ---- state carried between ticks
        self.tick = 0
        self.t_s = 0.0
        x0 = self.world.own_state
        self.u_L = np.asarray(self.controller.act(0.0, x0, self.route, None), float)
        self.u_0 = self.u_L.copy()
        self.scan: LidarScan | None = None
        self._scan_new: LidarScan | None = None
        self._past: deque[tuple[float, float]] = deque(maxlen=240)
        # read-only arrays the snapshots share while their source is unchanged: the past
        # track, the targets' static facts, the route (see _build_snapshot)
        self._past_ro: NDArray[np.float64] | None = None
        self._static_ro: tuple[Any, ...] | None = None
        self._route_ro: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
        self._plan_ro: tuple[Any, Any] | None = None  # (filter answer, its plan_part)
        self._events: list[str] = []
        self._commands: list[tuple[str, dict[str, Any]]] = []
        self._lock = threading.Lock()
        self._latest: Snapshot | None = None
        self._latest_bytes: bytes | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._wall = 0.0
        self._last_line_t = 0.0
        self._summary: RunSummary | None = None
        self.on_snapshot: Callable[[Snapshot, bytes], None] | None = None
        self.metrics = RunMetrics(
            list(self.world.table.names), own_length_m=self.params.length,
            own_beam_m=self.params.beam,
            land=self.scene.land, near_coast_m=max(4.0 * self.params.length, 50.0),
            gate_m=max(2.0 * self.params.length, 10.0),
            observer_settle_s=max(self.estimator.observer.gains.convergence_90_s))
        if live:
            # the feed's tag-block times are real: simulation time 0 is now, after the
            # slow parts of the construction (solver, compiled kernels), and the feed is
            # opened now
            now = self.clock.now_utc()
            self.epoch_unix_s = now.timestamp()
            self.clock.start_time_utc = now
            # the weather, and the world built on its wind, at the new epoch: the world is
            # built again from its own seed, as a re-run of the recording builds it
            self._weather_cache = None
            self.world = World(scenario, self.scene, self.params, dt_s=self.dt_s,
                               rng=np.random.default_rng(seeds[0]),
                               weather_wind=self._wind_from_weather(0.0),
                               pilot_period_s=1.0 / rates.controller_hz)
            self.ais = AisInput(self.scene, epoch_unix_s=self.epoch_unix_s,
                                evict_after_s=ais_evict_after_s)
            self.live = LiveAisFeed(str(scenario.ais.url), self.scene)
        # ---- recorder
        self.recorder: Recorder | None = None
        if record_path is not None:
            self.recorder = Recorder(record_path, scenario_json=scenario.model_dump_json(),
                                     seed=self.seed, epoch_unix_s=self.epoch_unix_s,
                                     chunk_size=record_chunk_bytes, max_bytes=record_max_bytes)
            if self.weather is not None:
                self.recorder.write_json("/twin/weather", 0.0, {"t_s": 0.0, "source": self.weather.source})

    # ================================================================ sources at the edge
    def _open_weather(self) -> tuple[WeatherForecast | None, str]:
        w = self.scenario.weather
        try:
            if w.mode == "fixture":
                return OfflineWeatherSource().fetch(), "fixture"
            if w.mode == "file":
                return OfflineWeatherSource(w.path).fetch(), str(w.path)
            from asvtwin.sources.weather import MetNoClient

            # the live service (network at the edge): needs ASVTWIN_USER_AGENT naming the
            # application and a contact, as api.met.no's terms ask; the forecast is fetched
            # once at the start of the run
            p = self.scenario.own_ship.start.to_ned(self.scene.frame)
            lat, lon = self.scene.frame.to_wgs84(p[0], p[1])
            client = MetNoClient(float(lat), float(lon),
                                 user_agent=os.environ.get("ASVTWIN_USER_AGENT", ""),
                                 clock=lambda: self.clock.now_utc().timestamp())
            return client.fetch(), "met.no"
        except Exception as exc:  # noqa: BLE001 - a missing forecast degrades, not kills
            self._events_early = [f"weather unavailable ({exc}); running without weather"]
            return None, "none"

    def _weather_at(self, t_s: float) -> Any:
        """The forecast at ``t_s``, interpolated at most every 10 s of simulation time
        (the forecast is hourly; interpolating it for every snapshot cost 3 ms)."""
        if self.weather is None:
            return None
        key = math.floor(t_s / 10.0)
        if self._weather_cache is None or self._weather_cache[0] != key:
            w = self.weather.series.at_sim_time(10.0 * key, epoch_unix_s=self.epoch_unix_s)
            self._weather_cache = (key, w)
        return self._weather_cache[1]

    def _wind_from_weather(self, t_s: float) -> tuple[float, float] | None:
        w = self._weather_at(t_s)
        if w is None or w.wind_speed_m_s is None or w.wind_from_rad is None:
            return None
        return float(w.wind_speed_m_s), float(w.wind_from_rad)

    def _open_ais_file(self) -> list[tuple[float, str]]:
        path = Path(str(self.scenario.ais.path))
        try:
            raw = path.read_bytes().splitlines()
        except OSError as exc:
            raise SourceError(f"ais.path {path}: cannot read the NMEA log: {exc}") from exc
        times = [tag_time(r) for r in raw]
        t0 = next((t for t in times if t is not None), None)
        out, last = [], 0.0
        for r, t in zip(raw, times, strict=True):
            if t is not None and t0 is not None:
                last = t - t0
            out.append((last, r.decode("ascii", "replace")))
        return out

    # ================================================================ thread-safe controls
    def _queue(self, command: str, **args: Any) -> None:
        with self._lock:
            self._commands.append((command, args))

    def pause(self) -> None:
        """Pause at the next tick boundary."""
        self.clock.pause()
        self._queue("pause")

    def resume(self) -> None:
        """Resume at the current speed."""
        self.clock.resume()
        self._queue("resume")

    def set_speed(self, factor: float | str) -> None:
        """Speed factor (1 = real time) or ``"max"``."""
        self.clock.set_speed(factor)
        self._queue("set_speed", factor=factor)

    def step_once(self, n_ticks: int = 1) -> None:
        """Run ``n_ticks`` ticks while paused."""
        self.clock.step(n_ticks)

    def set_filter_enabled(self, enabled: bool) -> None:
        """Switch the safety filter in or out between u_L and the thrusters."""
        self._queue("set_filter_enabled", enabled=bool(enabled))

    def set_route(self, waypoints_ned: ArrayLike) -> None:
        """New route from the current position through ``waypoints_ned`` (k, 2) [m]."""
        w = np.asarray(waypoints_ned, dtype=float)
        if w.ndim != 2 or w.shape[1] != 2 or w.shape[0] < 1 or not np.isfinite(w).all():
            raise StateError(f"waypoints must be a finite (k, 2) array [north_m, east_m] with "
                             f"k >= 1, actually shape {w.shape}")
        self._queue("set_route", waypoints=w.tolist())

    def inject_vessel(self, spec: TargetSpec) -> None:
        """Add a target to the world at the next tick."""
        self._queue("inject_vessel", spec=spec.model_dump(mode="json"))

    def set_wind(self, speed_m_s: float, from_deg: float) -> None:
        """Replace the mean wind: ``speed_m_s`` [m/s] from ``from_deg`` [deg]."""
        if not (math.isfinite(speed_m_s) and 0 <= speed_m_s <= 60 and math.isfinite(from_deg)):
            raise StateError(f"wind speed must be in [0, 60] m/s and direction finite, "
                             f"actually: {speed_m_s}, {from_deg}")
        self._queue("set_wind", speed_m_s=float(speed_m_s), from_deg=float(from_deg))

    def set_manual_thrust(self, tau: ArrayLike) -> None:
        """Thrust [N, N, Nm] held by the ``manual`` controller."""
        if not isinstance(self.controller, ManualController):
            raise StateError(f"manual thrust needs controller 'manual', this twin runs "
                             f"{self.controller_name!r}")
        self._queue("set_manual_thrust", tau=np.asarray(tau, float).reshape(-1).tolist())

    def set_ais_feed(self, alive: bool) -> None:
        """Cut (False) or restore (True) the AIS feed, as a lost link would."""
        self._queue("set_ais_feed", alive=bool(alive))

    def feed_nmea(self, lines: list[str]) -> None:
        """Raw NMEA lines received at the next tick (a second receiver, or a test)."""
        self._queue("feed_nmea", lines=[str(x) for x in lines])

    def _apply(self, command: str, args: dict[str, Any]) -> None:
        t = self.t_s
        if command == "set_filter_enabled":
            on = bool(args["enabled"])
            if on and self.filter is None:  # built once; re-enabling reuses the solver
                self.filter = FilterStage(self.params, self.scene, backend=self.psf_backend,
                                          tracker_q=self.perception.tracker.config.q)
            elif on and not self.filter_enabled and self.filter is not None:
                # the plan kept from before the filter was switched out is stale: forget
                # it (and the warm start) so no fallback replays it
                self.filter.reset()
            self.filter_enabled = on
        elif command == "set_route":
            w = np.asarray(args["waypoints"], dtype=float)
            self.route = np.vstack([self.world.own_state[None, :2], w])
        elif command == "inject_vessel":
            spec = TargetSpec.model_validate(args["spec"])
            i = self.world.inject(spec)
            self.transponders.add([spec.mmsi], [spec.ais_class if spec.mmsi else None],
                                  [spec.name], [spec.ais_ship_type], [spec.length_m],
                                  [spec.beam_m], t_s=t)
            self.metrics.add_target(spec.name)
            self._events.append(f"t={t:.1f} s: vessel {spec.name} injected (target {i})")
        elif command == "set_wind":
            self.world.set_wind(args["speed_m_s"], math.radians(args["from_deg"]))
            self._wind_set = (float(args["speed_m_s"]), math.radians(args["from_deg"]))
        elif command == "set_manual_thrust":
            assert isinstance(self.controller, ManualController)
            self.controller.set_tau(args["tau"])
        elif command == "set_ais_feed":
            self.ais_feed_alive = bool(args["alive"])
            if not self.ais_feed_alive:
                self.scheduler.note("ais", f"AIS feed cut at t={t:.1f} s")
        elif command == "feed_nmea" and self._inputs is None:  # a re-run has them recorded
            self._extra_lines.extend(args["lines"])
        if command not in ("pause", "resume", "set_speed"):
            self._events.append(f"t={t:.1f} s: {command}")

    def _take_commands(self) -> None:
        with self._lock:
            cmds, self._commands = self._commands, []
        if self._inputs is not None:  # a re-run: the recording's commands, same ticks
            cmds = [c for c in cmds if c[0] in ("pause", "resume", "set_speed")]
            cmds += self._inputs.commands.get(self.tick, [])
        for name, args in cmds:
            if self.recorder is not None:
                self.recorder.write_json("/twin/commands", self.t_s, {
                    "t_s": self.t_s, "tick": self.tick, "command": name, "args": args})
            try:
                self._apply(name, args)
            except Exception as exc:  # noqa: BLE001 - a bad command never stops the twin
                self._events.append(f"t={self.t_s:.1f} s: command {name} refused: {exc}")
                _log.warning("command %s refused: %s", name, exc)

    # ================================================================ the tick
    def _ais_lines(self, t: float, truth: _F8) -> list[str]:
        lines: list[str] = []
        if self._inputs is not None:
            lines = list(self._inputs.nmea.get(self.tick, []))
        elif self.ais_feed_alive and self.ais_mode == "synthetic":
            lines = self.transponders.step(t, truth)
        elif self.live is not None:
            lines = self.live.take()  # taken even while cut, so a cut feed's lines are lost
            if not self.ais_feed_alive:
                lines = []
        elif self.ais_feed_alive and self._file_lines is not None:
            i = self._file_i
            while i < len(self._file_lines) and self._file_lines[i][0] <= t + 1e-9:
                lines.append(self._file_lines[i][1])
                i += 1
            self._file_i = i
        lines += self._extra_lines
        self._extra_lines = []
        if lines and self.recorder is not None:
            self.recorder.write_json("/twin/nmea", t, {"t_s": t, "tick": self.tick, "lines": lines})
        return lines

    def step(self) -> Snapshot:
        """Run one tick; return the latest snapshot (built at the snapshot rate)."""
        sch = self.scheduler
        t = self.t_s = self.tick * self.dt_s
        self._take_commands()
        own = self.world.own_state
        truth = self.world.target_states

        # 2. sources
        if sch.due("ais", t):
            lines = self._ais_lines(t, truth)
            sch.call("ais", t, self.ais.step, t, lines)
            if lines:
                self._last_line_t = t
            elif self.ais_feed_alive and self.ais_mode != "off" and t - self._last_line_t > 120.0 \
                    and any(c is not None for c in self.world.table.ais_class):
                sch.note("ais", "no NMEA line for more than 120 s (feed silent)")
        if sch.due("weather", t):
            sch.call("weather", t, self._weather_step, t)
        # 3. LiDAR
        if sch.due("lidar", t):
            ok, scan = sch.call("lidar", t, self.lidar.scan, own, truth, self.world.table.length_m,
                                self.world.table.beam_m, self.scene.land, self._rng_lidar, t_s=t)
            if ok and scan is not None:
                self.scan = self._scan_new = scan
        # 4. tracker
        if sch.due("tracker", t):
            ok, _ = sch.call("tracker", t, self.perception.step, t, self._scan_new, self.ais.take(),
                             self.ais.take_static())
            self._scan_new = None
            if sch.due("tracking_score", t):
                sch.call("tracking_score", t, self.metrics.tracking, self.perception.tracks,
                         truth)
        # 5. observer and fault detector
        if sch.due("observer", t):
            sch.call("observer", t, self._observer_step, t, own)
        # 6. controller and filter
        if sch.due("controller", t):
            ok, u = sch.call("controller", t, self._act, t, own)
            if self._own_monitor:
                self.route_monitor.update(own[:2], self.route)
            if ok and u is not None and np.isfinite(u).all():
                self.u_L = np.asarray(u, float).reshape(3)
            if not self.filter_enabled:
                self.u_0 = self.u_L.copy()
        if self.filter_enabled and self.filter is not None and sch.due("filter", t):
            ok, res = sch.call("filter", t, self.filter.step, t, own, self.u_L,
                               self.perception.tracks, self.estimator.d_hat)
            if ok and res is not None:
                self.u_0 = np.asarray(res.u0, float)
            else:
                self.u_0 = self.filter.emergency(t, own)
        # 7. snapshot (state at t, decisions at t)
        if sch.due("snapshot", t):
            ok, snap = sch.call("snapshot", t, self._build_snapshot, t, own, truth)
            if ok and snap is not None:
                sch.call("recorder", t, self._publish, snap)
        # 8. world
        ok, _ = sch.call("world", t, self.world.step, self.u_0)
        if not ok:
            raise StateError(f"the world's simulation failed at t={t:.2f} s: "
                             f"{sch.stats('world').last_error}")
        if sch.due("scoring", t):
            ok, ev = sch.call("scoring", t, self.metrics.truth, t + self.dt_s,
                              self.world.own_state, self.world.target_states,
                              self.world.table.length_m, self.world.table.beam_m)
            if ok and ev:
                self._events.extend(ev)
        st = self.route_status
        if st is not None:
            self.metrics.cte(st.cte_m)
        self.tick += 1
        self.t_s = self.tick * self.dt_s
        return self._latest if self._latest is not None else \
            self._build_snapshot(t, own, truth, keep_state=True)

    def _act(self, t: float, own: _F8) -> _F8:
        """u_L from the controller; a controller that gives way (``see_traffic``) is shown
        what the own ship knows of the traffic first: the confirmed tracks."""
        see = getattr(self.controller, "see_traffic", None)
        due = getattr(self.controller, "traffic_due", None)
        if see is not None and (due is None or due(t)):
            # the confirmed tracks' ids, positions and velocities (the same rows as
            # ``tracks.confirmed()`` without building a second snapshot), and only on the
            # ticks where the controller decides with them
            tr = self.perception.tracks
            m = tr.is_confirmed
            see(tr.ids[m], tr.mean[m, :2], tr.mean[m, 2:])
        return self.controller.act(t, own, self.route, self.scan)

    def _weather_step(self, t: float) -> None:
        if self.recorder is not None and self.weather is not None and t > 0:
            self.recorder.write_json("/twin/weather", t, {"t_s": t, "source": self.weather.source})

    def _observer_step(self, t: float, own: _F8) -> None:
        est = self.estimator
        nu = est.measure(own[3:6])
        tau = self.world.own.thrust[0]
        before = est.nan_inputs
        est.step(t, nu, tau)
        if est.nan_inputs > before:
            self.scheduler.note("observer", "velocity measurements were NaN; d̂ held "
                                "(see observer invalid_samples)")
        if self.scheduler.stats("observer").calls > 0:  # the first sample only anchors ν
            self.metrics.observer(t, est.d_hat, self.world.d_true, est.valid)
        for e in est.events[len(self._fault_seen):]:
            self._events.append(e)
        self._fault_seen = list(est.events)

    @property
    def route_status(self) -> GuidanceStatus:
        """Progress along the route, whatever the controller (cte NaN before its first
        call)."""
        return self.route_monitor.status

    # ================================================================ snapshot
    def _build_snapshot(self, t: float, own: _F8, truth: _F8, *, keep_state: bool = False
                        ) -> Snapshot:
        """The snapshot of the state at ``t``. ``keep_state``: leave the pending events
        and the past track as they are (a paused twin's refresh must not take what the
        next recorded snapshot carries)."""
        sc = self.scene
        tb = self.world.table
        lat, lon = sc.frame.to_wgs84(own[0], own[1])
        v = assemble.ground_velocity(own)
        if not keep_state and (not self._past or t - self._past[-1][0] >= 1.0):
            self._past.append((t, own[0], own[1]))  # type: ignore[arg-type]
            self._past_ro = None
        if self._past_ro is None:  # (rebuilt once a second, not at every snapshot)
            self._past_ro = ro([p[1:] for p in self._past], shape=(-1, 2))
        static = self._static_ro
        if static is None or static[0] is not tb or len(static[1]) != len(tb.names):
            # the targets' static facts, read-only, until a target is added
            static = self._static_ro = (
                tb, tuple(tb.names), ro([-1 if m is None else m for m in tb.mmsi], np.int64),
                ro(tb.length_m), ro(tb.beam_m), ro(np.arange(len(tb.names)), np.int64))
        if self._route_ro is None or self._route_ro[0] is not self.route:
            self._route_ro = (self.route, ro(self.route, shape=(-1, 2)))
        st = self.route_status
        ownship = OwnShip(
            vessel=self.scenario.own_ship.vessel, length_m=self.params.length,
            beam_m=self.metrics.own_beam_m, state=ro(own), lat_deg=float(lat), lon_deg=float(lon),
            sog_m_s=float(np.hypot(*v)), cog_rad=float(np.arctan2(v[1], v[0])),
            tau_cmd=ro(self.u_0), tau_applied=ro(self.world.own.applied_thrust[0]),
            route=self._route_ro[1],
            waypoint_index=int(st.waypoint_index) if st else 0,
            cte_m=float(st.cte_m) if st else math.nan, controller=self.controller_name,
            goal_reached=bool(st.done) if st else False,
            past_track=self._past_ro)
        _, names, mmsi, length_m, beam_m, ids = static
        gt = GroundTruth(ids=ids, names=names, mmsi=mmsi, state=ro(truth, shape=(-1, 6)),
                         length_m=length_m, beam_m=beam_m)
        est = self.estimator
        obs = ObserverState(d_hat=ro(est.d_hat), d_true=ro(self.world.d_true),
                            fault=est.fault_kind is not None, fault_kind=est.fault_kind,
                            fault_channel=est.fault_channel,
                            fault_confidence=est.fault_confidence, valid=est.valid)
        f = self.filter
        horizon = (f.N * f.dt_s) if f is not None else 60.0 * math.sqrt(self.params.length / 1.255)
        pred_times = np.linspace(0.0, horizon, 7)
        last = f.last if (f is not None and self.filter_enabled) else None
        if last is not None and (self._plan_ro is None or self._plan_ro[0] is not last):
            self._plan_ro = (last, assemble.plan_part(last, f.dt_s, f.psf.d_safe_m))  # type: ignore[union-attr]
        filt = assemble.filter_part(
            last, enabled=self.filter_enabled,
            plan=self._plan_ro[1] if last is not None and self._plan_ro is not None else None,
            t_s=f.last_t_s if (f is not None and last is not None) else t,
            u_L=self.u_L, u_0=self.u_0,
            dt_s=f.dt_s if f else 0.0, d_safe_m=f.psf.d_safe_m if f else 0.0,
            calls=f.calls if f else 0, interventions=f.interventions if f else 0,
            fallbacks=sum(f.fallbacks.values()) if f else 0,
            period_s=1.0 / self.scenario.rates.filter_hz)
        w = self._weather_at(t)
        cur = self.world.env_state.current_ned_m_s
        source = self.weather.source if self.weather is not None else "none"
        wind_m_s = math.nan if w is None or w.wind_speed_m_s is None else w.wind_speed_m_s
        wind_from = math.nan if w is None or w.wind_from_rad is None else w.wind_from_rad
        if self._wind_set is not None:  # the operator's wind is the one acting on the ship
            wind_m_s, wind_from = self._wind_set
            source = f"{source}; wind set by operator"
        weather = WeatherState(
            source=source, wind_speed_m_s=wind_m_s, wind_from_rad=wind_from,
            air_temperature_c=math.nan if w is None or w.air_temperature_c is None
            else w.air_temperature_c,
            pressure_hpa=math.nan if w is None or w.air_pressure_pa is None
            else w.air_pressure_pa / 100.0,
            current_m_s=ro(cur),
            age_s=math.nan if w is None else self.epoch_unix_s + t - w.t_unix_s)
        events = tuple(self._events)
        if not keep_state:
            self._events = []
        counters = {"ais_lines": self.ais.lines, "ais_reports": self.ais.reports,
                    **{f"ais_error_{k}": v for k, v in self.ais.errors().items()},
                    "observer_nan_inputs": est.nan_inputs, "ticks": self.tick,
                    **{f"tracker_{k}": v for k, v in self.perception.tracker.counters.items()
                       if k in ("tracks_created", "tracks_deleted", "ais_rejected")}}
        return Snapshot(
            seq=self.tick, t_s=t, scenario=self.scenario.name, clock=self.clock.state(t),
            own=ownship, truth=gt, ais=assemble.ais_part(self.ais.targets(t), sc.frame),
            lidar=assemble.lidar_part(self.scan, sc.land,
                                      self.perception.tracker.config.cluster.coast_margin_m),
            ellipses=assemble.ellipses_part(self.perception.ellipses()),
            tracks=assemble.tracks_part(self.perception.tracks, t, own, pred_times,
                                        self.perception.tracker.config.q, own_velocity=v),
            observer=obs, filter=filt, weather=weather, health=self.scheduler.health(),
            events=events, counters=counters)

    def _publish(self, snap: Snapshot) -> None:
        data = encode(snap)
        with self._lock:
            self._latest, self._latest_bytes = snap, data
        rec = self.recorder
        if rec is not None and rec.active:
            rec.write("/twin/snapshot", snap.t_s, data)
            if rec.error is not None:
                self.scheduler.note("recorder", rec.error)
                self._events.append(f"t={snap.t_s:.1f} s: {rec.error}")
        if self.on_snapshot is not None:
            self.on_snapshot(snap, data)

    # ================================================================ running
    def latest(self) -> Snapshot:
        """The last snapshot published (one is built and published now if none exists
        yet, e.g. for a viewer connecting to a twin that starts paused)."""
        with self._lock:
            s = self._latest
        if s is None:  # (no controls applied here: this may be another thread)
            self._publish_current(take_commands=False)
            with self._lock:
                s = self._latest
        assert s is not None
        return s

    def refresh(self) -> Snapshot:
        """Apply the queued controls and publish a snapshot of the current state without
        advancing time (what a paused twin shows; the run loop calls it while paused, so
        call it only from the thread that runs the twin). Not recorded: the recording
        holds the ticks' snapshots, and the controls applied here are recorded at this
        tick, where a re-run applies them too."""
        return self._publish_current(take_commands=True)

    def _publish_current(self, *, take_commands: bool) -> Snapshot:
        if take_commands and self._inputs is None:  # a re-run applies them in its ticks
            self._take_commands()
        snap = self._build_snapshot(self.t_s, self.world.own_state, self.world.target_states,
                                    keep_state=True)
        data = encode(snap)
        with self._lock:
            self._latest, self._latest_bytes = snap, data
        return snap

    def latest_bytes(self) -> bytes | None:
        """The last snapshot as encoded JSON (what the recorder and server send)."""
        with self._lock:
            return self._latest_bytes

    def run(self, duration_s: float | None = None, *,
            progress: Callable[[float, float], None] | None = None) -> RunSummary:
        """Run until ``duration_s`` (the scenario's by default) or :meth:`stop`; close the
        recording and return the summary. ``progress(t_s, duration_s)`` is called about
        every 5 % of the run."""
        end = float(self.scenario.duration_s if duration_s is None else duration_s)
        n_end = round(end / self.dt_s)
        w0 = self.clock.perf()
        every = max(1, n_end // 20)
        idle_seq = -1
        try:
            while self.tick < n_end and not self._stop.is_set():
                if not self.clock.wait_for_tick(self.tick * self.dt_s, block=False):
                    if self.clock.stopped or not self.clock.paused:
                        break
                    # paused: controls still apply and the published snapshot shows them
                    # (and the paused clock) so a viewer that connects now sees the twin
                    with self._lock:
                        pending = bool(self._commands)
                    if pending or idle_seq != self.tick:
                        self.refresh()
                        idle_seq = self.tick
                    self.clock.wait_while_paused()
                    continue
                self.step()
                if progress is not None and self.tick % every == 0:
                    progress(self.t_s, end)
        finally:
            self._wall += self.clock.perf() - w0
            self._summary = self.summary()
            self.close()
        return self._summary

    def start_background(self, duration_s: float | None = None) -> threading.Thread:
        """Run :meth:`run` in a daemon thread (for the server); :meth:`stop` ends it."""
        if self._thread is not None and self._thread.is_alive():
            raise StateError("the twin is already running in the background")
        self._stop.clear()
        self.clock.start()
        self._thread = threading.Thread(target=self.run, args=(duration_s,), daemon=True,
                                        name=f"twin-{self.scenario.name}")
        self._thread.start()
        return self._thread

    def stop(self, timeout_s: float = 10.0) -> None:
        """Stop the loop after the current tick and wait for the thread."""
        self._stop.set()
        self.clock.stop()
        if self._thread is not None:
            self._thread.join(timeout_s)

    def close(self) -> None:
        """Stop a live feed, write the summary into the recording and finish the file."""
        if self.live is not None:
            self.live.close()
        rec = self.recorder
        if rec is not None and not rec.closed:
            if rec.active:
                s = self._summary or self.summary()
                rec.write_json("/twin/summary", self.t_s, s.to_dict())
            rec.close()
            if rec.error is not None:
                self.scheduler.note("recorder", rec.error)

    def summary(self) -> RunSummary:
        """The run so far, scored against ground truth."""
        f = self.filter
        sch = self.scheduler
        deg = list(sch.degradations())
        if f is not None and f.fallbacks:
            deg.append(f"filter fell back {sum(f.fallbacks.values())} times in {f.calls} calls "
                       f"({', '.join(f'{k} {v}' for k, v in sorted(f.fallbacks.items()))}); "
                       "u_L was never applied unfiltered")
        if self.recorder is not None and self.recorder.error is not None and \
                not any(d.startswith("recorder") for d in deg):
            deg.append(f"recorder degraded: {self.recorder.error}")
        deg.extend(self._events_early)
        if self.live is not None:
            lv = {k: v for k, v in self.live.counters().items() if v}
            if lv or self.live.dropped or self.live.error:
                deg.append(f"live AIS feed {self.live.url}: "
                           + ", ".join([f"{k} {v}" for k, v in sorted(lv.items())]
                                       + ([f"{self.live.dropped} lines dropped (buffer full)"]
                                          if self.live.dropped else [])
                                       + ([self.live.error] if self.live.error else [])))
        errs = self.ais.errors()
        if sum(errs.values()):
            deg.append(f"ais input: {sum(errs.values())} malformed or rejected NMEA lines/"
                       f"reports dropped ({', '.join(f'{k} {v}' for k, v in sorted(errs.items()))})")
        st = self.route_status
        ticks = self.tick
        sim_s = ticks * self.dt_s
        counters = {"ais_lines": self.ais.lines, "ais_reports": self.ais.reports,
                    **{f"ais_error_{k}": v for k, v in self.ais.errors().items()},
                    "observer_nan_inputs": self.estimator.nan_inputs,
                    "clock_lag_resets": self.clock.lag_resets,
                    "recorded_messages": self.recorder.messages if self.recorder else 0}
        rec_path = None
        if self.recorder is not None and self.recorder.path is not None:
            rec_path = str(self.recorder.path)
        return self.metrics.summarise(
            criteria=self.scenario.criteria, goal_reached=bool(st.done) if st else False,
            scenario=self.scenario.name, seed=self.seed, duration_s=sim_s, ticks=ticks,
            controller=self.scenario.own_ship.controller,
            wall_s=self._wall, realtime_factor=sim_s / self._wall if self._wall > 0 else math.inf,
            filter_calls=f.calls if f else 0, interventions=f.interventions if f else 0,
            fallbacks=dict(f.fallbacks) if f else {}, ms_per_tick=sch.ms_per_tick(ticks),
            degradations=tuple(deg), counters=counters, recording=rec_path)

    # ================================================================ re-running a recording
    @classmethod
    def from_recording(cls, path: str | os.PathLike[str], **kwargs: Any) -> Twin:
        """A twin that re-runs a recording from its raw inputs (NMEA lines, commands) and
        seed; its snapshots equal the recorded ones up to :data:`TIMING_FIELDS`."""
        from asvtwin.twin.replay import Recording

        rec = Recording(path)
        if rec.scenario is None:
            raise SourceError(f"{path}: the recording holds no scenario")
        scenario = Scenario.model_validate_json(orjson.dumps(rec.scenario))
        kwargs.setdefault("epoch_unix_s", rec.metadata["epoch_unix_s"])
        return cls(scenario, seed=rec.seed, inputs=RecordedInputs.read(rec), **kwargs)


class RecordedInputs:
    """The raw inputs of a recording, by tick: NMEA lines and operator commands."""

    def __init__(self, nmea: dict[int, list[str]], commands: dict[int, list[tuple[str, dict[str, Any]]]]
                 ) -> None:
        self.nmea = nmea
        self.commands = commands

    @classmethod
    def read(cls, rec: Any) -> RecordedInputs:
        nmea: dict[int, list[str]] = {}
        for _, data in rec.iter_messages(topic="/twin/nmea"):
            m = orjson.loads(data)
            nmea.setdefault(int(m["tick"]), []).extend(m["lines"])
        cmds: dict[int, list[tuple[str, dict[str, Any]]]] = {}
        for _, data in rec.iter_messages(topic="/twin/commands"):
            m = orjson.loads(data)
            if m["command"] not in ("pause", "resume", "set_speed"):
                cmds.setdefault(int(m["tick"]), []).append((m["command"], m["args"]))
        return cls(nmea, cmds)


def run_scenario(scenario: Scenario, *, seed: int | None = None, duration_s: float | None = None,
                 out_dir: str | Path | None = None, record: bool = True,
                 psf_backend: str = "auto", clock: Clock | None = None,
                 progress: Callable[[float, float], None] | None = None) -> RunSummary:
    """Run a scenario headless; with ``out_dir``, write ``run.mcap`` (when ``record``) and
    ``summary.json`` there."""
    rec_path = None
    if out_dir is not None:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        if record:
            rec_path = out / "run.mcap"
    twin = Twin(scenario, seed=seed, clock=clock, record_path=rec_path, psf_backend=psf_backend)
    summary = twin.run(duration_s, progress=progress)
    if out_dir is not None:
        (Path(out_dir) / "summary.json").write_bytes(
            orjson.dumps(summary.to_dict(), option=orjson.OPT_INDENT_2))
    return summary
