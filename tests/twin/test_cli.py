"""``asvtwin run --headless`` and ``asvtwin replay``: files, exit codes, summary, verify."""

from __future__ import annotations

import json

import pytest
from ruamel.yaml import YAML

from asvtwin.cli import main

from .conftest import BASE


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    scen = dict(BASE)
    scen["rates"] = {"sim_hz": 5.0, "tracker_hz": 2.0, "observer_hz": 5.0,
                     "controller_hz": 5.0, "filter_hz": 1.0, "snapshot_hz": 1.0}
    path = d / "scenario.yaml"
    with open(path, "w") as f:
        YAML().dump(json.loads(json.dumps(scen)), f)
    out = d / "out"
    code = main(["run", "--headless", "--scenario", str(path), "--duration", "20",
                 "--out", str(out)])
    return d, out, code


def test_run_headless_writes_recording_and_summary(run_dir, capsys):
    _, out, code = run_dir
    assert code == 0  # the criteria were met
    summary = json.loads((out / "summary.json").read_text())
    assert summary["ticks"] == 100 and summary["scenario"] == "twin_test"
    assert summary["passed"] is True and summary["collisions"] == 0
    assert (out / "run.mcap").stat().st_size > 1000


def test_replay_headless_json_and_verify(run_dir, capsys):
    _, out, _ = run_dir
    capsys.readouterr()
    assert main(["replay", str(out / "run.mcap"), "--headless", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["seed"] == 3 and info["truncated"] is False
    assert info["summary"]["ticks"] == 100 and info["duration_s"] == pytest.approx(19.0)
    assert main(["replay", str(out / "run.mcap"), "--verify"]) == 0
    text = capsys.readouterr().out
    assert "verify: 20 snapshots re-run from the raw inputs; identical" in text
    assert "PASSED" in text


def test_bad_inputs_exit_2(tmp_path, capsys):
    assert main(["replay", str(tmp_path / "nope.mcap"), "--headless"]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["run", "--headless", "--speed", "warp", "--duration", "1",
                 "--out", str(tmp_path)]) == 2
    assert "speed must be" in capsys.readouterr().err
