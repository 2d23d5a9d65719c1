from __future__ import annotations

import argparse
import csv

import pytest

from asvtwin import __version__
from asvtwin.cli import build_parser, main


def _all_commands(parser, prefix=()):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield prefix + (name,)
                yield from _all_commands(sub, prefix + (name,))


def test_version(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert __version__ in capsys.readouterr().out


def test_every_command_has_help(capsys):
    commands = list(_all_commands(build_parser()))
    assert ("sim",) in commands
    for cmd in commands:
        with pytest.raises(SystemExit) as e:
            main([*cmd, "--help"])
        assert e.value.code == 0
        assert "usage: asvtwin" in capsys.readouterr().out


def test_sim_writes_csv_and_png(tmp_path, capsys):
    assert main(["sim", "--vessel", "cybership2", "--manoeuvre", "thrust_step",
                 "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "steady_speed_analytic_m_s" in out and "steady speed, analytic" in out
    rows = list(csv.DictReader((tmp_path / "cybership2_thrust_step.csv").open()))
    assert float(rows[0]["u_m_s"]) == 0.0
    assert float(rows[-1]["u_m_s"]) == pytest.approx(0.5788, abs=2e-3)
    png = (tmp_path / "cybership2_thrust_step.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


def test_sim_rejects_unknown_vessel(capsys):
    with pytest.raises(SystemExit) as e:
        main(["sim", "--vessel", "titanic"])
    assert e.value.code == 2
    assert "invalid choice" in capsys.readouterr().err


def test_sim_in_the_fjord_reports_clearance_and_grounding(tmp_path, capsys):
    # from Trondheim harbour north into open water: clear of the shore
    assert main(["sim", "--scene", "default", "--manoeuvre", "turning_circle",
                 "--out", str(tmp_path), "--no-plot"]) == 0
    out = capsys.readouterr().out
    assert "min_distance_to_shore_m" in out and "aground" not in out
    # heading 120° from the harbour runs onto Brattøra
    assert main(["sim", "--scene", "default", "--manoeuvre", "thrust-step",  # old spelling
                 "--start-heading-deg", "120", "--out", str(tmp_path), "--no-plot"]) == 0
    assert "aground at t =" in capsys.readouterr().out
    rows = list(csv.DictReader(
        (tmp_path / "cybership2_full_scale_thrust_step.csv").open()))
    assert float(rows[-1]["psi_deg"]) == pytest.approx(120.0)
    assert float(rows[-1]["y_m"]) > 0 > float(rows[-1]["x_m"])  # heading south-east


def test_sim_json_has_metrics_notes_and_imo_criteria(tmp_path, capsys):
    import json
    import math

    assert main(["sim", "--vessel", "cybership2", "--manoeuvre", "zigzag",
                 "--surge-fraction", "1", "--no-plot", "--json", "--out", str(tmp_path)]) == 0
    out = json.loads(capsys.readouterr().out)  # stdout is exactly one JSON object
    assert out["vessel"] == "cybership2" and out["length_m"] == 1.255
    assert out["metrics"]["swing_checked"] == 0.0
    assert out["metrics"]["first_overshoot_deg"] is None  # NaN is null, with a reason
    assert "course-unstable" in out["notes"]["first_overshoot_deg"]
    crit = {c["name"]: c for c in out["criteria"]}
    assert crit["first overshoot, 10°/10° zig-zag"]["passed"] is False
    assert math.isclose(crit["initial turning (run to 10° heading change)"]["limit"], 2.5)
    assert out["files"] == [str(tmp_path / "cybership2_zigzag.csv")]
