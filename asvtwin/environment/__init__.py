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
    "Environment",
    "EnvironmentConfig",
    "EnvironmentState",
    "CurrentConfig",
    "WindConfig",
    "WaveConfig",
    "GaussMarkov",
    "default_environment",
    "calm_environment",
    "wind_vector",
    "gauss_markov_step",
    "current_force",
    "wind_force",
    "wave_drift_force",
    "WindCoefficients",
    "RHO_AIR",
]
