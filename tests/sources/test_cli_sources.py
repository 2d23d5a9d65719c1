"""``asvtwin ais ...`` and ``asvtwin weather show`` (offline, or against 127.0.0.1)."""

from __future__ import annotations

import asyncio
import json
import threading
from importlib import resources

import numpy as np
import pytest

from asvtwin.cli import main
from asvtwin.sources.ais import AisPipeline, SyntheticTraffic, default_fleet

SAMPLE = str(resources.files("asvtwin.sources").joinpath("data", "trondheim_synthetic_15min.nmea"))


def test_ais_stats_json(capsys) -> None:
    assert main(["ais", "stats", SAMPLE, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    # the summary counts the whole log: the Hammerfest line is a sixth MMSI, outside the scene
    assert out["mmsis"] == 6 and out["lines"] == 474
    assert "outside_scene" not in out["errors"] and out["errors"]["duplicate"] > 0
    assert out["scene"]["position_reports_outside_scene"] == 1
    assert out["scene"]["position_reports_in_scene"] == out["reports"] - 1
    assert set(out["messages_by_type"]) == {"1", "5", "18", "24"}
    # the span from every tag block, the Hammerfest line (2024-02-14) included
    assert out["time_span"]["first"] == "2024-02-14 01:16:38Z"
    assert main(["ais", "stats", SAMPLE]) == 0
    assert "rejected, by kind" in capsys.readouterr().out
    assert main(["ais", "stats", "/nonexistent.nmea"]) == 2


def test_ais_listen_file_records_history(capsys, tmp_path) -> None:
    db = str(tmp_path / "h.sqlite")
    assert main(["ais", "listen", SAMPLE, "--speed", "0", "--no-live", "--db", db]) == 0
    out = capsys.readouterr().out
    assert "AIS targets" in out and "outside_scene 1" in out
    ferry = default_fleet()[0].mmsi
    assert main(["ais", "history", "--db", db, "--mmsi", str(ferry), "--since",
                 "2024-11-20T11:05Z", "--json"]) == 0
    rows = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert rows and all(r["mmsi"] == ferry for r in rows)
    assert min(r["t_unix_s"] for r in rows) >= 1_732_100_700.0
    assert main(["ais", "history", "--db", db, "--limit", "3"]) == 0
    assert "3 reports" in capsys.readouterr().out
    assert main(["ais", "history", "--db", str(tmp_path / "none.sqlite")]) == 2


def test_ais_listen_synthetic_default(capsys) -> None:
    assert main(["ais", "listen", "synthetic:3", "--speed", "0", "--duration", "300",
                 "--no-live", "--rows", "10"]) == 0
    out = capsys.readouterr().out
    assert "reports" in out and "rejected: none" in out


def test_ais_listen_tcp_on_loopback(capsys) -> None:
    lines = list(SyntheticTraffic(rng=np.random.default_rng(1),
                                  start_unix_s=1_732_100_400).lines(120))
    ready = threading.Event()
    port = {}

    def server() -> None:
        async def handle(reader, writer):
            writer.write(("\n".join(lines) + "\n").encode())
            await writer.drain()
            writer.close()

        async def run():
            srv = await asyncio.start_server(handle, "127.0.0.1", 0)
            port["p"] = srv.sockets[0].getsockname()[1]
            ready.set()
            await asyncio.sleep(3.0)
            srv.close()

        asyncio.run(run())

    t = threading.Thread(target=server, daemon=True)
    t.start()
    assert ready.wait(5.0)
    assert main(["ais", "listen", f"tcp://127.0.0.1:{port['p']}", "--duration", "1.0",
                 "--no-live"]) == 0
    out = capsys.readouterr().out
    expected = len(AisPipeline().feed_batch(lines))
    assert f"reports {expected} " in out and "disconnected" in out


def test_ais_bad_source(capsys) -> None:
    assert main(["ais", "listen", "tcp://127.0.0.1", "--no-live"]) == 2
    assert "port is required" in capsys.readouterr().err  # errors go to stderr


def test_weather_show_offline_and_live_needs_a_user_agent(capsys, monkeypatch) -> None:
    assert main(["weather", "show", "--json", "--hours", "6", "--step", "1"]) == 0
    rows = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert len(rows) == 7 and rows[0]["time"] == "2024-11-20T11:00Z"
    assert rows[0]["wind_speed_m_s"] == pytest.approx(5.3)
    assert rows[0]["synthetic"] is True and "not MET Norway data" in rows[0]["source"]
    assert main(["weather", "show"]) == 0
    out = capsys.readouterr().out
    assert "SYNTHETIC" in out and "not a forecast, not MET Norway data" in out
    assert "CC BY" not in out  # no credit to MET Norway for data it did not make
    monkeypatch.delenv("ASVTWIN_USER_AGENT", raising=False)
    assert main(["weather", "show", "--live"]) == 2  # refused before any connection
    assert "contact" in capsys.readouterr().err  # errors go to stderr
