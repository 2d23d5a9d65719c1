"""Weather for the twin: MET Norway Locationforecast 2.0 (compact), live or replayed.

The live client (:class:`MetNoClient`) is opt-in and never contacted in tests or by default;
:class:`OfflineWeatherSource` replays the bundled Trondheim fixture.
"""

from __future__ import annotations

from asvtwin.sources.weather.metno import (
    ATTRIBUTION,
    FIXTURE_NAME,
    METNO_COMPACT_URL,
    MetNoClient,
    OfflineWeatherSource,
    weather_updates,
)
from asvtwin.sources.weather.series import (
    EXPECTED_UNITS,
    WeatherForecast,
    WeatherSample,
    WeatherSeries,
    parse_compact,
)

__all__ = [
    "ATTRIBUTION",
    "EXPECTED_UNITS",
    "FIXTURE_NAME",
    "METNO_COMPACT_URL",
    "MetNoClient",
    "OfflineWeatherSource",
    "WeatherForecast",
    "WeatherSample",
    "WeatherSeries",
    "parse_compact",
    "weather_updates",
]
