"""Seeded closed-loop runs for validating the observer and the fault detector.

:func:`simulate` steps r independent runs at once (one vessel each, batched in the
simulator): a speed-and-heading autopilot follows a seeded schedule of course changes, the
environment (:mod:`asvtwin.environment`, one independent realisation per run) and an
optional test disturbance profile push the hull, actuator faults are injected at given
times, and ν is measured with seeded Gaussian noise. Everything the observer and the
detector need comes back as plain arrays in a :class:`RunResult`.

Scaling: the sampling step, the autopilot's gains, the schedule and the sensor noise are
given at model scale (CyberShip II, L = 1.255 m) and Froude-scaled by λ = L / 1.255
(times × √λ, speeds × √λ, rates ÷ √λ).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from asvtwin.environment import (
    Environment,
    EnvironmentConfig,
    WindCoefficients,
    current_force,
    default_environment,
    gauss_markov_step,
    wave_drift_force,
    wind_force,
)
from asvtwin.errors import ParameterError
from asvtwin.guidance import AutopilotGains, HeadingSpeedAutopilot
from asvtwin.units import wrap_angle
from asvtwin.vessel import BatchSimulator, VesselParams

__all__ = [
    "InjectedFault",
    "RunResult",
    "SensorNoise",
    "default_dt",
    "froude_ratio",
    "simulate",
]

_L_MODEL = 1.255
Profile = Callable[[float], NDArray[np.float64]]

#: Autopilot at model scale: heading natural frequency [rad/s], reference turn rate
#: [rad/s] and time between course changes [s] (Froude-scaled for other vessels).
WN_HEADING = 0.8
TURN_RATE = 0.01
TURN_EVERY_S = 120.0


def froude_ratio(params: VesselParams) -> float:
    """√λ with λ = L / L_CyberShipII: the Froude time (and speed) ratio."""
    return math.sqrt(params.length / _L_MODEL)


def default_dt(params: VesselParams) -> float:
    """Sampling step [s]: 0.1 s at model scale, Froude-scaled (≈ 0.84 s at ×70)."""
    return 0.1 * froude_ratio(params)


@dataclass(frozen=True, slots=True)
class SensorNoise:
    """White Gaussian noise on measured ν: std [m/s, m/s, rad/s]."""

    sigma_nu: tuple[float, float, float]

    def __post_init__(self) -> None:
        vals = tuple(float(v) for v in self.sigma_nu)
        if len(vals) != 3 or any(not (math.isfinite(v) and v >= 0) for v in vals):
            raise ParameterError(f"sigma_nu must be 3 finite values >= 0, actually: "
                                 f"{self.sigma_nu}")
        object.__setattr__(self, "sigma_nu", vals)

    @classmethod
    def for_vessel(cls, params: VesselParams) -> SensorNoise:
        """5 mm/s and 5 mrad/s at model scale (motion-capture velocities), Froude-scaled:
        ≈ 4 cm/s and 0.6 mrad/s at ×70 (GNSS Doppler velocity and a fibre-optic gyro)."""
        f = froude_ratio(params)
        return cls((0.005 * f, 0.005 * f, 0.005 / f))


@dataclass(frozen=True, slots=True)
class InjectedFault:
    """An actuator fault switched on at ``t_s`` in run ``vessel``: thrust reaching the hull
    = gain · actual + bias in ``dof``; ``stuck`` freezes it at its thrust then."""

    t_s: float
    vessel: int
    dof: int
    gain: float = 1.0
    bias: float = 0.0
    stuck: bool = False


@dataclass(frozen=True, slots=True)
class RunResult:
    """Arrays of r runs over T samples (index 0 is the initial sample, t = 0).

    x : (T, r, 6) true states; nu_meas : (T, r, 3) measured ν; tau : (T, r, 3) actual
    (healthy-actuator) thrust applied over the step ending at each sample (row 0 zero);
    tau_applied : (T, r, 3) thrust that reached the hull; tau_d : (T, r, 3) true τ_d
    over that step; t_s : (T,); dt_s; seed.
    """

    t_s: NDArray[np.float64]
    x: NDArray[np.float64]
    nu_meas: NDArray[np.float64]
    tau: NDArray[np.float64]
    tau_applied: NDArray[np.float64]
    tau_d: NDArray[np.float64]
    dt_s: float
    seed: int


class _EnvBatch:
    """r independent realisations of one EnvironmentConfig, advanced together."""

    def __init__(self, params: VesselParams, cfg: EnvironmentConfig, r: int,
                 rng: np.random.Generator) -> None:
        self.p, self.cfg, self.rng = params, cfg, rng
        env = Environment(cfg)
        s0 = env.initial_state(rng)
        self.wave_F = env.wave_drift_magnitude(params, replace(s0, wave_factor=1.0))
        self.cur_mean = env.current_mean_ned_m_s
        self.wind_mean = env.wind_mean_ned_m_s
        self.bc = cfg.current.variation.sigma * rng.standard_normal((r, 2))
        self.bw = cfg.wind.gusts.sigma * rng.standard_normal((r, 2))
        self.bz = cfg.waves.variation.sigma * rng.standard_normal(r)
        w = cfg.wind
        self.coef = WindCoefficients(w.c_x, w.c_y, w.c_n)

    def advance(self, dt: float) -> None:
        c, rng = self.cfg, self.rng
        self.bc = gauss_markov_step(self.bc, dt, c.current.variation.T_s,
                                    c.current.variation.sigma, rng)
        self.bw = gauss_markov_step(self.bw, dt, c.wind.gusts.T_s, c.wind.gusts.sigma, rng)
        self.bz = gauss_markov_step(self.bz, dt, c.waves.variation.T_s,
                                    c.waves.variation.sigma, rng)

    def forces(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        tau = current_force(self.p, x, self.cur_mean + self.bc)
        tau += wind_force(self.p, x, self.wind_mean + self.bw, coefficients=self.coef)
        if self.cfg.waves.Hs_m > 0:
            tau += wave_drift_force(self.p, x, self.wave_F * np.maximum(0.0, 1.0 + self.bz),
                                    self.cfg.waves.direction_rad)
        return tau


def simulate(params: VesselParams, n_runs: int, duration_s: float, *, seed: int,
             dt_s: float | None = None,
             environment: EnvironmentConfig | None | str = "default",
             profile: Profile | None = None, noise: SensorNoise | None = None,
             faults: Sequence[InjectedFault] = (), speed_fraction: float = 0.5,
             turns: bool = True) -> RunResult:
    """Run ``n_runs`` seeded closed-loop runs of ``duration_s`` seconds.

    Parameters
    ----------
    params : VesselParams
    n_runs : int
        Independent runs r (each its own environment realisation and noise).
    duration_s : float
        Length [s].
    seed : int
        Seed of the one ``numpy.random.Generator`` behind every draw.
    dt_s : float, optional
        Step [s]; :func:`default_dt` by default.
    environment : EnvironmentConfig, "default" or None
        "default" is :func:`asvtwin.environment.default_environment` for the vessel;
        None is calm water.
    profile : callable t_s -> (3,) or (r, 3), optional
        An extra, known τ_d [N, N, Nm] (body frame) added to the environment's.
    noise : SensorNoise, optional
        Measurement noise on ν; none by default.
    faults : sequence of InjectedFault
    speed_fraction : float
        Surge speed reference as a fraction of the vessel's top speed (0.57 m/s × √λ).
    turns : bool
        Course changes of 20-60° every 120 s × √λ (seeded), turning at most 0.01 rad/s ÷ √λ; else hold the initial course.
    """
    if n_runs < 1 or not (duration_s > 0):
        raise ParameterError(f"n_runs must be >= 1 and duration_s > 0, actually: "
                             f"{n_runs}, {duration_s}")
    rng = np.random.default_rng(seed)
    f = froude_ratio(params)
    h = default_dt(params) if dt_s is None else float(dt_s)
    T = round(duration_s / h) + 1
    r = n_runs
    if environment == "default":
        environment = default_environment(params)
    env = None if environment is None else _EnvBatch(params, environment, r, rng)  # type: ignore[arg-type]
    u_ref = speed_fraction * 0.57 * f
    # the project's autopilot: surge feed-forward + PI (closed-loop time constant 5 s·√λ),
    # heading PID (critically damped, ω_n 0.8/√λ, integral m_r ω³/10), on measured ν
    r_max = TURN_RATE / f
    autopilot = HeadingSpeedAutopilot(params, AutopilotGains.critically_damped(
        params, WN_HEADING / f, integral=True, speed_time_constant_s=5.0 * f), dt_s=h)
    tau_ff = float(autopilot.surge_feedforward(u_ref)[0])
    psi0 = rng.uniform(-math.pi, math.pi, r)
    x0 = np.zeros((r, 6))
    x0[:, 2] = psi0
    x0[:, 3] = u_ref
    tau0 = np.zeros((r, 3))
    tau0[:, 0] = tau_ff
    sim = BatchSimulator(params, x0, dt_s=h, tau0=tau0)
    psi_ref = psi0.copy()
    psi_target = psi0.copy()
    next_turn = rng.uniform(0.25, 1.0, r) * TURN_EVERY_S * f
    sig = np.zeros(3) if noise is None else np.asarray(noise.sigma_nu)
    out_x = np.empty((T, r, 6))
    out_nm = np.empty((T, r, 3))
    out_t = np.zeros((T, r, 3))
    out_ta = np.zeros((T, r, 3))
    out_d = np.zeros((T, r, 3))
    out_x[0] = x0
    out_nm[0] = x0[:, 3:] + sig * rng.standard_normal((r, 3))
    pending = sorted(faults, key=lambda fl: fl.t_s)
    fi = 0
    for k in range(1, T):
        t = (k - 1) * h
        while fi < len(pending) and pending[fi].t_s <= t + 1e-9:
            fl = pending[fi]
            if fl.stuck:
                sim.stick_actuator(fl.vessel, fl.dof)
            else:
                sim.set_fault(fl.vessel, fl.dof, gain=fl.gain, bias=fl.bias)
            fi += 1
        nm = out_nm[k - 1]
        x = out_x[k - 1]
        if turns:
            due = t >= next_turn
            if due.any():
                step = rng.uniform(math.radians(20), math.radians(60), r) \
                    * rng.choice([-1.0, 1.0], r)
                psi_target = np.where(due, np.asarray(wrap_angle(psi_target + step)),
                                      psi_target)
                next_turn = np.where(due, t + TURN_EVERY_S * f, next_turn)
            # the reference turns towards the target at most r_max
            psi_ref = np.asarray(wrap_angle(psi_ref + np.clip(wrap_angle(psi_target - psi_ref),
                                                   -r_max * h, r_max * h)))
        # true heading, measured ν (conditional-integration anti-windup inside)
        cmd = autopilot.tau(np.column_stack([x[:, :3], nm]), psi_ref, u_ref)
        d = np.zeros((r, 3))
        if env is not None:
            d += env.forces(x)
        if profile is not None:
            d += np.broadcast_to(np.asarray(profile(t), dtype=float), (r, 3))
        xn = sim.step(cmd, d)
        if env is not None:
            env.advance(h)
        out_x[k] = xn
        out_t[k] = sim.thrust
        out_ta[k] = sim.applied_thrust
        out_d[k] = d
        out_nm[k] = xn[:, 3:] + sig * rng.standard_normal((r, 3))
    return RunResult(t_s=np.arange(T, dtype=np.float64) * h, x=out_x, nu_meas=out_nm, tau=out_t,
                     tau_applied=out_ta, tau_d=out_d, dt_s=h, seed=seed)
