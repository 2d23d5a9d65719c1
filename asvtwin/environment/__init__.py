"""Environmental disturbances τ_d: ocean current, wind, wave drift; seeded processes."""

from asvtwin.environment.disturbances import (
    CurrentConfig,
    Environment,
    EnvironmentConfig,
    EnvironmentState,
    GaussMarkov,
    WaveConfig,
    WindConfig,
    calm_environment,
    default_environment,
    gauss_markov_step,
    wind_vector,
)
from asvtwin.environment.forces import (
    RHO_AIR,
    WindCoefficients,
    current_force,
    wave_drift_force,
    wind_force,
)

__all__ = [
    "RHO_AIR",
    "CurrentConfig",
    "Environment",
    "EnvironmentConfig",
    "EnvironmentState",
    "GaussMarkov",
    "WaveConfig",
    "WindCoefficients",
    "WindConfig",
    "calm_environment",
    "current_force",
    "default_environment",
    "gauss_markov_step",
    "wave_drift_force",
    "wind_force",
    "wind_vector",
]
