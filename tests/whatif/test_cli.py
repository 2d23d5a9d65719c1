"""``asvtwin whatif`` and ``asvtwin sweep`` from the command line."""

from __future__ import annotations

import json

import pytest

from asvtwin.cli import main


def test_whatif_cli_forks_a_scenario_and_prints_json(capsys):
    code = main(["whatif", "model_scale_crossing", "--at", "0.5", "--rollouts", "4",
                 "--horizon", "50", "--alt", "route+filter_off", "--alt",
                 "starboard:40+filter_off", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 1  # 4 futures cannot bound the risk below 5 %: said by the exit code
    assert 0.5 - 0.2 - 1e-9 <= out["t_s"] <= 0.5  # the last snapshot (5 Hz) at or before
    assert [a["label"] for a in out["alternatives"]] == ["route+filter_off",
                                                         "starboard:40+filter_off"]
    assert out["encounters"][0]["rule"] == 15


def test_whatif_cli_refuses_a_bad_alternative(capsys):
    code = main(["whatif", "model_scale_crossing", "--alt", "starboard:500"])
    assert code == 2
    assert "starboard:500" in capsys.readouterr().err


def test_sweep_cli_refuses_a_bad_parameter(capsys, tmp_path):
    code = main(["sweep", "model_scale_crossing", "--param", "own_ship.speed=1,2",
                 "--out", str(tmp_path)])
    assert code == 2
    err = capsys.readouterr().err
    assert "own_ship.speed" in err and "no field" in err


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A real 3 s recording of the model-scale crossing made by the twin's recorder."""
    from asvtwin.scenarios import load_library
    from asvtwin.twin.runtime import run_scenario

    out = tmp_path_factory.mktemp("rec")
    run_scenario(load_library("model_scale_crossing"), seed=2, duration_s=3.0, out_dir=out)
    return out / "run.mcap"


def test_whatif_on_a_recording_forks_its_snapshot(recording, capsys):
    """``asvtwin whatif REC.mcap --at T`` forks the recorded snapshot at or before T (the
    tracker's picture, not the scenario's plan) and answers with the recorded chart and
    hull: the filter-on future calls the filter, the same command gives the same answer."""
    from asvtwin.twin import Recording
    from asvtwin.whatif import encounters, fork

    argv = ["whatif", str(recording), "--at", "2.1", "--rollouts", "3", "--horizon", "15",
            "--alt", "route", "--alt", "starboard:40+filter_off", "--json"]
    code = main(argv)
    out = json.loads(capsys.readouterr().out)
    assert code in (0, 1)
    f = fork(Recording(recording).message_at(2.1))  # independently, from the file
    assert out["t_s"] == pytest.approx(f.t_s) and 1.9 <= f.t_s <= 2.1
    assert f.n_tracks >= 1 and f.vessel == "cybership2"
    want = [e.__dict__ for e in encounters(f)]
    assert [(e["track_id"], e["kind"], e["rule"]) for e in out["encounters"]] == \
        [(e["track_id"], e["kind"], e["rule"]) for e in want]
    assert out["encounters"][0]["range_m"] == pytest.approx(want[0]["range_m"])
    by = {a["label"]: a for a in out["alternatives"]}
    assert by["route"]["filter_calls"] > 0 and by["starboard:40+filter_off"]["filter_calls"] == 0
    assert main(argv) == code
    again = json.loads(capsys.readouterr().out)
    assert again["alternatives"] == out["alternatives"]


@pytest.mark.parametrize(("args", "words"), [
    (["--at", "60"], "after the last snapshot"),
    (["--at", "1", "--alt", "port:0"], "port:0"),
])
def test_whatif_on_a_recording_refuses_bad_requests(recording, capsys, args, words):
    assert main(["whatif", str(recording), *args]) == 2
    assert words in capsys.readouterr().err


def test_whatif_on_a_missing_recording_names_the_file(tmp_path, capsys):
    missing = tmp_path / "nope.mcap"
    assert main(["whatif", str(missing), "--at", "1"]) == 2
    assert "nope.mcap" in capsys.readouterr().err
