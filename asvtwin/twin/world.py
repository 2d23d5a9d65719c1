"""The world: ground truth the twin never sees directly.

The own ship (:class:`~asvtwin.vessel.VesselSimulator`), every target in one
:class:`~asvtwin.vessel.BatchSimulator` (each hull CyberShip II Froude-scaled to its length),
and the environment (current, wind, waves) acting on the own ship. The targets are steered
by their behaviours (hold course and speed, follow waypoints, a simple COLREG give-way or
stand-on rule), computed for all targets at once; an ``ais_replay`` target is put where
its AIS log says at every step (:mod:`asvtwin.twin.ais_track`). The twin's runtime reads the world only
through sensors (AIS lines from :mod:`asvtwin.twin.transponders`, LiDAR scans) and to score
a run (distances, tracking error): ground truth never decides.

Targets feel no environmental disturbance (their autopilots would cancel most of it, and
the twin never models them at that level).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from asvtwin.checks import F8 as _F8
from asvtwin.environment import (
    CurrentConfig,
    Environment,
    EnvironmentConfig,
    GaussMarkov,
    WaveConfig,
    WindConfig,
)
from asvtwin.errors import ScenarioError
from asvtwin.geo import Scene
from asvtwin.scenarios import AisReplay, ConstantVelocity, Scenario, TargetSpec
from asvtwin.sources.ais import ReportBatch
from asvtwin.twin.ais_track import AisTrack, read_ais_log
from asvtwin.twin.pilots import TargetPilots
from asvtwin.units import KNOT_M_S
from asvtwin.vessel import (
    BatchSimulator,
    VesselParams,
    cybership2,
    damping,
    froude_scale,
)

__all__ = ["FULL_SCALE_REFERENCE_M", "TargetTable", "World", "environment_config",
           "steady_thrust"]


#: Ship length the weather's wind and the default waves are meant for [m] (CyberShip II ×70);
#: a model-scale own ship gets them Froude-scaled.
FULL_SCALE_REFERENCE_M = 87.85
_MODEL_LENGTH_M = 1.255


def steady_thrust(params: VesselParams, u_m_s: float) -> _F8:
    """Thrust [N, N, Nm] that holds surge speed ``u_m_s`` straight ahead: τ = D(ν)ν at
    ν = (u, 0, 0) (C(ν)ν vanishes for pure surge)."""
    nu = np.array([u_m_s, 0.0, 0.0])
    tau = damping(params, nu) @ nu
    lo, hi = np.asarray(params.actuators.tau_min), np.asarray(params.actuators.tau_max)
    return np.clip(np.asarray(tau, dtype=float).reshape(3), lo, hi)


def environment_config(scenario: Scenario, own_length_m: float,
                       weather_wind: tuple[float, float] | None) -> EnvironmentConfig:
    """The environment of a scenario for an own ship of ``own_length_m``.

    Current and an explicit wind are taken as written (the scenario's own scale). A wind
    "from the weather" (``weather_wind`` = speed [m/s], from [rad], for a full-scale ship)
    and the waves (0.6 m, towards the current) are Froude-scaled to a model-scale hull.
    """
    env = scenario.environment
    s = min(1.0, own_length_m / FULL_SCALE_REFERENCE_M)
    sq = math.sqrt(s)
    current = CurrentConfig(env.current_speed_m_s, math.radians(env.current_to_deg),
                            GaussMarkov(0.05 * env.current_speed_m_s, 600.0 * sq))
    if env.wind_speed_m_s is not None and env.wind_from_deg is not None:
        wind = WindConfig(env.wind_speed_m_s, math.radians(env.wind_from_deg),
                          GaussMarkov(0.15 * env.wind_speed_m_s, 30.0 * sq))
    elif weather_wind is not None:
        w, frm = weather_wind
        wind = WindConfig(w * sq, frm, GaussMarkov(0.15 * w * sq, 30.0 * sq))
    else:
        wind = WindConfig()
    waves = (WaveConfig(0.6 * s, math.radians(env.current_to_deg), 0.3,
                        GaussMarkov(0.3, 120.0 * sq)) if env.waves else WaveConfig())
    return EnvironmentConfig(current=current, wind=wind, waves=waves)


@dataclass
class TargetTable:
    """Static facts about the targets, row ``i`` = target ``i`` (plain lists/arrays)."""

    names: list[str]
    mmsi: list[int | None]
    ais_class: list[str | None]
    ship_type: list[int]
    length_m: _F8
    beam_m: _F8

    def append(self, spec: TargetSpec) -> None:
        self.names.append(spec.name)
        self.mmsi.append(spec.mmsi)
        self.ais_class.append(spec.ais_class if spec.mmsi is not None else None)
        self.ship_type.append(spec.ais_ship_type)
        self.length_m = np.append(self.length_m, spec.length_m)
        self.beam_m = np.append(self.beam_m, spec.beam_m)


def target_params(length_m: float) -> VesselParams:
    """CyberShip II Froude-scaled to a hull of ``length_m`` [m]."""
    return froude_scale(cybership2(), length_m / _MODEL_LENGTH_M, name=f"target_{length_m:g}m")


class World:
    """Ground truth: own ship, targets and environment, stepped together.

    Parameters
    ----------
    scenario : Scenario
    scene : Scene
    own_params : VesselParams
        The own ship's parameters (astern thrust as the scenario allows).
    dt_s : float
        Simulation step [s].
    rng : numpy.random.Generator
        Environment variations.
    weather_wind : (speed [m/s], from [rad]) or None
        Wind from the weather source, for a scenario that takes it from there.
    pilot_period_s : float
        The targets' autopilots run at this period [s] (their thrust is held between
        runs, as a real autopilot's output is); 0: every step.
    """

    def __init__(self, scenario: Scenario, scene: Scene, own_params: VesselParams, *,
                 dt_s: float, rng: np.random.Generator,
                 weather_wind: tuple[float, float] | None = None,
                 pilot_period_s: float = 0.0) -> None:
        self.scenario = scenario
        self.scene = scene
        self.dt_s = float(dt_s)
        self.rng = rng
        self.t_s = 0.0
        own = scenario.own_ship
        p0 = own.start.to_ned(scene.frame)
        x0 = np.array([p0[0], p0[1], math.radians(own.heading_deg),
                       own.speed_kn * KNOT_M_S, 0.0, 0.0])
        self.own_params = own_params
        self.own = BatchSimulator(own_params, x0[None], dt_s=self.dt_s,
                                  tau0=steady_thrust(own_params, x0[3])[None])
        self.env = Environment(environment_config(scenario, own_params.length, weather_wind))
        self.env_state = self.env.initial_state(rng)
        self.d_true = np.zeros(3)
        self.table = TargetTable([], [], [], [], np.zeros(0), np.zeros(0))
        self._params: list[VesselParams] = []
        self._x = np.zeros((0, 6))
        self.pilots = TargetPilots(scene.frame)
        self.targets: BatchSimulator | None = None
        self.pilot_period_s = float(pilot_period_s)
        self._pilot_next = 0.0
        self._tau_t = np.zeros((0, 3))
        self._logs: dict[str, ReportBatch] = {}
        self._replay: dict[int, AisTrack] = {}  # target index -> its AIS log track
        for spec in scenario.targets:
            self._add(spec)
        self._rebuild(self._x, np.zeros((len(self._params), 3)))

    # ------------------------------------------------------------------ targets
    def _add(self, spec: TargetSpec) -> None:
        b = spec.behaviour
        params = target_params(spec.length_m)
        if isinstance(b, AisReplay):
            # kinematic: its state comes from the log at every step (see ais_track); the
            # pilot entry only keeps the batch's rows aligned
            if b.file not in self._logs:
                self._logs[b.file] = read_ais_log(b.file, self.scene)
            track = AisTrack(self._logs[b.file], b.mmsi, source=f"target {spec.name!r} file "
                             f"{b.file}")
            self._replay[len(self._params)] = track
            x = track.state_at(self.t_s)
            spec = spec.model_copy(update={"behaviour": ConstantVelocity()})
        else:
            assert spec.start is not None  # the schema requires it for these behaviours
            p = spec.start.to_ned(self.scene.frame)
            u = spec.speed_kn * KNOT_M_S
            x = np.array([p[0], p[1], math.radians(spec.heading_deg), u, 0.0, 0.0])
        self._params.append(params)
        self._x = np.vstack([self._x, x])
        self.table.append(spec)
        self.pilots.add(spec, params, x)

    def _rebuild(self, x: _F8, tau: _F8) -> None:
        if len(self._params) == 0:
            self.targets = None
            return
        tau0 = tau.copy()
        new = np.flatnonzero(~np.any(tau0 != 0.0, axis=1))
        for i in new.tolist():  # a new target starts with the thrust that holds its speed
            tau0[i] = steady_thrust(self._params[i], float(x[i, 3]))
        self.targets = BatchSimulator(self._params, x, dt_s=self.dt_s, tau0=tau0,
                                      t0_s=self.t_s)

    def inject(self, spec: TargetSpec) -> int:
        """Add a target now (its index); the batch is rebuilt with the others' states kept."""
        x_old = self.target_states
        tau_old = self.targets.thrust if self.targets is not None else np.zeros((0, 3))
        if spec.name in self.table.names:
            raise ScenarioError(f"a target named {spec.name!r} already exists")
        if spec.mmsi is not None and spec.mmsi in self.table.mmsi:
            raise ScenarioError(f"a target with MMSI {spec.mmsi} already exists")
        self._x = x_old
        self._add(spec)
        self._rebuild(self._x, np.vstack([tau_old, np.zeros((1, 3))]))
        self._pilot_next = self.t_s  # the new target gets its autopilot at once
        return len(self._params) - 1

    @property
    def n_targets(self) -> int:
        """Number of targets."""
        return len(self._params)

    @property
    def target_states(self) -> _F8:
        """Target states (n, 6) (a copy)."""
        return self.targets.state if self.targets is not None else np.zeros((0, 6))

    @property
    def own_state(self) -> _F8:
        """Own-ship state (6,) (a copy)."""
        return self.own.state[0]

    # ------------------------------------------------------------------ stepping
    def set_wind(self, speed_m_s: float, from_rad: float) -> None:
        """Replace the mean wind (gusts keep their statistics)."""
        cfg = self.env.config
        wind = WindConfig(float(speed_m_s), float(from_rad), cfg.wind.gusts,
                          cfg.wind.c_x, cfg.wind.c_y, cfg.wind.c_n)
        self.env = Environment(EnvironmentConfig(cfg.current, wind, cfg.waves))

    def step(self, tau_own: _F8) -> None:
        """Advance everything by ``dt_s`` with own-ship command ``tau_own`` [N, N, Nm]."""
        x_own = self.own.state[0]
        self.d_true = self.env.forces(self.own_params, x_own, self.env_state)[0]
        self.own.step(tau_own, self.d_true)
        if self.targets is not None:
            if self.t_s + 1e-9 >= self._pilot_next or self._tau_t.shape[0] != self.n_targets:
                self._tau_t = self.pilots.tau(self.t_s, self.targets.state, x_own)
                self._pilot_next = self.t_s + self.pilot_period_s
            self.targets.step(self._tau_t)
            if self._replay:  # replayed vessels are where their log puts them
                x = self.targets.state
                for i, track in self._replay.items():
                    x[i] = track.state_at(self.t_s + self.dt_s)
                self.targets.reset(x, tau0=self.targets.thrust, t0_s=self.targets.t_s)
        self.env_state = self.env.advance(self.env_state, self.dt_s, self.rng)
        self.t_s += self.dt_s
