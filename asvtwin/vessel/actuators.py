"""Astern thrust: the full-scale own ship can go astern, as real supply vessels do.

The paper's RL setting (CyberShip II at model scale) has forward-only surge thrust,
F_u ∈ [0, 2] N, and :func:`asvtwin.vessel.params.cybership2` keeps it. A supply vessel
with controllable-pitch propellers or azimuth thrusters can reverse its thrust, which
gives a stopped ship facing a crossing vessel an escape a forward-only model lacks.
:func:`with_astern` bounds the astern surge thrust by a fraction of the ahead limit.

The fraction is an assumption, not a measured figure for this hull: ducted propellers and
azimuth thrusters of offshore supply vessels deliver roughly half to three quarters of
their ahead bollard pull astern (the nozzle and blade sections are shaped for ahead
flow); :data:`ASTERN_FRACTION` = 0.6 is used. The damping coefficients were identified
going ahead (Skjetne et al. 2004, CyberShip II); the model's |u|-terms are symmetric, so
it uses them astern too: adequate for the low astern speeds a stop or a back-off
reaches, not for sustained astern transits.
"""

from __future__ import annotations

import dataclasses
import math

from asvtwin.errors import ParameterError
from asvtwin.vessel.params import VesselParams, cybership2_full_scale

__all__ = ["ASTERN_FRACTION", "cybership2_full_scale_astern", "with_astern"]

#: Astern surge thrust as a fraction of the ahead limit (an assumption, see above).
ASTERN_FRACTION = 0.6


def with_astern(params: VesselParams, fraction: float = ASTERN_FRACTION) -> VesselParams:
    """The same vessel able to go astern: surge thrust bounded below by
    −``fraction`` × the ahead limit (same lag and rate limit).

    Raises
    ------
    ParameterError
        ``fraction`` outside (0, 1], or no finite positive ahead thrust limit.

    Examples
    --------
    >>> from asvtwin.vessel import cybership2_full_scale
    >>> p = with_astern(cybership2_full_scale())
    >>> round(p.actuators.tau_min[0] / p.actuators.tau_max[0], 2)
    -0.6
    """
    if not (math.isfinite(fraction) and 0.0 < fraction <= 1.0):
        raise ParameterError(f"with_astern: fraction must be in (0, 1], actually: {fraction}")
    act = params.actuators
    if not (math.isfinite(act.tau_max[0]) and act.tau_max[0] > 0):
        raise ParameterError(f"with_astern: vessel {params.name!r} needs a finite positive "
                             f"ahead thrust limit, actually tau_max[0] = {act.tau_max[0]}")
    tau_min = (-fraction * act.tau_max[0], act.tau_min[1], act.tau_min[2])
    return params.replace(actuators=dataclasses.replace(act, tau_min=tau_min))


def cybership2_full_scale_astern() -> VesselParams:
    """The 88 m supply vessel (:func:`cybership2_full_scale`) with astern thrust."""
    return with_astern(cybership2_full_scale())
