"""The environment as a process in time: current, wind and waves, seeded.

Each slowly varying quantity is a constant mean plus a first-order Gauss–Markov process

.. math:: \\dot b = -b / T + w, \\qquad w \\sim \\mathcal N(0, 2\\sigma^2 / T)

discretised exactly: b_{k+1} = e^{-Δt/T} b_k + σ √(1 − e^{-2Δt/T}) ξ_k, so its
stationary standard deviation is σ whatever the step. Every draw comes from the
``numpy.random.Generator`` passed in; the state is a frozen value
(:class:`EnvironmentState`), advanced by :meth:`Environment.advance`.

The field is uniform in space over the scene (the fjord's weather API has a ~1 km grid,
larger than any manoeuvre here); :meth:`Environment.forces` turns it into τ_d for any
number of vessels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from asvtwin.checks import check_positive
from asvtwin.environment.forces import (
    RHO_AIR,
    WindCoefficients,
    _environment_force_batch,
    _packed,
    environment_rows,
)
from asvtwin.errors import ConfigError, StateError
from asvtwin.vessel.params import RHO_SEA, VesselParams

__all__ = [
    "CurrentConfig",
    "Environment",
    "EnvironmentConfig",
    "EnvironmentState",
    "GaussMarkov",
    "WaveConfig",
    "WindConfig",
    "calm_environment",
    "default_environment",
    "gauss_markov_step",
    "wind_vector",
]

G = 9.81


def wind_vector(speed_m_s: float, from_direction_rad: float) -> NDArray[np.float64]:
    """Velocity of the air [N, E] [m/s] for a wind of ``speed`` *from* a direction.

    Meteorological convention (MET Norway's ``wind_from_direction``): a northerly
    (from 0) blows towards the south.
    """
    return -speed_m_s * np.array([math.cos(from_direction_rad), math.sin(from_direction_rad)])


def gauss_markov_step(b: ArrayLike, dt_s: float, T_s: float, sigma: float,
                      rng: np.random.Generator) -> NDArray[np.float64]:
    """Exact discrete step of a first-order Gauss–Markov process (any shape)."""
    b = np.asarray(b, dtype=float)
    if sigma == 0.0:
        return b * math.exp(-dt_s / T_s)
    a = math.exp(-dt_s / T_s)
    return a * b + sigma * math.sqrt(1.0 - a * a) * rng.standard_normal(b.shape)


def _positive(name: str, v: float, lo_open: bool = True) -> None:
    check_positive(v, name, allow_zero=not lo_open, where="environment", error=ConfigError)


@dataclass(frozen=True, slots=True)
class GaussMarkov:
    """Parameters of a first-order Gauss–Markov variation: σ and time constant T [s]."""

    sigma: float = 0.0
    T_s: float = 300.0

    def __post_init__(self) -> None:
        _positive("sigma", self.sigma, lo_open=False)
        _positive("T_s", self.T_s)


@dataclass(frozen=True, slots=True)
class CurrentConfig:
    """Ocean current: mean speed [m/s] towards ``direction_rad`` (NED) plus Gauss–Markov
    variation of each NED component."""

    speed_m_s: float = 0.0
    direction_rad: float = 0.0
    variation: GaussMarkov = GaussMarkov()

    def __post_init__(self) -> None:
        _positive("current.speed_m_s", self.speed_m_s, lo_open=False)


@dataclass(frozen=True, slots=True)
class WindConfig:
    """Mean wind ``speed_m_s`` *from* ``from_direction_rad`` plus gusts (Gauss–Markov on
    each NED component of the air velocity), and the hull's wind coefficients."""

    speed_m_s: float = 0.0
    from_direction_rad: float = 0.0
    gusts: GaussMarkov = GaussMarkov(0.0, 30.0)
    c_x: float = 0.7
    c_y: float = 0.85
    c_n: float = 0.10

    def __post_init__(self) -> None:
        _positive("wind.speed_m_s", self.speed_m_s, lo_open=False)


@dataclass(frozen=True, slots=True)
class WaveConfig:
    """Wave drift: significant wave height [m] travelling towards ``direction_rad``.

    The mean drift force magnitude is ½ ρ g (H_s/2)² L · ``reflection`` (Faltinsen's wall
    formula with a reflection coefficient for a ship-shaped hull), varying slowly with a
    relative Gauss–Markov factor.
    """

    Hs_m: float = 0.0
    direction_rad: float = 0.0
    reflection: float = 0.3
    variation: GaussMarkov = GaussMarkov(0.3, 120.0)

    def __post_init__(self) -> None:
        _positive("waves.Hs_m", self.Hs_m, lo_open=False)
        if not 0.0 <= self.reflection <= 1.0:
            raise ConfigError(f"environment: waves.reflection must be in [0, 1], "
                              f"actually: {self.reflection}")


@dataclass(frozen=True, slots=True)
class EnvironmentConfig:
    """Current, wind and waves of a scene (uniform in space)."""

    current: CurrentConfig = CurrentConfig()
    wind: WindConfig = WindConfig()
    waves: WaveConfig = WaveConfig()

    def froude_scaled(self, scale: float) -> EnvironmentConfig:
        """The same sea state for a vessel ``scale`` times smaller (scale = 1/λ < 1 to go
        from full scale to a model): speeds × √scale, heights × scale, times × √scale."""
        if not (math.isfinite(scale) and scale > 0):
            raise ConfigError(f"environment: scale must be > 0, actually: {scale}")
        s = math.sqrt(scale)

        def gm(g: GaussMarkov, speed: bool) -> GaussMarkov:
            return GaussMarkov(g.sigma * (s if speed else 1.0), g.T_s * s)

        return EnvironmentConfig(
            current=replace(self.current, speed_m_s=self.current.speed_m_s * s,
                            variation=gm(self.current.variation, True)),
            wind=replace(self.wind, speed_m_s=self.wind.speed_m_s * s,
                         gusts=gm(self.wind.gusts, True)),
            waves=replace(self.waves, Hs_m=self.waves.Hs_m * scale,
                          variation=gm(self.waves.variation, False)),
        )


@dataclass(frozen=True, slots=True)
class EnvironmentState:
    """The environment at one instant: plain values.

    current_ned_m_s : (2,) current velocity [m/s]; wind_ned_m_s : (2,) air velocity
    [m/s]; wave_factor : relative drift-force factor (1 + slow variation, >= 0).
    """

    t_s: float
    current_ned_m_s: NDArray[np.float64]
    wind_ned_m_s: NDArray[np.float64]
    wave_factor: float
    _b_current: NDArray[np.float64] = field(repr=False)
    _b_wind: NDArray[np.float64] = field(repr=False)
    _b_wave: float = field(repr=False)


class Environment:
    """Advances an :class:`EnvironmentConfig` in time and computes τ_d for vessels.

    Examples
    --------
    >>> import numpy as np
    >>> from asvtwin.vessel import cybership2_full_scale
    >>> from asvtwin.environment import Environment, default_environment
    >>> p = cybership2_full_scale()
    >>> env = Environment(default_environment(p))
    >>> rng = np.random.default_rng(1)
    >>> s = env.initial_state(rng)
    >>> s = env.advance(s, 1.0, rng)
    >>> env.forces(p, np.zeros((2, 6)), s).shape
    (2, 3)
    """

    def __init__(self, config: EnvironmentConfig) -> None:
        self.config = config
        c = config.current
        self._current_mean = c.speed_m_s * np.array([math.cos(c.direction_rad),
                                                     math.sin(c.direction_rad)])
        self._wind_mean = wind_vector(config.wind.speed_m_s, config.wind.from_direction_rad)
        self._coeff = WindCoefficients(config.wind.c_x, config.wind.c_y, config.wind.c_n)
        # per hull (by identity, parameter sets are immutable): the compiled force's rows
        self._rows: dict[int, tuple[VesselParams, NDArray[np.float64], NDArray[np.float64],
                                    NDArray[np.float64]]] = {}
        # per step length: each process's (e^{-Δt/T}, σ √(1 − e^{-2Δt/T}), draws)
        self._steps: dict[float, tuple[tuple[float, float, bool], ...]] = {}

    @property
    def current_mean_ned_m_s(self) -> NDArray[np.float64]:
        """Mean current velocity [N, E] [m/s] (the state adds the slow variation)."""
        return self._current_mean.copy()

    @property
    def wind_mean_ned_m_s(self) -> NDArray[np.float64]:
        """Mean air velocity [N, E] [m/s] (the state adds the gusts)."""
        return self._wind_mean.copy()

    def _state(self, t: float, bc: NDArray[np.float64], bw: NDArray[np.float64], bz: float
               ) -> EnvironmentState:
        return EnvironmentState(
            t_s=t,
            current_ned_m_s=self._current_mean + bc,
            wind_ned_m_s=self._wind_mean + bw,
            wave_factor=max(0.0, 1.0 + bz),
            _b_current=bc, _b_wind=bw, _b_wave=bz,
        )

    def initial_state(self, rng: np.random.Generator, t_s: float = 0.0) -> EnvironmentState:
        """A state drawn from the processes' stationary distribution."""
        cfg = self.config
        bc = cfg.current.variation.sigma * rng.standard_normal(2)
        bw = cfg.wind.gusts.sigma * rng.standard_normal(2)
        bz = cfg.waves.variation.sigma * float(rng.standard_normal())
        return self._state(t_s, bc, bw, bz)

    def advance(self, state: EnvironmentState, dt_s: float, rng: np.random.Generator
                ) -> EnvironmentState:
        """The state ``dt_s`` seconds later (a new value; ``state`` is unchanged).

        The arithmetic and the draws of :func:`gauss_markov_step` applied to the current
        (2 components), the gusts (2) and the wave factor, in that order, on plain floats:
        one ``standard_normal`` call for all the draws (the generator fills an array with
        the same sequence as successive calls), so the same seed gives the same states."""
        coeffs = self._steps.get(dt_s)
        if coeffs is None:
            cfg = self.config
            coeffs = tuple(
                (a, g.sigma * math.sqrt(1.0 - a * a), g.sigma != 0.0)
                for g in (cfg.current.variation, cfg.wind.gusts, cfg.waves.variation)
                for a in (math.exp(-dt_s / g.T_s),))
            if len(self._steps) >= 16:
                self._steps.clear()
            self._steps[dt_s] = coeffs
        (ac, sc, dc), (aw, sw, dw), (az, sz, dz) = coeffs
        k = 2 * dc + 2 * dw + dz
        xi = rng.standard_normal(k).tolist() if k else []

        def step2(b: NDArray[np.float64], a: float, sig: float, drawn: bool
                  ) -> NDArray[np.float64]:
            if not drawn:
                return b * a
            e0, e1 = xi.pop(0), xi.pop(0)
            return np.array([a * b[0] + sig * e0, a * b[1] + sig * e1])

        bc = step2(state._b_current, ac, sc, dc)
        bw = step2(state._b_wind, aw, sw, dw)
        bz = az * state._b_wave + sz * xi[0] if dz else state._b_wave * az
        return self._state(state.t_s + dt_s, bc, bw, float(bz))

    def wave_drift_magnitude(self, params: VesselParams, state: EnvironmentState) -> float:
        """Drift force magnitude [N]: ½ ρ g (H_s/2)² L · reflection · factor."""
        w = self.config.waves
        rho = params.rho_water if params.rho_water > 0 else RHO_SEA
        return 0.5 * rho * G * (w.Hs_m / 2.0) ** 2 * params.length * w.reflection \
            * state.wave_factor

    def forces(self, params: VesselParams, x: ArrayLike, state: EnvironmentState
               ) -> NDArray[np.float64]:
        """τ_d (n, 3) [N, N, Nm], body frame, for states ``x`` (n, 6): current, wind and
        wave drift in one compiled pass (:func:`~asvtwin.environment.forces.environment_force`,
        the same arithmetic as the sum of the three NumPy force functions)."""
        x = np.ascontiguousarray(np.atleast_2d(np.asarray(x, dtype=np.float64)))
        if x.ndim != 2 or x.shape[1] != 6:
            raise StateError(f"x must have shape (n, 6), actually: {x.shape}")
        rows = self._rows.get(id(params))
        if rows is None or rows[0] is not params:
            w = self.config.waves
            wind, wave = environment_rows(params, self._coeff, RHO_AIR, w.direction_rad, 0.05,
                                          w.Hs_m > 0.0)
            if len(self._rows) >= 16:
                self._rows.clear()
            rows = self._rows[id(params)] = (params, wind, wave, _packed(params))
        F = self.wave_drift_magnitude(params, state) if self.config.waves.Hs_m > 0.0 else 0.0
        out = np.zeros((x.shape[0], 3))
        _environment_force_batch(x, np.ascontiguousarray(state.current_ned_m_s, np.float64),
                                 np.ascontiguousarray(state.wind_ned_m_s, np.float64),
                                 rows[3], rows[1], rows[2], F, out)
        return out


def _full_scale_default() -> EnvironmentConfig:
    """A breezy autumn day in the Trondheim Fjord, full scale: 0.3 m/s tidal current
    towards the north-east, 8 m/s south-westerly wind with gusts, 0.6 m wind sea."""
    return EnvironmentConfig(
        current=CurrentConfig(0.3, math.radians(45.0), GaussMarkov(0.05, 600.0)),
        wind=WindConfig(8.0, math.radians(225.0), GaussMarkov(1.5, 30.0)),
        waves=WaveConfig(0.6, math.radians(45.0), 0.3, GaussMarkov(0.3, 120.0)),
    )


def default_environment(params: VesselParams, *, full_scale_length_m: float | None = None
                        ) -> EnvironmentConfig:
    """The default sea state, Froude-scaled to the vessel.

    The full-scale conditions are for a ship of ``full_scale_length_m`` (default: the
    vessel itself if longer than 20 m, else CyberShip II's 70× prototype, 87.85 m); a
    model-scale vessel gets them Froude-scaled to its length.
    """
    L_full = full_scale_length_m or (params.length if params.length > 20.0 else 87.85)
    cfg = _full_scale_default()
    if params.length >= L_full:
        return cfg
    return cfg.froude_scaled(params.length / L_full)


def calm_environment() -> EnvironmentConfig:
    """No current, no wind, no waves."""
    return EnvironmentConfig()
