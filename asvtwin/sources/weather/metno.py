"""MET Norway Locationforecast 2.0 (compact): a polite live client and an offline replay.

The terms of service of api.met.no (https://api.met.no/doc/TermsOfService) ask for:

- a ``User-Agent`` naming the application and a contact (requests without one get 403);
- at most 4 decimals in ``lat``/``lon``;
- no request before the ``Expires`` time of the last response, and ``If-Modified-Since`` with
  its ``Last-Modified`` (a 304 answer costs nothing);
- backing off on 429 (throttled) and 5xx.

:class:`MetNoClient` does all of that with the standard library (``http.client``), keeps the
last good forecast in memory (and optionally in a cache file), and on any failure returns it
flagged ``stale`` rather than raising: a network error, an HTTP error, a broken status line, a
body cut short, bad gzip, bad UTF-8, a document that is not the compact schema, a body larger
than ``max_body_bytes``, or a server so slow that the whole request exceeds
``total_timeout_s`` (a watchdog closes the socket, so a server trickling a byte a second cannot
hold a fetch, or the event loop's worker thread, for hours). An unreadable cache file is
ignored and an unwritable one only logged. Data: MET Norway, CC BY 4.0 (credit "Data from MET
Norway").

Per the project's network rule nothing here runs in tests or by default: tests point
``base_url`` at a server on 127.0.0.1, and :class:`OfflineWeatherSource` replays the bundled
fixture, which is **synthetic**: a Trondheim forecast authored for this project in the compact
schema (a low passing on 21 Nov 2024), not a recorded response and not MET Norway data. It is
labelled so wherever it is shown (``WeatherForecast.synthetic``, its ``source`` string, the CLI).
"""

from __future__ import annotations

import asyncio
import http.client
import json
import logging
import math
import os
import socket
import threading
import urllib.parse
import urllib.request
import zlib
from collections.abc import AsyncIterator, Callable
from email.utils import parsedate_to_datetime
from importlib import resources
from pathlib import Path

from asvtwin.errors import ConfigError, SourceError
from asvtwin.sources.weather.series import WeatherForecast, WeatherSeries, parse_compact

__all__ = [
    "ATTRIBUTION",
    "FIXTURE_NAME",
    "FIXTURE_SOURCE",
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
#: The bundled fixture (Trondheim, 63.43 N 10.39 E): synthetic, authored for this project.
FIXTURE_NAME = "locationforecast_compact_trondheim_synthetic.json"
#: How the fixture names itself in ``WeatherForecast.source`` (and so on every display).
FIXTURE_SOURCE = ("synthetic fixture (authored for asvtwin in the MET Norway compact schema; "
                  "not a forecast, not MET Norway data)")


class _Failure(Exception):
    """One failed request: ``kind`` for the counters, the message for the log."""

    def __init__(self, kind: str, message: str, retry_after: float | None = None) -> None:
        super().__init__(message)
        self.kind = kind
        self.retry_after = retry_after


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
        Socket timeout of each connect and read [s].
    total_timeout_s : float
        Deadline of a whole request, connect to last byte [s]: a watchdog closes the socket.
    max_body_bytes : int
        Largest response body accepted, after gzip decompression [bytes].
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
                 timeout_s: float = 10.0, total_timeout_s: float = 30.0,
                 max_body_bytes: int = 8 << 20, min_backoff_s: float = 60.0,
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
        parts = urllib.parse.urlsplit(self.url)
        if parts.scheme not in ("http", "https") or not parts.hostname:
            raise ConfigError(f"base_url must be an http(s) URL, actually: {base_url!r}")
        self._parts = parts
        for name, v in (("timeout_s", timeout_s), ("total_timeout_s", total_timeout_s)):
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"{name} must be finite and > 0, actually: {v}")
        if max_body_bytes < 1:
            raise ConfigError(f"max_body_bytes must be >= 1, actually: {max_body_bytes}")
        self.timeout_s = float(timeout_s)
        self.total_timeout_s = float(total_timeout_s)
        self.max_body_bytes = int(max_body_bytes)
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
            last_modified = doc.get("last_modified")
            fetched, expires = doc.get("fetched_unix_s"), doc.get("expires_unix_s")
            if not all(x is None or isinstance(x, (int, float)) for x in (fetched, expires)) \
                    or not (last_modified is None or isinstance(last_modified, str)):
                raise ValueError("fetched_unix_s / expires_unix_s / last_modified mistyped")
        except (OSError, KeyError, TypeError, AttributeError, ValueError, RecursionError,
                SourceError) as exc:
            self.errors["cache_read"] = self.errors.get("cache_read", 0) + 1
            _log.warning("ignoring unreadable weather cache %s: %s", self.cache_path, exc)
            return
        self._last_modified = last_modified
        self._forecast = WeatherForecast(series, "met.no", fetched, expires)

    def _save_cache(self, body: str, fc: WeatherForecast) -> None:
        if self.cache_path is None:
            return
        tmp = self.cache_path.with_suffix(".tmp")
        try:
            tmp.write_text(json.dumps({"body": body, "last_modified": self._last_modified,
                                       "fetched_unix_s": fc.fetched_unix_s,
                                       "expires_unix_s": fc.expires_unix_s}), encoding="utf-8")
            tmp.replace(self.cache_path)
        except OSError as exc:  # the forecast is good; only the cache is lost
            self.errors["cache_write"] = self.errors.get("cache_write", 0) + 1
            log = _log.warning if self.errors["cache_write"] == 1 else _log.debug
            log("cannot write the weather cache %s (%s); continuing without it",
                self.cache_path, exc)

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
        self.requests += 1
        try:
            status, hdrs, body = self._request(headers)
            expires = _http_time(hdrs.get("Expires"))
            if status == 304 and fc is not None:
                self.not_modified += 1
                self._failures = 0
                self._forecast = WeatherForecast(fc.series, "met.no", now, expires, stale=False)
                return self._forecast
            if status == 429 or status >= 500:
                retry = hdrs.get("Retry-After")
                raise _Failure(f"http_{status}", f"HTTP {status} from {self.url}",
                               float(retry) if retry and retry.isdigit() else None)
            if status not in (200, 203):
                hint = " (is the User-Agent accepted?)" if status == 403 else ""
                raise _Failure(f"http_{status}", f"HTTP {status} from {self.url}{hint}")
            if status == 203:
                _log.warning("MET Norway: this product version is deprecated (HTTP 203)")
            try:
                text = body.decode("utf-8")
            except UnicodeDecodeError as exc:
                raise _Failure("bad_response", f"body is not UTF-8 ({exc.reason})") from exc
            try:
                series = parse_compact(text, label=self.url)
            except SourceError as exc:
                raise _Failure("bad_response", str(exc)) from exc
        except _Failure as failure:
            return self._fail(failure.kind, str(failure), now, failure.retry_after)
        self._failures = 0
        self._last_modified = hdrs.get("Last-Modified") or self._last_modified
        self._forecast = WeatherForecast(series, "met.no", now, expires, stale=False)
        self._save_cache(text, self._forecast)
        return self._forecast

    def _connection(self) -> http.client.HTTPConnection:
        u = self._parts
        https = u.scheme == "https"
        host, port = u.hostname or "", u.port or (443 if https else 80)
        cls = http.client.HTTPSConnection if https else http.client.HTTPConnection
        proxy = None
        # a loopback server (tests) is reached directly, never through a proxy
        if host not in ("127.0.0.1", "localhost", "::1"):
            proxy = urllib.request.getproxies().get(u.scheme)
            if proxy and urllib.request.proxy_bypass(host):
                proxy = None
        if proxy:
            p = urllib.parse.urlsplit(proxy if "://" in proxy else f"http://{proxy}")
            conn = cls(p.hostname or "", p.port or 8080, timeout=self.timeout_s)
            conn.set_tunnel(host, port)
            return conn
        return cls(host, port, timeout=self.timeout_s)

    def _request(self, headers: dict[str, str]) -> tuple[int, dict[str, str], bytes]:
        """One GET with a total deadline and a body cap: ``(status, headers, body)``.

        Raises
        ------
        _Failure
            For every way the exchange can fail.
        """
        u = self._parts
        conn = self._connection()
        expired = threading.Event()

        def watchdog() -> None:  # the deadline: unblock whatever read is waiting
            expired.set()
            sock = conn.sock
            if sock is not None:
                try:
                    sock.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass

        timer = threading.Timer(self.total_timeout_s, watchdog)
        timer.daemon = True
        timer.start()
        try:
            conn.request("GET", f"{u.path or '/'}?{u.query}", headers=headers)
            resp = conn.getresponse()
            hdrs = {k.title(): v for k, v in resp.getheaders()}
            raw = bytearray()
            while chunk := resp.read1(65536):
                raw += chunk
                if len(raw) > self.max_body_bytes:
                    raise _Failure("too_large", f"response body larger than "
                                   f"{self.max_body_bytes} bytes from {self.url}")
            if expired.is_set():  # the watchdog cut the socket: whatever came is partial
                raise _Failure("deadline", f"no complete answer within "
                               f"{self.total_timeout_s:g} s from {self.url}")
            declared = hdrs.get("Content-Length")
            if declared is not None and declared.isdigit() and int(declared) != len(raw):
                raise _Failure("incomplete", f"body cut short: {len(raw)} of {declared} bytes")
            body = bytes(raw)
            if hdrs.get("Content-Encoding", "").lower() == "gzip":
                body = self._gunzip(body)
            return resp.status, hdrs, body
        except _Failure:
            raise
        except (OSError, http.client.HTTPException, ValueError) as exc:
            if expired.is_set():
                raise _Failure("deadline", f"no complete answer within "
                               f"{self.total_timeout_s:g} s from {self.url}") from exc
            kind = "network" if isinstance(exc, OSError) else "bad_response"
            raise _Failure(kind, f"{type(exc).__name__}: {exc}") from exc
        finally:
            timer.cancel()
            conn.close()

    def _gunzip(self, data: bytes) -> bytes:
        d = zlib.decompressobj(wbits=31)  # gzip container
        try:
            out = d.decompress(data, self.max_body_bytes + 1)
        except zlib.error as exc:
            raise _Failure("bad_response", f"body is not valid gzip ({exc})") from exc
        if len(out) > self.max_body_bytes:
            raise _Failure("too_large", f"gzip body inflates beyond {self.max_body_bytes} bytes")
        if not d.eof:
            raise _Failure("bad_response", "gzip body cut short")
        return out


class OfflineWeatherSource:
    """A compact-schema document replayed as if it were live (the default weather).

    Parameters
    ----------
    path : path, optional
        A compact-schema JSON file (e.g. a response saved from api.met.no); the bundled
        Trondheim fixture when omitted, which is synthetic (``forecast.synthetic`` is True and
        its ``source`` says so).
    align_to_unix_s : float, optional
        Shift the series so its first step falls at this time (replay at another date).
    """

    def __init__(self, path: str | os.PathLike[str] | None = None, *,
                 align_to_unix_s: float | None = None) -> None:
        if path is None:
            res = resources.files("asvtwin.sources").joinpath("data", FIXTURE_NAME)
            data, label = res.read_bytes(), f"asvtwin/sources/data/{FIXTURE_NAME}"
            source = f"{FIXTURE_SOURCE}: {label}"
        else:
            try:
                data, label = Path(path).read_bytes(), str(path)
            except OSError as exc:
                raise SourceError(f"cannot read weather file {path}: "
                                  f"{exc.strerror or exc}") from exc
            source = f"file:{label}"
        series: WeatherSeries = parse_compact(data, label=label)
        if align_to_unix_s is not None:
            series = series.shifted(align_to_unix_s - series.span_unix_s[0])
        self.forecast = WeatherForecast(series, source, synthetic=path is None)

    def fetch(self) -> WeatherForecast:
        """The replayed forecast (never stale, never expires)."""
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
