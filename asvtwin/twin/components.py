"""The twin's own components: what the own ship knows, built from measurements only.

Each is a plain object the runtime calls at its rate; none knows the scheduler, the server
or the recorder, so each runs alone in a test:

- :class:`AisInput` — NMEA lines in, through the real :class:`~asvtwin.sources.ais.AisPipeline`
  (decoding, fragment assembly, validation, error counters), the
  :class:`~asvtwin.sources.ais.TargetRegistry` (dead reckoning, staleness) and the reports
  queued for the tracker;
- :class:`Perception` — LiDAR clusters (coast returns removed) and the multi-target tracker
  (:class:`~asvtwin.tracking.Tracker`), with the ellipses of the last scan;
- :class:`DisturbanceEstimator` — the disturbance observer (d̂ of τ_d) and the actuator
  fault detector on measured velocities;
- :class:`FilterStage` — the predictive safety filter, given the tracker's predictions as
  moving obstacles (never ground truth), the scene's coast near the ship and d̂.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable

import numpy as np

from asvtwin.checks import F8 as _F8
from asvtwin.control import (
    CoastSegments,
    FilterResult,
    MovingObstacles,
    PsfConfig,
    SafetyFilter,
    braking_input,
    covariance_inflation,
    plain_config,
)
from asvtwin.geo import Scene
from asvtwin.observer import DisturbanceObserver, FaultDetector, ResidualModel, SensorNoise
from asvtwin.sensors import LidarScan
from asvtwin.sources.ais import AisPipeline, AisStatic, ReportBatch, TargetRegistry, TargetSnapshot
from asvtwin.tracking import (
    AisMeasurementBatch,
    Clusters,
    EllipseFits,
    Tracker,
    TrackerConfig,
    TrackSnapshot,
    cluster_scan,
    fit_ellipses,
    predictions_for_safety,
)
from asvtwin.tracking.turning import TurnRateEstimator, constant_turn_positions
from asvtwin.vessel import VesselParams

__all__ = ["AisInput", "DisturbanceEstimator", "FilterStage", "Perception", "tracker_config",
           "twin_filter_config"]


def tracker_config(own_length_m: float, full_scale_m: float) -> TrackerConfig:
    """The tracker's settings for an own ship of ``own_length_m``, Froude-scaled below
    full scale (s = own_length_m / full_scale_m, at most 1; s = 1 gives the defaults but
    ``measure_with_dimensions=False``: AIS dimensions only keep new tracks off a known hull).

    The defaults describe full-scale vessels: an acceleration noise q of 0.01 m²/s³, a new
    track's velocity σ of 8 m/s, AIS positions to 5 m. A model-scale scene's vessels are
    1.3 m models in a basin: under Froude similarity (lengths × s, speeds and times × √s)
    an acceleration is unchanged and a spectral density [m²/s³] scales by √s. Unscaled, a
    model target's 25 s prediction grew a clearance circle of about 20 m (70 m for a new
    track) around a 1.3 m hull, and the model-scale crossing fell back on 113 of 400
    filter calls. Scaled: q and the AIS report ageing q × √s, velocity σs (a new track's
    prior, and the bound a LiDAR-only track's σ must settle below before it is confirmed)
    × √s, lengths (AIS position σ, as the twin's transponders are scaled, track
    separation, merge distance, deletion σ) × s. The sensor models (LiDAR, clustering) are the scenario's
    and the chart's error a property of the chart; reporting intervals and coasting times
    are real seconds. None of these change."""
    s = min(1.0, float(own_length_m) / float(full_scale_m))
    # the AIS static reports' length and beam keep new tracks off a known hull, but do not
    # size its LiDAR measurement: that model is over-confident (docs/tracking.md)
    cfg = TrackerConfig(measure_with_dimensions=False)
    if s >= 1.0:
        return cfg
    r = math.sqrt(s)
    ais = dataclasses.replace(cfg.ais, position_std_m=cfg.ais.position_std_m * s,
                              sog_std_m_s=cfg.ais.sog_std_m_s * r,
                              accel_q=cfg.ais.accel_q * r)
    return dataclasses.replace(
        cfg, q=cfg.q * r, init_velocity_std_m_s=cfg.init_velocity_std_m_s * r,
        confirm_velocity_std_m_s=cfg.confirm_velocity_std_m_s * r,
        course_min_speed_m_s=cfg.course_min_speed_m_s * r,
        max_position_std_m=cfg.max_position_std_m * s,
        min_separation_m=cfg.min_separation_m * s, merge_distance_m=cfg.merge_distance_m * s,
        ais=ais)


def twin_filter_config(backend: str = "auto", *, comfort: bool = False) -> PsfConfig:
    """The safety filter's options in the twin (its own ship is the 88 m hull).

    - A retry runs the SQP towards convergence, each iterate judged (``PsfConfig``'s
      default, ten steps at most; one step per retry until 2026-12-07). With one step,
      the full-scale random encounters (240 runs, seeds 1-4 of
      ``random_vessel_cases``) came to 0.652 d_safe at the closest; with ten judged
      steps 0.950, and over 42 hours of the benchmark's dense scene (seeds 7-27, both
      controllers) runs inside d_safe 3 -> 1 and fallbacks 16,740 -> 14,400, the
      collision count the same (1: seed 20 ``los_psf`` before, seed 26 ``rl_psf``
      after), for 17 % of the speed (``realtime_factor`` 70.2 -> 58.2 at seed 7, side
      by side; docs/twin.md, "Safety in dense traffic").
    - HPIPM's tolerance 1e-4, not BALANCE's own: with it, 6 % of the full-scale QPs there
      stopped at the iteration limit and failed; 1e-4 ran the twin 1.09-1.33 times as
      fast at seeds 7, 8, 9, with as many fallbacks within run-to-run spread
      (docs/twin.md, "Speed").
    - HPIPM's SPEED_ABS mode: half the time per solve (5.5 against 12.4 ms median in the
      benchmark scene), the full-scale encounter set and the dense scene as safe
      (docs/twin.md, "Speed", 2026-12-03 afternoon).

    - The plain filter (``asvtwin.control.plain_config``: lag-free plans, no comfort
      pass-through, five cold-start solves, the obstacle margins' slack priced like the
      velocity bounds'), the filter's defaults until 2026-12-07. With the defaults since (docs/psf.md, "The comfort bound by
      default") the twin's options hold the comfort bound in the full-scale encounter
      set (steered yaw 1.017 nu_max,r against 1.257, closest 0.984 d_safe against
      0.999), but over the benchmark's 42 dense hours (seeds 7-27, both controllers)
      they collided twice (seed 16 ``los_psf``, 35.0 m; seed 26 ``rl_psf``, 6.6 m)
      where these collide once (seed 26, 21.3 m), with 14,878 fallbacks against 14,400
      and ``realtime_factor`` median 48.5 against 50.4 (two runs at a time;
      docs/twin.md, "Safety in dense traffic").

    ``comfort=True`` adds the comfort pass-through and prices the yaw rate's slack ten
    times the others' (``yaw_slack_weight=10``). Measured on acados (docs/psf.md, "The
    comfort bound in the twin's filter"): since the pass-through also keeps the last
    certified plan's remainder and offers governed fallback turns, the full-scale
    encounter set's avoidance turns at most 1.038 times ν_max,r instead of 1.26 (no
    case above 1.05 instead of 4), but the twin's benchmark runs near or under its
    ``realtime_factor`` goal of 50 with it (50.9 and 48.3 against 59.4 and 47.3 run
    alternately; 48.6 median of 8 before the pass-through's extension), so it is not the
    default. On IPOPT it was worse than the defaults in every respect measured (before
    that extension).
    """
    return plain_config(backend=backend, qp_tol=1e-4, hpipm_mode="SPEED_ABS",
                        comfort_pass_through=comfort, yaw_slack_weight=10.0 if comfort else 1.0)


class AisInput:
    """AIS as the twin receives it: lines -> reports -> registry and tracker queue.

    Parameters
    ----------
    scene : Scene
        Frame and bounds of the pipeline.
    epoch_unix_s : float
        UNIX time of simulation time 0 [s].
    evict_after_s : float
        A target not heard for this long leaves the registry [s].
    """

    def __init__(self, scene: Scene, *, epoch_unix_s: float, evict_after_s: float = 300.0
                 ) -> None:
        self.epoch_unix_s = float(epoch_unix_s)
        self.pipeline = AisPipeline(scene)
        self.registry = TargetRegistry(epoch_unix_s=epoch_unix_s, evict_after_s=evict_after_s)
        self._pending: list[AisMeasurementBatch] = []
        #: static records (type 5 / 24: length and beam) since the last take_static()
        self._static: list[AisStatic] = []
        self.lines = 0
        self.reports = 0
        self.last_report_t_s = math.nan

    def step(self, t_s: float, lines: list[str]) -> ReportBatch:
        """Take the lines received at ``t_s``; return the accepted reports."""
        self.lines += len(lines)
        batch = self.pipeline.feed_batch(lines, recv_time_s=self.epoch_unix_s + t_s)
        if len(batch) or batch.static:
            self.registry.update_batch(batch)
        if batch.static:
            self._static.extend(batch.static)
        if len(batch):
            self.reports += len(batch)
            self.last_report_t_s = t_s
            self._pending.append(AisMeasurementBatch.from_batch(
                batch, epoch_unix_s=self.epoch_unix_s))
        return batch

    def take(self) -> AisMeasurementBatch | tuple[()]:
        """The reports queued since the last call (for the tracker), as one batch."""
        if not self._pending:
            return ()
        if len(self._pending) == 1:
            out = self._pending[0]
        else:
            cols = {f.name: np.concatenate([getattr(b, f.name) for b in self._pending])
                    for f in dataclasses.fields(AisMeasurementBatch)}
            out = AisMeasurementBatch(**cols)
        self._pending = []
        return out

    def take_static(self) -> list[AisStatic]:
        """The static records (MMSI, length, beam) received since the last call: the
        tracker sizes a tied track's hull from them."""
        out, self._static = self._static, []
        return out

    def targets(self, t_s: float) -> TargetSnapshot:
        """The registry's targets dead-reckoned to ``t_s``."""
        return self.registry.extrapolate(t_s)

    def errors(self) -> dict[str, int]:
        """The pipeline's error counters by kind (read from its counters, not from a whole
        ``stats`` record: this is asked at every snapshot)."""
        return {str(k): int(v) for k, v in self.pipeline.counters.counts.items()}


class Perception:
    """LiDAR segmentation and the tracker (AIS and LiDAR fused)."""

    def __init__(self, scene: Scene | None, config: TrackerConfig | None = None) -> None:
        self.land = scene.land if scene is not None else None
        self.tracker = Tracker(config, self.land)
        self.clusters: Clusters | None = None
        self.tracks: TrackSnapshot = self.tracker.step(0.0)

    def step(self, t_s: float, scan: LidarScan | None,
             ais: AisMeasurementBatch | tuple[()], static: Iterable[AisStatic] = ()) -> TrackSnapshot:
        """Track update at ``t_s`` with the scan taken since the last call (or None), the
        AIS reports and the AIS static records (length and beam by MMSI) since then."""
        if static:
            self.tracker.update_static(static)
        cl = None
        if scan is not None:
            cl = cluster_scan(scan, self.land, self.tracker.config.cluster)
            self.clusters = cl
        self.tracks = self.tracker.step(t_s, cl, ais)
        return self.tracks

    def ellipses(self) -> EllipseFits | None:
        """Ellipse fits of the last scan's clusters (None before the first scan)."""
        cl = self.clusters
        if cl is None or len(cl) == 0:
            return None
        return fit_ellipses(cl.points, cl.offsets)


class DisturbanceEstimator:
    """The disturbance observer and the fault detector on measured ν (with sensor noise).

    Parameters
    ----------
    params : VesselParams
        The own ship.
    dt_s : float
        Sampling period [s].
    rng : numpy.random.Generator
        Draws the velocity sensor noise.
    """

    def __init__(self, params: VesselParams, *, dt_s: float, rng: np.random.Generator) -> None:
        self.params = params
        self.dt_s = float(dt_s)
        self.rng = rng
        self.noise = SensorNoise.for_vessel(params)
        self.observer = DisturbanceObserver(params, 1, dt_s=dt_s)
        self.detector = FaultDetector(
            params, 1, ResidualModel.from_sensor_noise(params, self.noise.sigma_nu, dt_s))
        self.events: list[str] = []
        self.fault_kind: str | None = None
        self.fault_channel: str | None = None
        self.fault_confidence = 0.0
        self.nan_inputs = 0

    @property
    def d_hat(self) -> _F8:
        """d̂ (3,) [N, N, Nm], body frame."""
        return self.observer.estimate[0]

    @property
    def valid(self) -> bool:
        """Whether the last update used a good measurement."""
        return bool(self.observer.valid[0])

    def measure(self, nu: _F8) -> _F8:
        """ν as the velocity sensors report it (truth + white noise)."""
        return nu + np.asarray(self.noise.sigma_nu) * self.rng.standard_normal(3)

    def step(self, t_s: float, nu_meas: _F8, tau: _F8) -> _F8:
        """One sample: measured ν (3,) (NaN = dropout) and the thrust over the step."""
        if not np.isfinite(nu_meas).all() or not np.isfinite(tau).all():
            self.nan_inputs += 1
        self.observer.update(nu_meas[None], tau[None])
        for ev in self.detector.update(t_s, nu_meas[None], tau[None]) or ():
            self.fault_kind = str(getattr(ev, "kind", "fault"))
            self.fault_channel = str(getattr(ev, "dof_name", getattr(ev, "dof", "")))
            self.fault_confidence = float(getattr(ev, "confidence", 1.0))
            self.events.append(f"t={t_s:.1f} s: actuator fault detected: {self.fault_kind} "
                               f"in {self.fault_channel}")
        return self.d_hat


class FilterStage:
    """The predictive safety filter fed from the twin's own picture.

    Parameters
    ----------
    params : VesselParams
    scene : Scene or None
    backend : str
        Safety filter backend (``"auto"``: the fastest installed).
    tracker_q : float
        The tracker's acceleration noise [m²/s³], for the obstacle predictions.
    """

    def __init__(self, params: VesselParams, scene: Scene | None, *, backend: str = "auto",
                 tracker_q: float = 0.01) -> None:
        self.params = params
        self.land = scene.land if scene is not None else None
        self.psf = SafetyFilter(params, config=twin_filter_config(backend))
        cfg = self.psf.config
        self.N, self.dt_s = cfg.N, cfg.dt_s
        self.tracker_q = float(tracker_q)
        self.hull_radius_m = 0.5 * params.length
        self.confidence = 0.95  # probability mass of a track's clearance circle
        self._kappa = float(covariance_inflation(np.eye(2), self.confidence))
        reach = self.N * self.dt_s * float(self.psf.nu_max[0])
        self.coast_radius_m = reach + self.psf.d_safe_m + self.psf.d_f_m
        self.last: FilterResult | None = None
        self.last_t_s = math.nan  # simulation time of the call that gave ``last``
        self.calls = 0
        self.interventions = 0
        self.fallbacks: dict[str, int] = {}
        #: turn rates of the tracks from their course history: a turning track is given
        #: to the filter twice, on its straight (CV) path and on its constant-turn arc
        self.turns = TurnRateEstimator()
        self.turning_tracks = 0  # given on their arc at the last call

    def reset(self) -> None:
        """Forget the last plan and the warm start (the solver itself is kept)."""
        self.psf.reset()
        self.last, self.last_t_s = None, math.nan

    def obstacles(self, t_s: float, x: _F8, tracks: TrackSnapshot
                  ) -> list[MovingObstacles | CoastSegments]:
        """Moving obstacles from the tracker's safety predictions of the confirmed tracks,
        and the coast segments the plan could reach.

        The clearance of each track at each stage is the tracker's
        (:func:`~asvtwin.tracking.predictions_for_safety`): hull radius + κ σ_max of the CV
        prediction's position covariance scaled by the tracker's measured consistency factor
        (:data:`~asvtwin.tracking.COVARIANCE_INFLATION`), κ the 95 % radius of a 2-D Gaussian
        (2.45). The filter takes a hull radius plus a covariance per stage; the clearance is
        passed as the isotropic covariance (σ_eff² I, σ_eff = (clearance − hull)/κ) whose
        95 % inflation gives it back exactly. Tracks keep their ids ("track 2" in the
        filter's explanation). A track whose course turns steadily
        (:class:`~asvtwin.tracking.turning.TurnRateEstimator`) is given twice: on its CV
        path and on its constant-turn arc, with the same clearance."""
        obs: list[MovingObstacles | CoastSegments] = []
        self.turning_tracks = 0
        confirmed = tracks.is_confirmed  # (the rows predictions_for_safety keeps)
        if confirmed.any():
            times = max(t_s, tracks.t_s) + self.dt_s * np.arange(self.N + 1)
            sp = predictions_for_safety(tracks, times, q=self.tracker_q,
                                        k_sigma=self._kappa,
                                        default_hull_radius_m=self.hull_radius_m)
            if len(sp.track_ids):
                pos = sp.positions
                semi = tracks.semi_axes_m[confirmed, 0]
                hull = np.where(np.isnan(semi), self.hull_radius_m, semi)
                gap = np.min(np.hypot(pos[..., 0] - x[0], pos[..., 1] - x[1]), axis=1)
                keep = gap < self.coast_radius_m + sp.clearance_radius_m.max(axis=1)
                rate = self.turns.update(t_s, sp.track_ids, sp.velocity)
                if keep.any():
                    sig = np.maximum(sp.clearance_radius_m[keep] - hull[keep, None],
                                     0.0) / self._kappa
                    cov = sig[..., None, None] ** 2 * np.eye(2)
                    ids = tuple(int(i) for i in sp.track_ids[keep])
                    obs.append(MovingObstacles(
                        positions=pos[keep], radii=hull[keep], covariances=cov,
                        confidence=self.confidence, ids=ids))
                    turning = rate[keep] != 0.0
                    if turning.any():  # the turn beside the straight path (tracking.turning)
                        arc = constant_turn_positions(pos[keep][turning, 0],
                                                      sp.velocity[keep][turning],
                                                      rate[keep][turning], times - times[0],
                                                      max_turn_rad=0.5 * math.pi)
                        obs.append(MovingObstacles(
                            positions=arc, radii=hull[keep][turning],
                            covariances=cov[turning], confidence=self.confidence,
                            ids=tuple(i for i, k in zip(ids, turning, strict=True) if k)))
                        self.turning_tracks = int(turning.sum())
        if self.land is not None:
            segs = self.land.segments_within(x[:2], self.coast_radius_m)
            if len(segs):
                obs.append(CoastSegments(segs))
        return obs

    def step(self, t_s: float, x: _F8, u_L: _F8, tracks: TrackSnapshot, d_hat: _F8
             ) -> FilterResult:
        """u_0 for u_L at state ``x`` (never raises for bad solver luck; raises for bugs)."""
        obs = self.obstacles(t_s, x, tracks)
        d = d_hat if np.isfinite(d_hat).all() else None
        res = self.psf.filter(x, u_L, obs, d, t_s=t_s)
        self.last, self.last_t_s = res, float(t_s)
        self.calls += 1
        if res.intervened:
            self.interventions += 1
        if res.fallback != "none":
            self.fallbacks[res.fallback] = self.fallbacks.get(res.fallback, 0) + 1
        return res

    def emergency(self, t_s: float, x: _F8) -> _F8:
        """The input when the filter itself failed (raised): braking with the yaw rate
        damped (the terminal set's controller), never u_L. Counted as fallback
        ``component_error``."""
        self.fallbacks["component_error"] = self.fallbacks.get("component_error", 0) + 1
        u = braking_input(self.params, x, self.psf.terminal_set.k_r)
        return np.asarray(u, dtype=float).reshape(3)
