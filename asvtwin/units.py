"""Unit conversions at the edges of the twin, one named converter each.

Inside, everything is SI (m, s, rad, N, Nm). Knots, degrees and hPa appear only at the
edges (AIS, weather, the viewer, the CLI) and pass through these functions.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "KNOT_M_S",
    "compass_deg_to_rad",
    "deg_to_rad",
    "hpa_to_pa",
    "knots_to_m_s",
    "m_s_to_knots",
    "pa_to_hpa",
    "rad_to_deg",
    "wrap_angle",
]

#: One international knot in m/s (1852 m per hour).
KNOT_M_S = 1852.0 / 3600.0


def knots_to_m_s(speed_kn: ArrayLike) -> NDArray[np.float64] | float:
    """Convert a speed in knots to m/s."""
    return np.asarray(speed_kn, dtype=float) * KNOT_M_S


def m_s_to_knots(speed_m_s: ArrayLike) -> NDArray[np.float64] | float:
    """Convert a speed in m/s to knots."""
    return np.asarray(speed_m_s, dtype=float) / KNOT_M_S


def deg_to_rad(angle_deg: ArrayLike) -> NDArray[np.float64] | float:
    """Convert degrees to radians."""
    return np.deg2rad(np.asarray(angle_deg, dtype=float))


def rad_to_deg(angle_rad: ArrayLike) -> NDArray[np.float64] | float:
    """Convert radians to degrees."""
    return np.rad2deg(np.asarray(angle_rad, dtype=float))


def wrap_angle(angle_rad: ArrayLike) -> NDArray[np.float64] | float:
    """Wrap an angle to [-pi, pi)."""
    a = np.asarray(angle_rad, dtype=float)
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def compass_deg_to_rad(bearing_deg: ArrayLike) -> NDArray[np.float64] | float:
    """A compass bearing (degrees from north, clockwise; AIS COG/heading) to ψ in radians.

    The NED frame uses the same convention (ψ from north, clockwise positive), so this is
    only the unit change, wrapped to [-pi, pi).
    """
    return wrap_angle(deg_to_rad(bearing_deg))


def hpa_to_pa(p_hpa: ArrayLike) -> NDArray[np.float64] | float:
    """Convert hectopascal to pascal."""
    return np.asarray(p_hpa, dtype=float) * 100.0


def pa_to_hpa(p_pa: ArrayLike) -> NDArray[np.float64] | float:
    """Convert pascal to hectopascal."""
    return np.asarray(p_pa, dtype=float) / 100.0
