"""The diagnostic twin (capability level 2): disturbance observer and fault diagnosis.

- :class:`DisturbanceObserver`: batched nonlinear disturbance observer, d̂ of τ_d.
- :class:`FaultDetector`: Kalman residuals + GLR for actuator faults (loss of thrust,
  stuck, bias), thresholds derived from a false-alarm target.
- :mod:`asvtwin.observer.runs`: seeded closed-loop runs; :mod:`asvtwin.observer.report`:
  the validation report.
"""

from asvtwin.observer.calibration import fit_residual_model
from asvtwin.observer.disturbance import (
    GAIN_MIN,
    DisturbanceObserver,
    ObserverGains,
    default_gains,
    gain_range,
)
from asvtwin.observer.faults import (
    DetectorConfig,
    FaultDetector,
    FaultEvent,
    FaultKind,
    ResidualModel,
    default_window_s,
    steady_state_filter,
)
from asvtwin.observer.runs import InjectedFault, RunResult, SensorNoise, simulate

__all__ = [
    "GAIN_MIN",
    "DetectorConfig",
    "DisturbanceObserver",
    "FaultDetector",
    "FaultEvent",
    "FaultKind",
    "InjectedFault",
    "ObserverGains",
    "ResidualModel",
    "RunResult",
    "SensorNoise",
    "default_gains",
    "default_window_s",
    "fit_residual_model",
    "gain_range",
    "simulate",
    "steady_state_filter",
]
