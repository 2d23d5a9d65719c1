"""Weather time series from MET Norway Locationforecast 2.0 (compact), interpolated to any time.

The paper's descriptive twin streams "wind speed, wind direction, temperature, air pressure,
and more". :func:`parse_compact` reads a Locationforecast 2.0 *compact* response (GeoJSON
``Feature``; ``properties.timeseries[]`` with ``data.instant.details``; hourly steps first,
then 6-hourly ones whose ``next_1_hours`` block is missing), checks the units in
``properties.meta.units`` and converts to SI at this edge: wind speed [m/s], wind-from
direction [rad] (meteorological: where the wind comes *from*, clockwise from north), air
temperature [°C], pressure [Pa], relative humidity and cloud cover as fractions [0, 1].

:meth:`WeatherSeries.at` interpolates linearly in time; the wind direction through the wind
vector (so 350° and 10° average to 0°, not 180°). Values out of their physical range become
"not available" (NaN in the arrays, None in a :class:`WeatherSample`), with a warning.
"""

from __future__ import annotations

import json
import logging
import math
from dataclasses import dataclass
from datetime import datetime
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from asvtwin.checks import F8 as _F8
from asvtwin.errors import SourceError
from asvtwin.units import deg_to_rad, hpa_to_pa

__all__ = ["EXPECTED_UNITS", "WeatherForecast", "WeatherSample", "WeatherSeries", "parse_compact"]

_log = logging.getLogger("asvtwin.sources.weather")

#: Units the compact product declares in ``properties.meta.units`` (checked on parse).
EXPECTED_UNITS = {
    "air_pressure_at_sea_level": "hPa",
    "air_temperature": "celsius",
    "cloud_area_fraction": "%",
    "relative_humidity": "%",
    "wind_from_direction": "degrees",
    "wind_speed": "m/s",
}
#: Plausible range of each instant variable, in the product's units.
_RANGES = {
    "wind_speed": (0.0, 100.0),
    "wind_from_direction": (0.0, 360.0),
    "air_temperature": (-80.0, 60.0),
    "air_pressure_at_sea_level": (850.0, 1100.0),
    "relative_humidity": (0.0, 100.0),
    "cloud_area_fraction": (0.0, 100.0),
}


@dataclass(frozen=True, slots=True)
class WeatherSample:
    """Weather at one time; None where not available.

    Attributes
    ----------
    t_unix_s : float
        Valid time [UNIX s].
    wind_speed_m_s : float or None
        10 m wind speed [m/s].
    wind_from_rad : float or None
        Direction the wind comes from [rad], clockwise from north, in [0, 2 pi).
    air_temperature_c : float or None
        2 m air temperature [°C].
    air_pressure_pa : float or None
        Air pressure at sea level [Pa].
    relative_humidity : float or None
        Relative humidity, fraction in [0, 1].
    cloud_fraction : float or None
        Cloud area fraction in [0, 1].
    """

    t_unix_s: float
    wind_speed_m_s: float | None
    wind_from_rad: float | None
    air_temperature_c: float | None
    air_pressure_pa: float | None
    relative_humidity: float | None
    cloud_fraction: float | None

    def wind_ned_m_s(self) -> tuple[float, float] | None:
        """Velocity of the air ``(north, east)`` [m/s], the direction it blows *towards*.

        Same convention as :func:`asvtwin.environment.wind_vector`: a wind from the north
        (0 rad) at 10 m/s is ``(-10, 0)``. None when speed or direction is unknown.
        """
        if self.wind_speed_m_s is None or self.wind_from_rad is None:
            return None
        return (-self.wind_speed_m_s * math.cos(self.wind_from_rad),
                -self.wind_speed_m_s * math.sin(self.wind_from_rad))


def _opt(v: float) -> float | None:
    return None if math.isnan(v) else float(v)


@dataclass(frozen=True)
class WeatherSeries:
    """A forecast as arrays over its valid times (NaN = not available).

    ``precipitation_mm_h`` comes from ``next_1_hours`` where present, else ``next_6_hours``
    divided by 6 (the 6-hourly part of the product), else NaN.
    """

    t_unix_s: _F8
    wind_speed_m_s: _F8
    wind_from_rad: _F8
    air_temperature_c: _F8
    air_pressure_pa: _F8
    relative_humidity: _F8
    cloud_fraction: _F8
    precipitation_mm_h: _F8
    symbol_code: tuple[str | None, ...]
    lat_deg: float
    lon_deg: float
    updated_unix_s: float

    def __len__(self) -> int:
        return int(self.t_unix_s.shape[0])

    @property
    def span_unix_s(self) -> tuple[float, float]:
        """First and last valid time [UNIX s]."""
        return float(self.t_unix_s[0]), float(self.t_unix_s[-1])

    def shifted(self, dt_s: float) -> WeatherSeries:
        """The same series with every time moved by ``dt_s`` [s] (replay at another date)."""
        import dataclasses

        return dataclasses.replace(self, t_unix_s=self.t_unix_s + dt_s,
                                   updated_unix_s=self.updated_unix_s + dt_s)

    def interpolate(self, t_unix_s: ArrayLike) -> dict[str, _F8]:
        """Linear interpolation of every variable at the given times (clamped at the ends).

        Returns
        -------
        dict of ndarray
            Keys as the :class:`WeatherSample` fields; wind direction through the wind vector.
        """
        t = np.asarray(t_unix_s, dtype=np.float64)
        tt = self.t_unix_s
        out = {"t_unix_s": t}
        for name in ("wind_speed_m_s", "air_temperature_c", "air_pressure_pa",
                     "relative_humidity", "cloud_fraction"):
            out[name] = _interp_nan(t, tt, getattr(self, name))
        # direction: interpolate the unit vector of the wind-from direction
        c = _interp_nan(t, tt, np.cos(self.wind_from_rad))
        s = _interp_nan(t, tt, np.sin(self.wind_from_rad))
        ang = np.arctan2(s, c) % (2 * np.pi)
        out["wind_from_rad"] = np.where(np.hypot(c, s) > 1e-9, ang, np.nan)
        return out

    def at(self, t_unix_s: float) -> WeatherSample:
        """The weather at one time [UNIX s] (clamped to the first/last step)."""
        v = self.interpolate(np.array([t_unix_s]))
        return WeatherSample(float(t_unix_s), _opt(v["wind_speed_m_s"][0]),
                             _opt(v["wind_from_rad"][0]), _opt(v["air_temperature_c"][0]),
                             _opt(v["air_pressure_pa"][0]), _opt(v["relative_humidity"][0]),
                             _opt(v["cloud_fraction"][0]))

    def at_sim_time(self, t_s: float, *, epoch_unix_s: float) -> WeatherSample:
        """The weather at simulation time ``t_s`` [s] of a run that started at ``epoch_unix_s``."""
        return self.at(epoch_unix_s + t_s)

    def samples(self) -> list[WeatherSample]:
        """One sample per forecast step (for the history)."""
        return [self.at(float(t)) for t in self.t_unix_s]


def _interp_nan(t: _F8, tt: _F8, y: _F8) -> _F8:
    """np.interp that skips NaN samples (all NaN -> NaN)."""
    ok = ~np.isnan(y)
    if not ok.any():
        return np.full_like(t, np.nan)
    return np.interp(t, tt[ok], y[ok])


@dataclass(frozen=True)
class WeatherForecast:
    """A forecast with its provenance and freshness.

    Attributes
    ----------
    series : WeatherSeries
    source : str
        ``"met.no"``, ``"file:<path>"``, or for the bundled fixture
        ``"synthetic fixture (...): <path>"``.
    fetched_unix_s : float or None
        When it was downloaded (None for a fixture).
    expires_unix_s : float or None
        The server's ``Expires`` [UNIX s]; no new request before it.
    stale : bool
        True when the last request failed and this is the last good data.
    synthetic : bool
        True for data authored for the project (the bundled fixture): not a forecast and not
        MET Norway data; shown as such wherever it is displayed.
    """

    series: WeatherSeries
    source: str
    fetched_unix_s: float | None = None
    expires_unix_s: float | None = None
    stale: bool = False
    synthetic: bool = False


def _iso_to_unix(text: object, field: str, label: str) -> float:
    if not isinstance(text, str):
        raise SourceError(f"{label}: {field} must be an ISO 8601 time string, actually: {text!r}")
    try:
        dt = datetime.fromisoformat(text)
        dt.timestamp()
    except (ValueError, OverflowError, OSError) as exc:
        raise SourceError(f"{label}: {field} must be an ISO 8601 time, actually: {text!r}") from exc
    if dt.tzinfo is None:
        raise SourceError(f"{label}: {field} must carry a time zone (Z), actually: {text!r}")
    return dt.timestamp()


def _get(obj: object, key: str, label: str, path: str) -> Any:
    if not isinstance(obj, dict) or key not in obj:
        what = "missing" if isinstance(obj, dict) else f"{path or 'the document'} is a " \
            f"{type(obj).__name__}, not an object"
        raise SourceError(f"{label}: field {path}.{key} expected in the compact schema, "
                          f"actually {what}")
    return obj[key]


def _dict(obj: object, label: str, path: str) -> dict[str, Any]:
    if not isinstance(obj, dict):
        raise SourceError(f"{label}: {path} must be a JSON object, actually: "
                          f"{type(obj).__name__}")
    return obj


def _number(v: object) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def parse_compact(doc: dict[str, Any] | str | bytes, *, label: str = "<response>"
                  ) -> WeatherSeries:
    """Parse a Locationforecast 2.0 compact document into a :class:`WeatherSeries`.

    Never raises anything but :class:`SourceError`, whatever the input (a server's broken
    answer must not escape as a ``TypeError``).

    Raises
    ------
    SourceError
        Not UTF-8 JSON, not the compact schema (names the missing or mistyped field), wrong
        units, no time steps, or times not strictly increasing.
    """
    try:
        return _parse(doc, label)
    except SourceError:
        raise
    except (TypeError, AttributeError, KeyError, IndexError, ValueError, OverflowError,
            RecursionError) as exc:  # a shape the explicit checks did not foresee
        raise SourceError(f"{label}: not the compact schema ({type(exc).__name__}: "
                          f"{str(exc)[:120]})") from exc


def _parse(doc: dict[str, Any] | str | bytes, label: str) -> WeatherSeries:
    if isinstance(doc, (str, bytes)):
        try:
            doc = json.loads(doc)
        except json.JSONDecodeError as exc:
            raise SourceError(f"{label}: not valid JSON ({exc.msg} at line {exc.lineno})") from exc
        except UnicodeDecodeError as exc:
            raise SourceError(f"{label}: not UTF-8 text ({exc.reason} at byte "
                              f"{exc.start})") from exc
    props = _get(doc, "properties", label, "")
    meta = _get(props, "meta", label, "properties")
    units = _dict(_get(meta, "units", label, "properties.meta"), label, "properties.meta.units")
    for key, unit in EXPECTED_UNITS.items():
        if key in units and units[key] != unit:
            raise SourceError(f"{label}: properties.meta.units.{key} must be {unit!r}, "
                              f"actually: {units[key]!r}")
    updated = _iso_to_unix(_get(meta, "updated_at", label, "properties.meta"),
                           "properties.meta.updated_at", label)
    coords = _get(_get(doc, "geometry", label, ""), "coordinates", label, "geometry")
    if not (isinstance(coords, list) and len(coords) >= 2 and _number(coords[0])
            and _number(coords[1]) and -180 <= coords[0] <= 180 and -90 <= coords[1] <= 90):
        raise SourceError(f"{label}: geometry.coordinates must be [lon, lat(, height)] in "
                          f"degrees, actually: {str(coords)[:80]}")
    steps = _get(props, "timeseries", label, "properties")
    if not isinstance(steps, list) or not steps:
        raise SourceError(f"{label}: properties.timeseries must be a non-empty list, "
                          f"actually: {type(steps).__name__} of length "
                          f"{len(steps) if isinstance(steps, list) else 0}")
    n = len(steps)
    times = np.empty(n)
    cols = {k: np.full(n, np.nan) for k in _RANGES}
    precip = np.full(n, np.nan)
    symbols: list[str | None] = []
    for i, step in enumerate(steps):
        path = f"properties.timeseries[{i}]"
        times[i] = _iso_to_unix(_get(step, "time", label, path), f"{path}.time", label)
        data = _dict(_get(step, "data", label, path), label, f"{path}.data")
        details = _dict(_get(_get(data, "instant", label, f"{path}.data"), "details", label,
                             f"{path}.data.instant"), label, f"{path}.data.instant.details")
        for key, (lo, hi) in _RANGES.items():
            v: Any = details.get(key)
            if v is None:
                continue
            if not _number(v) or not lo <= v <= hi:
                _log.warning("%s: %s.data.instant.details.%s must be a number in [%g, %g], "
                             "actually %r: treated as not available", label, path, key, lo, hi,
                             v)
                continue
            cols[key][i] = float(v)
        symbol = None
        for block, hours in (("next_1_hours", 1.0), ("next_6_hours", 6.0)):
            nb = data.get(block)
            if isinstance(nb, dict):
                det = nb.get("details")
                amount: Any = det.get("precipitation_amount") if isinstance(det, dict) else None
                if _number(amount) and amount >= 0 and np.isnan(precip[i]):
                    precip[i] = float(amount) / hours
                summ = nb.get("summary")
                code = summ.get("symbol_code") if isinstance(summ, dict) else None
                symbol = symbol or (code if isinstance(code, str) else None)
        symbols.append(symbol)
    if np.any(np.diff(times) <= 0):
        bad = int(np.argmax(np.diff(times) <= 0)) + 1
        raise SourceError(f"{label}: properties.timeseries times must increase strictly, "
                          f"actually step {bad} is not after step {bad - 1}")
    return WeatherSeries(
        t_unix_s=times, wind_speed_m_s=cols["wind_speed"],
        wind_from_rad=np.asarray(deg_to_rad(cols["wind_from_direction"])) % (2 * np.pi),
        air_temperature_c=cols["air_temperature"],
        air_pressure_pa=np.asarray(hpa_to_pa(cols["air_pressure_at_sea_level"])),
        relative_humidity=cols["relative_humidity"] / 100.0,
        cloud_fraction=cols["cloud_area_fraction"] / 100.0,
        precipitation_mm_h=precip, symbol_code=tuple(symbols),
        lat_deg=float(coords[1]), lon_deg=float(coords[0]), updated_unix_s=updated,
    )
