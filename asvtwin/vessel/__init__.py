"""The vessel: 3-DOF model, parameter sets, thruster dynamics, batched simulation."""

from asvtwin.vessel.model import (
    coriolis,
    damping,
    dissipation_margin,
    kinetic_energy,
    rhs,
    rotation,
    state_space,
)
from asvtwin.vessel.params import (
    VESSELS,
    ActuatorParams,
    VesselParams,
    cybership2,
    cybership2_full_scale,
    froude_scale,
    vessel_by_name,
)
from asvtwin.vessel.simulator import BatchSimulator, VesselSimulator

__all__ = [
    "VESSELS",
    "ActuatorParams",
    "BatchSimulator",
    "VesselParams",
    "VesselSimulator",
    "coriolis",
    "cybership2",
    "cybership2_full_scale",
    "damping",
    "dissipation_margin",
    "froude_scale",
    "kinetic_energy",
    "rhs",
    "rotation",
    "state_space",
    "vessel_by_name",
]
