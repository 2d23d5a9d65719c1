"""The MET Norway client against broken servers on 127.0.0.1 (issue items 16-17): every
malformed answer gives the last good forecast flagged stale (or SourceError when there is
none), never a raw exception; a trickling server and a huge body are cut off."""

from __future__ import annotations

import gzip
import json
import socket
import threading
import time
from collections.abc import Callable
from importlib import resources

import pytest

from asvtwin.cli import main
from asvtwin.errors import SourceError
from asvtwin.sources.weather import FIXTURE_NAME, MetNoClient, parse_compact

FIXTURE = resources.files("asvtwin.sources").joinpath("data", FIXTURE_NAME).read_bytes()
UA = "asvtwin-tests/1.0 tests@example.com"
NOW = 1_732_100_000.0


class RawServer:
    """A TCP server on 127.0.0.1 that answers each request with ``respond(conn)``: any bytes,
    at any pace, including ones no HTTP server would send."""

    def __init__(self, respond: Callable[[socket.socket], None]) -> None:
        self.respond = respond
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.url = f"http://127.0.0.1:{self.sock.getsockname()[1]}/compact"
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            with conn:
                data = b""
                while b"\r\n\r\n" not in data:
                    chunk = conn.recv(4096)
                    if not chunk:
                        break
                    data += chunk
                try:
                    self.respond(conn)
                except OSError:
                    pass

    def close(self) -> None:
        self.sock.close()


def http(body: bytes, *, status: str = "200 OK", headers: dict[str, str] | None = None,
         length: int | None = None) -> Callable[[socket.socket], None]:
    def respond(conn: socket.socket) -> None:
        h = {"Content-Type": "application/json",
             "Content-Length": str(len(body) if length is None else length)} | (headers or {})
        head = f"HTTP/1.1 {status}\r\n" + "".join(f"{k}: {v}\r\n" for k, v in h.items())
        conn.sendall(head.encode() + b"\r\n" + body)

    return respond


def _doc(edit: Callable[[dict], None]) -> bytes:
    d = json.loads(FIXTURE)
    edit(d)
    return json.dumps(d).encode()


def _set(path: str, value: object) -> Callable[[dict], None]:
    def edit(d: dict) -> None:
        *keys, last = path.split(".")
        for k in keys:
            d = d[int(k)] if k.isdigit() else d[k]
        d[last] = value

    return edit


MALFORMED = {
    "units_not_a_dict": http(_doc(_set("properties.meta.units", 5))),
    "short_coordinates": http(_doc(_set("geometry.coordinates", [10.39]))),
    "details_a_list": http(_doc(_set("properties.timeseries.3.data.instant.details", [1, 2]))),
    "data_a_string": http(_doc(_set("properties.timeseries.0.data", "sunny"))),
    "bad_gzip": http(b"\x1f\x8b\x08\x00garbage-not-deflate", headers={"Content-Encoding": "gzip"}),
    "bad_utf8": http(b'{"type": "Feature", "x": "\xff\xfe"}'),
    "incomplete_body": http(FIXTURE[:500], length=len(FIXTURE)),
    "bad_status_line": lambda conn: conn.sendall(b"HTTP/1.1 two hundred\r\n\r\n"),
    "not_http_at_all": lambda conn: conn.sendall(b"SSH-2.0-OpenSSH_9.6\r\n"),
    "truncated_gzip": http(gzip.compress(FIXTURE)[:300], headers={"Content-Encoding": "gzip"}),
    "json_nan_and_deep_nesting": http(b"[" * 100_000 + b"]" * 100_000),
}


def _good_cache(tmp_path) -> str:
    path = tmp_path / "cache.json"
    path.write_text(json.dumps({"body": FIXTURE.decode(), "last_modified": None,
                                "fetched_unix_s": NOW - 7200, "expires_unix_s": NOW - 3600}))
    return str(path)


@pytest.mark.parametrize("kind", sorted(MALFORMED))
def test_a_malformed_answer_gives_the_last_good_forecast_flagged_stale(kind, tmp_path) -> None:
    """Before: 8 of these raised raw exceptions (TypeError, AttributeError, BadGzipFile,
    UnicodeDecodeError, IncompleteRead, BadStatusLine, ...) despite holding a good forecast."""
    server = RawServer(MALFORMED[kind])
    try:
        client = MetNoClient(63.43, 10.39, user_agent=UA, clock=lambda: NOW,
                             base_url=server.url, cache_path=_good_cache(tmp_path),
                             total_timeout_s=5.0)
        fc = client.fetch()
        assert fc.stale and len(fc.series) == 88 and sum(client.errors.values()) == 1
        fresh = MetNoClient(63.43, 10.39, user_agent=UA, clock=lambda: NOW, base_url=server.url,
                            total_timeout_s=5.0)
        with pytest.raises(SourceError, match="no weather data"):
            fresh.fetch()  # nothing to fall back on: the documented SourceError, nothing else
    finally:
        server.close()


def test_corrupt_or_unwritable_cache_never_raises(tmp_path) -> None:
    server = RawServer(http(FIXTURE, headers={"Expires": "Wed, 20 Nov 2024 12:00:00 GMT"}))
    try:
        for content in ('{"body": 5}', "[]", '{"body": "{}", "fetched_unix_s": "x"}', "\xff",
                        '{"body": ' + json.dumps(FIXTURE.decode()) + ', "expires_unix_s": []}'):
            bad = tmp_path / "bad.json"
            bad.write_text(content, encoding="latin-1")
            client = MetNoClient(63.43, 10.39, user_agent=UA, clock=lambda: NOW,
                                 base_url=server.url, cache_path=bad)
            assert client.forecast is None and client.errors == {"cache_read": 1}
        # the cache path is a directory: the forecast is good, only the cache is lost
        client = MetNoClient(63.43, 10.39, user_agent=UA, clock=lambda: NOW,
                             base_url=server.url, cache_path=tmp_path)
        fc = client.fetch()
        assert not fc.stale and client.errors == {"cache_read": 1, "cache_write": 1}
    finally:
        server.close()


def test_a_trickling_server_is_cut_off_at_the_deadline() -> None:
    """Before: a server sending 1 byte/s held a fetch (and asyncio.run) for hours."""
    stop = threading.Event()

    def trickle(conn: socket.socket) -> None:
        for b in (b"HTTP/1.1 200 OK\r\nContent-Length: 100000\r\n\r\n" + FIXTURE):
            if stop.is_set():
                return
            conn.sendall(bytes([b]))
            time.sleep(0.05)

    server = RawServer(trickle)
    try:
        client = MetNoClient(63.43, 10.39, user_agent=UA, clock=lambda: NOW,
                             base_url=server.url, timeout_s=1.0, total_timeout_s=1.5)
        t0 = time.perf_counter()
        with pytest.raises(SourceError, match="no complete answer within 1.5 s"):
            client.fetch()
        assert time.perf_counter() - t0 < 3.0 and client.errors == {"deadline": 1}
    finally:
        stop.set()
        server.close()


def test_a_huge_body_is_capped() -> None:
    """Before: a 200 MB body was read whole. Here 64 MB is refused after the 1 MB cap,
    and a gzip body inflating beyond the cap too."""
    def huge(conn: socket.socket) -> None:
        conn.sendall(b"HTTP/1.1 200 OK\r\nContent-Length: 67108864\r\n\r\n")
        block = b" " * 65536
        for _ in range(1024):
            conn.sendall(block)

    bomb = gzip.compress(b" " * (16 << 20))
    for respond in (huge, http(bomb, headers={"Content-Encoding": "gzip"})):
        server = RawServer(respond)
        try:
            client = MetNoClient(63.43, 10.39, user_agent=UA, clock=lambda: NOW,
                                 base_url=server.url, max_body_bytes=1 << 20)
            with pytest.raises(SourceError, match="larger than|inflates beyond"):
                client.fetch()
            assert client.errors == {"too_large": 1}
        finally:
            server.close()


def test_weather_show_file_errors_are_one_line(tmp_path, capsys) -> None:
    for content in (b"{", b'{"properties": []}', b"\xff\xfe", _doc(_set("geometry", None))):
        f = tmp_path / "w.json"
        f.write_bytes(content)
        assert main(["weather", "show", "--file", str(f)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err and str(f) in err
    assert main(["weather", "show", "--file", str(tmp_path / "missing.json")]) == 2
    assert "missing.json" in capsys.readouterr().err


def test_parse_compact_only_ever_raises_source_error() -> None:
    for doc in (None, 5, [], {"properties": 5}, {"properties": {"meta": []}}, "[1, 2",
                b"\x80", {"geometry": {"coordinates": "x"}}):
        with pytest.raises(SourceError):
            parse_compact(doc)  # type: ignore[arg-type]
