"""WGS84 geodetic coordinates <-> the local North-East-Down tangent plane of a scene.

Inside the twin every position is a pair ``(north_m, east_m)`` in the tangent plane that
touches the WGS84 ellipsoid at the scene origin (Fossen's NED frame, x north, y east, z down).
Latitude and longitude appear only at the edges (AIS, the viewer, scene files) and pass
through :class:`LocalFrame`.

The mapping is exact, not a flat-earth approximation. A point on the ellipsoid surface
(height ``h = 0``) is converted to Earth-centred Earth-fixed (ECEF) coordinates, the origin's
ECEF position is subtracted and the difference is rotated into NED:

.. math::

    \\begin{bmatrix} n \\\\ e \\\\ d \\end{bmatrix}
    = R_{ned}^{ecef}(\\varphi_0, \\lambda_0)^\\top \\,(p_{ecef}(\\varphi, \\lambda, 0)
      - p_{ecef}(\\varphi_0, \\lambda_0, 0))

and ``(n, e)`` are kept; ``d`` (the drop of the ellipsoid below the plane, about 125 m at
40 km) is discarded. This matches ``pymap3d.geodetic2ned(lat, lon, 0, lat0, lon0, 0)`` to
floating-point precision.

The inverse is closed form: the point ``(n, e)`` of the plane is moved along the plane's
normal (the origin's "down" direction ``u_d``) until it meets the ellipsoid,

.. math::

    p(d) = p_0 + n\\,u_n + e\\,u_e + d\\,u_d, \\qquad
    \\frac{p_x^2 + p_y^2}{a^2} + \\frac{p_z^2}{b^2} = 1,

a quadratic in ``d`` whose small root is taken in the cancellation-free form
``d = -C / (B + sign(B) sqrt(B^2 - A C))``. For a point on the surface the geodetic latitude is
then exact, ``tan(phi) = z / ((1 - e^2) sqrt(x^2 + y^2))``, so no iteration is needed and
``to_ned(*to_wgs84(n, e)) == (n, e)`` to about 1e-9 m.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from asvtwin.errors import ParameterError

__all__ = ["WGS84_A_M", "WGS84_F", "LocalFrame"]

#: WGS84 semi-major axis [m].
WGS84_A_M = 6378137.0
#: WGS84 flattening [-].
WGS84_F = 1.0 / 298.257223563
_B = WGS84_A_M * (1.0 - WGS84_F)  # semi-minor axis [m]
_E2 = WGS84_F * (2.0 - WGS84_F)  # first eccentricity squared [-]


def _ecef_surface(
    lat_rad: NDArray[np.float64], lon_rad: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """ECEF coordinates [m] of points on the ellipsoid surface (h = 0)."""
    sin_lat = np.sin(lat_rad)
    cos_lat = np.cos(lat_rad)
    n_prime = WGS84_A_M / np.sqrt(1.0 - _E2 * sin_lat * sin_lat)  # prime vertical radius
    x = n_prime * cos_lat * np.cos(lon_rad)
    y = n_prime * cos_lat * np.sin(lon_rad)
    z = n_prime * (1.0 - _E2) * sin_lat
    return x, y, z


def _is_real(value: object) -> bool:
    """True for real numbers (int, float, numpy scalars), False for bool and the rest."""
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


@dataclass(frozen=True)
class LocalFrame:
    """Local NED tangent plane anchored at a WGS84 origin on the ellipsoid (h = 0).

    Parameters
    ----------
    lat0_deg : float
        Geodetic latitude of the origin [deg], in the open interval (-90, 90).
    lon0_deg : float
        Longitude of the origin [deg], in [-180, 180].

    Raises
    ------
    ParameterError
        If the origin is not finite or out of range.

    Examples
    --------
    >>> frame = LocalFrame(63.45, 10.40)
    >>> north_m, east_m = frame.to_ned(63.46, 10.40)
    >>> round(float(north_m), 1), abs(round(float(east_m), 6))
    (1114.7, 0.0)
    >>> lat, lon = frame.to_wgs84(north_m, east_m)
    >>> round(float(lat), 9), round(float(lon), 9)
    (63.46, 10.4)
    """

    lat0_deg: float
    lon0_deg: float
    _p0: tuple[float, float, float] = field(init=False, repr=False, compare=False)
    _rot: tuple[tuple[float, float, float], ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        lat0, lon0 = self.lat0_deg, self.lon0_deg
        if not _is_real(lat0) or not math.isfinite(lat0) or not -90 < lat0 < 90:
            raise ParameterError(
                f"lat0_deg must be a finite number in (-90, 90), actually: {lat0!r}"
            )
        if not _is_real(lon0) or not math.isfinite(lon0) or not -180 <= lon0 <= 180:
            raise ParameterError(
                f"lon0_deg must be a finite number in [-180, 180], actually: {lon0!r}"
            )
        object.__setattr__(self, "lat0_deg", float(lat0))
        object.__setattr__(self, "lon0_deg", float(lon0))
        phi, lam = math.radians(lat0), math.radians(lon0)
        x0, y0, z0 = _ecef_surface(np.array(phi), np.array(lam))
        object.__setattr__(self, "_p0", (float(x0), float(y0), float(z0)))
        sp, cp, sl, cl = math.sin(phi), math.cos(phi), math.sin(lam), math.cos(lam)
        # Rows are the NED unit vectors expressed in ECEF.
        rot = (
            (-sp * cl, -sp * sl, cp),  # north
            (-sl, cl, 0.0),  # east
            (-cp * cl, -cp * sl, -sp),  # down
        )
        object.__setattr__(self, "_rot", rot)

    def to_ned(
        self, lat_deg: ArrayLike, lon_deg: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Project WGS84 positions on the ellipsoid onto the local tangent plane.

        Parameters
        ----------
        lat_deg : array_like
            Geodetic latitude [deg], any shape broadcastable with `lon_deg`.
        lon_deg : array_like
            Longitude [deg].

        Returns
        -------
        north_m, east_m : ndarray
            Position in the local NED frame [m], broadcast shape of the inputs
            (0-d arrays for scalar inputs).
        """
        lat = np.radians(np.asarray(lat_deg, dtype=np.float64))
        lon = np.radians(np.asarray(lon_deg, dtype=np.float64))
        x, y, z = _ecef_surface(lat, lon)
        dx, dy, dz = x - self._p0[0], y - self._p0[1], z - self._p0[2]
        rn, re = self._rot[0], self._rot[1]
        north = rn[0] * dx + rn[1] * dy + rn[2] * dz
        east = re[0] * dx + re[1] * dy
        return north, east

    def to_wgs84(
        self, north_m: ArrayLike, east_m: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Map tangent-plane positions back to WGS84 latitude/longitude on the ellipsoid.

        The plane point is moved along the origin's down axis onto the ellipsoid (closed-form
        quadratic, see the module docstring), then converted to geodetic coordinates exactly.

        Parameters
        ----------
        north_m, east_m : array_like
            Position in the local NED frame [m], broadcastable shapes. Valid up to a few
            hundred kilometres from the origin.

        Returns
        -------
        lat_deg, lon_deg : ndarray
            Geodetic latitude and longitude [deg], longitude wrapped to [-180, 180).
        """
        n = np.asarray(north_m, dtype=np.float64)
        e = np.asarray(east_m, dtype=np.float64)
        rn, re, rd = self._rot
        a = WGS84_A_M
        # Work in units of the semi-major axis to keep the quadratic well scaled.
        px = (self._p0[0] + rn[0] * n + re[0] * e) / a
        py = (self._p0[1] + rn[1] * n + re[1] * e) / a
        pz = (self._p0[2] + rn[2] * n + re[2] * e) / a
        k = (a / _B) ** 2  # weight of z in the scaled ellipsoid x^2 + y^2 + k z^2 = 1
        # A d^2 + 2 B d + C = 0 with d the (scaled) step along the down axis.
        qa = rd[0] ** 2 + rd[1] ** 2 + k * rd[2] ** 2
        qb = px * rd[0] + py * rd[1] + k * pz * rd[2]
        qc = px * px + py * py + k * pz * pz - 1.0
        disc = np.sqrt(np.maximum(qb * qb - qa * qc, 0.0))
        d = -qc / (qb + np.copysign(disc, qb))
        x = px + d * rd[0]
        y = py + d * rd[1]
        z = pz + d * rd[2]
        lat = np.arctan2(z, (1.0 - _E2) * np.hypot(x, y))  # exact for h = 0
        lon = np.arctan2(y, x)
        lon_deg = (np.degrees(lon) + 180.0) % 360.0 - 180.0
        return np.degrees(lat), lon_deg

    def points_to_ned(self, lonlat_deg: ArrayLike) -> NDArray[np.float64]:
        """Convert an (n, 2) array of ``(lon, lat)`` [deg] (GeoJSON order) to (n, 2) NED [m].

        Parameters
        ----------
        lonlat_deg : array_like, shape (n, 2)
            Longitude, latitude pairs [deg] as in GeoJSON.

        Returns
        -------
        ndarray, shape (n, 2)
            ``(north_m, east_m)`` rows.
        """
        ll = np.asarray(lonlat_deg, dtype=np.float64).reshape(-1, 2)
        north, east = self.to_ned(ll[:, 1], ll[:, 0])
        return np.column_stack([north, east])

    def points_to_lonlat(self, ned_m: ArrayLike) -> NDArray[np.float64]:
        """Convert an (n, 2) array of ``(north_m, east_m)`` to (n, 2) ``(lon, lat)`` [deg].

        Parameters
        ----------
        ned_m : array_like, shape (n, 2)
            Positions in the local NED frame [m].

        Returns
        -------
        ndarray, shape (n, 2)
            ``(lon_deg, lat_deg)`` rows, GeoJSON order.
        """
        p = np.asarray(ned_m, dtype=np.float64).reshape(-1, 2)
        lat, lon = self.to_wgs84(p[:, 0], p[:, 1])
        return np.column_stack([lon, lat])
