"""MET Norway Locationforecast 2.0 (compact): a polite live client and an offline replay.

The terms of service of api.met.no (https://api.met.no/doc/TermsOfService) ask for:

- a ``User-Agent`` naming the application and a contact (requests without one get 403);
- at most 4 decimals in ``lat``/``lon``;
- no request before the ``Expires`` time of the last response, and ``If-Modified-Since`` with
  its ``Last-Modified`` (a 304 answer costs nothing);
- backing off on 429 (throttled) and 5xx.

:class:`MetNoClient` does all of that with the standard library (``urllib``), keeps the last
good forecast in memory (and optionally in a cache file), and on any failure returns it
flagged ``stale`` rather than raising. Data: MET Norway, CC BY 4.0 (credit "Data from MET
Norway"). Per the project's network rule nothing here runs in tests or by default: tests point
``base_url`` at a server on 127.0.0.1, and :class:`OfflineWeatherSource` replays the bundled
Trondheim fixture.
"""

from __future__ import annotations

import asyncio
import gzip
import json
import logging
import math
import os
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import AsyncIterator, Callable
from email.utils import parsedate_to_datetime
from importlib import resources
from pathlib import Path

from asvtwin.errors import ConfigError, SourceError
from asvtwin.sources.weather.series import WeatherForecast, WeatherSeries, parse_compact

__all__ = [
    "ATTRIBUTION",
    "FIXTURE_NAME",
    "METNO_COMPACT_URL",
    "MetNoClient",
    "OfflineWeatherSource",
    "weather_updates",
]

_log = logging.getLogger("asvtwin.sources.weather")

#: The compact product's endpoint (only ever contacted when a user runs with ``--live``).
METNO_COMPACT_URL = "https://api.met.no/weatherapi/locationforecast/2.0/compact"
#: Credit line required by the CC BY 4.0 licence of the data.
ATTRIBUTION = "Weather data from MET Norway (api.met.no), CC BY 4.0"
#: The bundled recorded response (Trondheim, 63.43 N 10.39 E).
FIXTURE_NAME = "locationforecast_compact_trondheim.json"


def _http_time(value: str | None) -> float | None:
    if not value:
        return None
    try:
        return parsedate_to_datetime(value).timestamp()
    except (TypeError, ValueError, IndexError):
        return None


class MetNoClient:
    """Locationforecast 2.0 compact client for one position.

    Parameters
    ----------
    lat_deg, lon_deg : float
        Position [deg]; rounded to 4 decimals as the terms require.
    user_agent : str
        Application name and a contact (an e-mail address or a URL), e.g.
        ``"asvtwin/0.1 https://github.com/you/asvtwin"``.
    clock : callable
        Returns the current UNIX time [s] (the only clock this client reads).
    base_url : str
        Endpoint; tests pass a server on 127.0.0.1.
    timeout_s : float
        Socket timeout of one request [s].
    min_backoff_s, max_backoff_s : float
        First and largest wait after a failed request [s] (doubling in between; a
        ``Retry-After`` header wins when longer).
    cache_path : path, optional
        File keeping the last good response across restarts.

    Raises
    ------
    ConfigError
        If the User-Agent lacks a contact or the position is out of range.
    """

    def __init__(self, lat_deg: float, lon_deg: float, *, user_agent: str,
                 clock: Callable[[], float], base_url: str = METNO_COMPACT_URL,
                 timeout_s: float = 10.0, min_backoff_s: float = 60.0,
                 max_backoff_s: float = 3600.0, cache_path: str | os.PathLike[str] | None = None
                 ) -> None:
        if not (isinstance(user_agent, str) and user_agent.strip()
                and ("@" in user_agent or "http" in user_agent)):
            raise ConfigError("user_agent must name the application and a contact (an e-mail "
                              "address or a URL) as MET Norway's terms require, e.g. "
                              f"'asvtwin/0.1 you@example.com'; actually: {user_agent!r}")
        if not (-90 <= lat_deg <= 90 and -180 <= lon_deg <= 180):
            raise ConfigError(f"lat_deg in [-90, 90] and lon_deg in [-180, 180] expected, "
                              f"actually: {lat_deg}, {lon_deg}")
        self.lat_deg = round(float(lat_deg), 4)
        self.lon_deg = round(float(lon_deg), 4)
        self.user_agent = user_agent.strip()
        self._clock = clock
        self.url = f"{base_url}?lat={self.lat_deg:.4f}&lon={self.lon_deg:.4f}"
        host = urllib.parse.urlsplit(base_url).hostname or ""
        # a loopback server (tests) is reached directly, never through an HTTP proxy
        self._opener = urllib.request.build_opener(urllib.request.ProxyHandler({})) \
            if host in ("127.0.0.1", "localhost", "::1") else urllib.request.build_opener()
        self.timeout_s = float(timeout_s)
        self.min_backoff_s = float(min_backoff_s)
        self.max_backoff_s = float(max_backoff_s)
        self.cache_path = Path(cache_path) if cache_path is not None else None
        self._forecast: WeatherForecast | None = None
        self._last_modified: str | None = None
        self._failures = 0
        self._next_attempt_s = -math.inf
        self.requests = 0
        self.not_modified = 0
        self.errors: dict[str, int] = {}
        self._load_cache()

    # ----------------------------------------------------------------- cache
    def _load_cache(self) -> None:
        if self.cache_path is None or not self.cache_path.exists():
            return
        try:
            doc = json.loads(self.cache_path.read_text(encoding="utf-8"))
            series = parse_compact(doc["body"], label=str(self.cache_path))
        except (OSError, KeyError, ValueError, SourceError) as exc:
            _log.warning("ignoring unreadable weather cache %s: %s", self.cache_path, exc)
            return
        self._last_modified = doc.get("last_modified")
        self._forecast = WeatherForecast(series, "met.no", doc.get("fetched_unix_s"),
                                         doc.get("expires_unix_s"))

    def _save_cache(self, body: str, fc: WeatherForecast) -> None:
        if self.cache_path is None:
            return
        tmp = self.cache_path.with_suffix(".tmp")
        tmp.write_text(json.dumps({"body": body, "last_modified": self._last_modified,
                                   "fetched_unix_s": fc.fetched_unix_s,
                                   "expires_unix_s": fc.expires_unix_s}), encoding="utf-8")
        tmp.replace(self.cache_path)

    # ----------------------------------------------------------------- fetch
    @property
    def forecast(self) -> WeatherForecast | None:
        """The last good forecast, if any."""
        return self._forecast

    def _fail(self, kind: str, message: str, now: float, retry_after: float | None = None
              ) -> WeatherForecast:
        self._failures += 1
        self.errors[kind] = self.errors.get(kind, 0) + 1
        delay = min(self.max_backoff_s, self.min_backoff_s * 2.0 ** (self._failures - 1))
        if retry_after is not None:
            delay = max(delay, min(retry_after, self.max_backoff_s))
        self._next_attempt_s = now + delay
        log = _log.warning if self.errors[kind] == 1 else _log.debug
        log("MET Norway request failed (%s: %s); keeping the last good forecast, next try in "
            "%.0f s", kind, message, delay)
        if self._forecast is None:
            raise SourceError(f"no weather data: {message} (and no earlier forecast to keep)")
        self._forecast = WeatherForecast(self._forecast.series, self._forecast.source,
                                         self._forecast.fetched_unix_s,
                                         self._forecast.expires_unix_s, stale=True)
        return self._forecast

    def fetch(self) -> WeatherForecast:
        """The current forecast: cached until ``Expires``, refreshed politely after.

        Returns
        -------
        WeatherForecast
            Fresh, or the last good one flagged ``stale`` after a failure.

        Raises
        ------
        SourceError
            Only when a request fails and there is no earlier forecast at all.
        """
        now = self._clock()
        fc = self._forecast
        if fc is not None and not fc.stale and fc.expires_unix_s is not None \
                and now < fc.expires_unix_s:
            return fc
        if now < self._next_attempt_s:
            if fc is None:
                raise SourceError("no weather data yet and backing off after a failed request")
            return fc
        headers = {"User-Agent": self.user_agent, "Accept-Encoding": "gzip"}
        if self._last_modified and fc is not None:
            headers["If-Modified-Since"] = self._last_modified
        request = urllib.request.Request(self.url, headers=headers)
        self.requests += 1
        try:
            with self._opener.open(request, timeout=self.timeout_s) as resp:
                status, hdrs, raw = resp.status, resp.headers, resp.read()
        except urllib.error.HTTPError as exc:
            status, hdrs, raw = exc.code, exc.headers, b""
        except (urllib.error.URLError, OSError, TimeoutError) as exc:
            return self._fail("network", str(exc), now)
        expires = _http_time(hdrs.get("Expires"))
        if status == 304 and fc is not None:
            self.not_modified += 1
            self._failures = 0
            self._forecast = WeatherForecast(fc.series, "met.no", now, expires, stale=False)
            return self._forecast
        if status == 429 or status >= 500:
            retry = hdrs.get("Retry-After")
            return self._fail(f"http_{status}", f"HTTP {status} from {self.url}", now,
                              float(retry) if retry and retry.isdigit() else None)
        if status not in (200, 203):
            hint = " (is the User-Agent accepted?)" if status == 403 else ""
            return self._fail(f"http_{status}", f"HTTP {status} from {self.url}{hint}", now)
        if status == 203:
            _log.warning("MET Norway: this product version is deprecated (HTTP 203)")
        if hdrs.get("Content-Encoding", "") == "gzip":
            raw = gzip.decompress(raw)
        body = raw.decode("utf-8")
        try:
            series = parse_compact(body, label=self.url)
        except SourceError as exc:
            return self._fail("bad_response", str(exc), now)
        self._failures = 0
        self._last_modified = hdrs.get("Last-Modified") or self._last_modified
        self._forecast = WeatherForecast(series, "met.no", now, expires, stale=False)
        self._save_cache(body, self._forecast)
        return self._forecast


class OfflineWeatherSource:
    """A recorded compact response replayed as if it were live (the default weather).

    Parameters
    ----------
    path : path, optional
        A compact-schema JSON file; the bundled Trondheim fixture when omitted.
    align_to_unix_s : float, optional
        Shift the series so its first step falls at this time (replay at another date).
    """

    def __init__(self, path: str | os.PathLike[str] | None = None, *,
                 align_to_unix_s: float | None = None) -> None:
        if path is None:
            res = resources.files("asvtwin.sources").joinpath("data", FIXTURE_NAME)
            text, label = res.read_text(encoding="utf-8"), f"asvtwin/sources/data/{FIXTURE_NAME}"
        else:
            try:
                text, label = Path(path).read_text(encoding="utf-8"), str(path)
            except OSError as exc:
                raise SourceError(f"cannot read weather file {path}: {exc}") from exc
        series: WeatherSeries = parse_compact(text, label=label)
        if align_to_unix_s is not None:
            series = series.shifted(align_to_unix_s - series.span_unix_s[0])
        self.forecast = WeatherForecast(series, f"fixture:{label}")

    def fetch(self) -> WeatherForecast:
        """The recorded forecast (never stale, never expires)."""
        return self.forecast


async def weather_updates(source: MetNoClient | OfflineWeatherSource, *,
                          clock: Callable[[], float], min_interval_s: float = 300.0
                          ) -> AsyncIterator[WeatherForecast]:
    """Yield the forecast now and after every refresh, never blocking the event loop.

    The live client runs in a worker thread; between polls it sleeps until the forecast's
    ``Expires`` (at least ``min_interval_s``). An offline source yields once.
    """
    while True:
        fc = await asyncio.to_thread(source.fetch)
        yield fc
        if isinstance(source, OfflineWeatherSource):
            return
        wait = min_interval_s
        if fc.expires_unix_s is not None and not fc.stale:
            wait = max(min_interval_s, fc.expires_unix_s - clock())
        await asyncio.sleep(wait)
