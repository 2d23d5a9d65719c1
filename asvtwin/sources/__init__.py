"""Live data for the twin (paper, "Capability Level 1: Descriptive"): AIS and weather.

- :mod:`asvtwin.sources.ais`: NMEA decoding and validation, TCP/UDP/file/synthetic sources,
  the target registry with dead reckoning;
- :mod:`asvtwin.sources.weather`: MET Norway Locationforecast 2.0 (compact), live or replayed;
- :mod:`asvtwin.sources.history`: the store every accepted report and weather sample goes to.

Network rule: live sources are configured by the user; nothing in the default run, the tests
or the benchmarks connects anywhere but 127.0.0.1.
"""

from __future__ import annotations

from asvtwin.sources.ais import (
    AisPipeline,
    AisReport,
    AisSource,
    AisStatic,
    ReportBatch,
    SyntheticTraffic,
    TargetRegistry,
    TargetSnapshot,
    open_ais_source,
)
from asvtwin.sources.history import HistoryStore, SqliteHistory, replay_session
from asvtwin.sources.recorder import HistoryRecorder
from asvtwin.sources.weather import (
    MetNoClient,
    OfflineWeatherSource,
    WeatherForecast,
    WeatherSample,
    WeatherSeries,
)

__all__ = [
    "AisPipeline",
    "AisReport",
    "AisSource",
    "AisStatic",
    "HistoryRecorder",
    "HistoryStore",
    "MetNoClient",
    "OfflineWeatherSource",
    "ReportBatch",
    "SqliteHistory",
    "SyntheticTraffic",
    "TargetRegistry",
    "TargetSnapshot",
    "WeatherForecast",
    "WeatherSample",
    "WeatherSeries",
    "open_ais_source",
    "replay_session",
]
