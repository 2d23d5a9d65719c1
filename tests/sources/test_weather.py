"""Weather: the compact schema, interpolation, and the polite client against 127.0.0.1."""

from __future__ import annotations

import asyncio
import copy
import gzip
import json
import logging
import math
import threading
from email.utils import formatdate
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources

import numpy as np
import pytest

from asvtwin.errors import ConfigError, SourceError
from asvtwin.sources.weather import (
    FIXTURE_NAME,
    MetNoClient,
    OfflineWeatherSource,
    WeatherSample,
    parse_compact,
    weather_updates,
)

FIXTURE = resources.files("asvtwin.sources").joinpath("data", FIXTURE_NAME).read_text()
UA = "asvtwin-tests/0.1 weather-tests@example.org"


@pytest.fixture(scope="module")
def doc():
    return json.loads(FIXTURE)


def test_fixture_hourly_then_six_hourly(doc) -> None:
    s = parse_compact(doc)
    steps = np.diff(s.t_unix_s)
    switch = int(np.argmax(steps > 3600))  # last hourly step -> first 6-hourly one
    assert np.all(steps[:switch] == 3600) and np.all(steps[switch:] == 21600)
    assert switch == 61 and len(s) == 88
    ts = doc["properties"]["timeseries"]
    first6 = next(i for i, x in enumerate(ts) if "next_1_hours" not in x["data"])
    assert first6 == 61  # 00 UTC: the 6-hourly part starts, next_1_hours is gone
    assert not any("next_1_hours" in x["data"] for x in ts[first6:])
    # precipitation rate: next_1_hours, else next_6_hours / 6, else not available
    assert s.precipitation_mm_h[0] == ts[0]["data"]["next_1_hours"]["details"]["precipitation_amount"]
    six = ts[first6]["data"]["next_6_hours"]["details"]["precipitation_amount"]
    assert s.precipitation_mm_h[first6] == pytest.approx(six / 6)
    assert math.isnan(s.precipitation_mm_h[-1]) and s.symbol_code[-1] is None
    d0 = ts[0]["data"]["instant"]["details"]
    assert s.air_pressure_pa[0] == pytest.approx(d0["air_pressure_at_sea_level"] * 100.0)
    assert s.wind_from_rad[0] == pytest.approx(math.radians(d0["wind_from_direction"]))
    assert s.relative_humidity[0] == pytest.approx(d0["relative_humidity"] / 100.0)
    assert (s.lat_deg, s.lon_deg) == (63.43, 10.39)


def test_interpolation_in_time_and_wind_direction_through_north(doc) -> None:
    d = copy.deepcopy(doc)
    ts = d["properties"]["timeseries"]
    ts[0]["data"]["instant"]["details"].update(wind_from_direction=350.0, air_temperature=2.0,
                                               wind_speed=4.0)
    ts[1]["data"]["instant"]["details"].update(wind_from_direction=10.0, air_temperature=4.0,
                                               wind_speed=6.0)
    s = parse_compact(d)
    mid = s.at(s.t_unix_s[0] + 1800.0)
    assert mid.air_temperature_c == pytest.approx(3.0)
    assert mid.wind_speed_m_s == pytest.approx(5.0)
    assert math.remainder(mid.wind_from_rad, 2 * math.pi) == pytest.approx(0.0, abs=1e-12)
    # clamped beyond the ends, at simulation time
    assert s.at_sim_time(-3600.0, epoch_unix_s=s.t_unix_s[0]).air_temperature_c == 2.0
    assert s.at(s.t_unix_s[-1] + 1e6).t_unix_s == s.t_unix_s[-1] + 1e6
    # the wind blows towards where it does not come from (environment's convention)
    north = WeatherSample(0.0, 10.0, 0.0, None, None, None, None)
    assert north.wind_ned_m_s() == pytest.approx((-10.0, 0.0))
    env = pytest.importorskip("asvtwin.environment")
    if hasattr(env, "wind_vector"):
        assert WeatherSample(0.0, 7.0, 1.0, None, None, None, None).wind_ned_m_s() == \
            pytest.approx(tuple(env.wind_vector(7.0, 1.0)))


def test_schema_errors_name_the_field(doc, caplog) -> None:
    d = copy.deepcopy(doc)
    del d["properties"]["timeseries"][3]["data"]["instant"]
    with pytest.raises(SourceError, match=r"properties\.timeseries\[3\]\.data\.instant"):
        parse_compact(d)
    d = copy.deepcopy(doc)
    d["properties"]["meta"]["units"]["wind_speed"] = "knots"
    with pytest.raises(SourceError, match="wind_speed must be 'm/s', actually: 'knots'"):
        parse_compact(d)
    d = copy.deepcopy(doc)
    d["properties"]["timeseries"][5]["time"] = d["properties"]["timeseries"][4]["time"]
    with pytest.raises(SourceError, match="increase strictly"):
        parse_compact(d)
    with pytest.raises(SourceError, match="not valid JSON"):
        parse_compact("{")
    d = copy.deepcopy(doc)
    d["properties"]["timeseries"][2]["data"]["instant"]["details"]["wind_speed"] = -3.0
    with caplog.at_level(logging.WARNING):
        s = parse_compact(d)
    assert math.isnan(s.wind_speed_m_s[2]) and "wind_speed" in caplog.text
    assert s.at(s.t_unix_s[2]).wind_speed_m_s is not None  # interpolated over the gap


class FakeMet:
    """A Locationforecast stand-in on 127.0.0.1: scripted answers, recorded requests."""

    def __init__(self) -> None:
        self.answers: list[tuple[int, dict[str, str], bytes]] = []
        self.requests: list[tuple[str, dict[str, str]]] = []
        fake = self

        class Handler(BaseHTTPRequestHandler):
            def do_GET(self) -> None:
                fake.requests.append((self.path, dict(self.headers)))
                status, headers, body = fake.answers.pop(0) if fake.answers else (500, {}, b"")
                self.send_response(status)
                for k, v in headers.items():
                    self.send_header(k, v)
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, *args: object) -> None:
                pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}/compact"
        self.thread = threading.Thread(target=self.server.serve_forever, args=(0.05,),
                                       daemon=True)
        self.thread.start()

    def close(self) -> None:
        self.server.shutdown()
        self.server.server_close()


@pytest.fixture
def met():
    server = FakeMet()
    yield server
    server.close()


def ok(now: float, *, max_age: float = 1800.0, gz: bool = False) -> tuple[int, dict, bytes]:
    body = FIXTURE.encode()
    headers = {"Content-Type": "application/json", "Expires": formatdate(now + max_age, usegmt=True),
               "Last-Modified": "Wed, 20 Nov 2024 10:49:28 GMT"}
    if gz:
        body = gzip.compress(body)
        headers["Content-Encoding"] = "gzip"
    return 200, headers, body


def test_client_honours_expires_and_if_modified_since(met) -> None:
    now = [1_732_100_000.0]
    client = MetNoClient(63.430001, 10.38999, user_agent=UA, clock=lambda: now[0],
                         base_url=met.url)
    met.answers.append(ok(now[0], gz=True))
    fc = client.fetch()
    assert not fc.stale and fc.source == "met.no" and len(fc.series) == 88
    path, headers = met.requests[0]
    assert path == "/compact?lat=63.4300&lon=10.3900"
    assert headers["User-Agent"] == UA and "If-Modified-Since" not in headers
    now[0] += 600.0  # before Expires: served from memory
    assert client.fetch() is fc and len(met.requests) == 1
    now[0] += 1300.0  # after Expires: conditional request, 304
    met.answers.append((304, {"Expires": formatdate(now[0] + 1800, usegmt=True)}, b""))
    fc2 = client.fetch()
    assert met.requests[1][1]["If-Modified-Since"] == "Wed, 20 Nov 2024 10:49:28 GMT"
    assert fc2.series is fc.series and not fc2.stale and client.not_modified == 1


def test_client_backs_off_and_keeps_the_last_good_data(met) -> None:
    now = [1_732_100_000.0]
    client = MetNoClient(63.43, 10.39, user_agent=UA, clock=lambda: now[0], base_url=met.url,
                         min_backoff_s=60.0, max_backoff_s=600.0)
    met.answers.append(ok(now[0], max_age=10.0))
    good = client.fetch()
    now[0] += 20.0
    met.answers.append((429, {"Retry-After": "120"}, b""))
    stale = client.fetch()
    assert stale.stale and stale.series is good.series and client.errors == {"http_429": 1}
    now[0] += 100.0  # still backing off (Retry-After 120 s): no request
    assert client.fetch().stale and len(met.requests) == 2
    now[0] += 30.0
    met.answers.append((503, {}, b""))
    assert client.fetch().stale and len(met.requests) == 3
    now[0] += 90.0  # second failure: 120 s backoff (60 doubled)
    assert len(met.requests) == 3 and client.fetch().stale and len(met.requests) == 3
    now[0] += 60.0
    met.answers.append(ok(now[0]))
    assert not client.fetch().stale and len(met.requests) == 4


def test_client_without_any_data_raises_and_checks_its_configuration(met) -> None:
    client = MetNoClient(63.43, 10.39, user_agent=UA, clock=lambda: 1e9, base_url=met.url)
    met.answers.append((503, {}, b""))
    with pytest.raises(SourceError, match="no weather data"):
        client.fetch()
    with pytest.raises(ConfigError, match="User-Agent|user_agent"):
        MetNoClient(63.43, 10.39, user_agent="python-urllib", clock=lambda: 0.0)
    with pytest.raises(ConfigError, match="lat_deg"):
        MetNoClient(95.0, 10.39, user_agent=UA, clock=lambda: 0.0)


def test_cache_file_survives_a_restart(met, tmp_path) -> None:
    now = 1_732_100_000.0
    cache = tmp_path / "met.json"
    a = MetNoClient(63.43, 10.39, user_agent=UA, clock=lambda: now, base_url=met.url,
                    cache_path=cache)
    met.answers.append(ok(now))
    a.fetch()
    b = MetNoClient(63.43, 10.39, user_agent=UA, clock=lambda: now + 60, base_url=met.url,
                    cache_path=cache)
    fc = b.fetch()
    assert len(met.requests) == 1 and len(fc.series) == 88 and not fc.stale


def test_offline_source_and_updates() -> None:
    src = OfflineWeatherSource(align_to_unix_s=1_800_000_000.0)
    assert src.fetch().series.span_unix_s[0] == 1_800_000_000.0
    fc = src.fetch()
    assert fc.synthetic and fc.source.startswith("synthetic fixture")  # never passed as data
    assert "not MET Norway data" in fc.source

    async def run():
        return [fc async for fc in weather_updates(src, clock=lambda: 0.0)]

    (fc,) = asyncio.run(run())
    assert fc is src.forecast
    with pytest.raises(SourceError, match="cannot read weather file"):
        OfflineWeatherSource("/nonexistent/forecast.json")
