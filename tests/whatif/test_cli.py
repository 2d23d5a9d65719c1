"""``asvtwin whatif`` and ``asvtwin sweep`` from the command line."""

from __future__ import annotations

import json

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
