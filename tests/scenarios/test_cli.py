"""``asvtwin scenario check | list | schema | run``."""

from __future__ import annotations

import importlib.util
import json

import pytest

from asvtwin.cli import main
from asvtwin.scenarios import library_names, scenario_json_schema

BAD = """\
name: bad
own_ship:
  start: {north_m: 3000, east_m: -2000}
  heading_deg: 400
  route: [{north_m: 4000, east_m: -2000}]
"""


def test_check_good_and_bad_files(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(BAD)
    assert main(["scenario", "check", "head_on"]) == 0
    out = capsys.readouterr().out
    assert "head_on: ok" in out and "route 1600 m" in out
    assert main(["scenario", "check", "head_on", str(bad)]) == 2
    err = capsys.readouterr().err
    assert f"{bad}:4: field 'own_ship.heading_deg'" in err and "< 360" in err


def test_check_json(tmp_path, capsys):
    assert main(["scenario", "check", "--json", "overtaking", str(tmp_path / "none.yaml")]) == 2
    rows = json.loads(capsys.readouterr().out)
    assert rows[0]["ok"] and rows[0]["targets"] == 1
    assert not rows[1]["ok"] and "no such scenario file" in rows[1]["error"]


def test_list_names_every_library_scenario(capsys):
    assert main(["scenario", "list", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["name"] for r in rows] == library_names()
    assert all("description" in r for r in rows)


def test_schema_to_stdout_and_file(tmp_path, capsys):
    assert main(["scenario", "schema"]) == 0
    assert json.loads(capsys.readouterr().out) == json.loads(json.dumps(scenario_json_schema()))
    out = tmp_path / "s" / "scenario.schema.json"
    assert main(["scenario", "schema", "--out", str(out)]) == 0
    assert json.loads(out.read_text())["$id"] == "asvtwin.scenario/1"


def test_run_refuses_a_bad_file_before_starting(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(BAD)
    assert main(["scenario", "run", str(bad)]) == 2
    assert "heading_deg" in capsys.readouterr().err


@pytest.mark.skipif(importlib.util.find_spec("asvtwin.twin.runtime") is None,
                    reason="asvtwin.twin.runtime is not available yet")
def test_run_short_json(tmp_path, capsys):
    rc = main(["scenario", "run", "model_scale_crossing", "--json", "--duration", "5",
               "--seed", "3", "--out", str(tmp_path)])
    summary = json.loads(capsys.readouterr().out)
    assert summary["scenario"] == "model_scale_crossing" and summary["seed"] == 3
    assert summary["duration_s"] == pytest.approx(5.0, abs=0.1)
    assert rc == (0 if summary["passed"] else 1)
    assert (tmp_path / "summary.json").is_file() and (tmp_path / "run.mcap").is_file()


@pytest.mark.skipif(importlib.util.find_spec("asvtwin.twin.runtime") is None,
                    reason="asvtwin.twin.runtime is not available yet")
def test_run_controller_override_is_used_and_reported(capsys):
    """--controller replaces the scenario's own-ship controller (los_psf -> los here: no
    filter calls at all) and the summary names the controller that ran."""
    rc = main(["scenario", "run", "model_scale_crossing", "--json", "--duration", "5",
               "--controller", "los"])
    summary = json.loads(capsys.readouterr().out)
    assert summary["controller"] == "los" and summary["filter_calls"] == 0
    assert rc in (0, 1)
    main(["scenario", "run", "model_scale_crossing", "--json", "--duration", "5"])
    summary = json.loads(capsys.readouterr().out)
    assert summary["controller"] == "los_psf" and summary["filter_calls"] > 0
    with pytest.raises(SystemExit) as exc:  # argparse: usage error, exit 2, before any run
        main(["scenario", "run", "model_scale_crossing", "--controller", "ppo"])
    assert exc.value.code == 2 and "invalid choice: 'ppo'" in capsys.readouterr().err


def test_run_controller_override_is_validated_like_a_file(tmp_path, capsys):
    """A controller the scenario cannot run under is refused before the run: LOS needs a
    route, and this scenario has none."""
    f = tmp_path / "drift.yaml"
    f.write_text("name: drift\nown_ship:\n  start: {north_m: 3000, east_m: -2000}\n"
                 "  controller: manual\ncriteria: {goal_reached: false}\n")
    assert main(["scenario", "check", str(f)]) == 0
    capsys.readouterr()
    assert main(["scenario", "run", str(f), "--controller", "los"]) == 2
    err = capsys.readouterr().err
    assert "cannot run under controller 'los'" in err and "route" in err
