"""The validation report and the ``asvtwin observer report`` command."""

from __future__ import annotations

import json

import pytest

from asvtwin.cli import main
from asvtwin.observer.report import SCENARIOS, observer_metrics, run_observer, write_report
from asvtwin.vessel import cybership2, cybership2_full_scale


@pytest.mark.parametrize("params", [cybership2(), cybership2_full_scale()],
                         ids=["model", "full"])
def test_step_metrics_match_theory_on_both_scales(params):
    sc = SCENARIOS[0]
    res, dh = run_observer(params, sc, noise=False, seed=2, n_runs=2)
    m = observer_metrics(params, sc, res, dh)
    for t90, theory in zip(m["t90_s"], m["t90_theory_s"]):
        assert abs(t90 - theory) <= 2 * res.dt_s
    assert max(m["rmse_rel"]) < 0.01  # 10 % step, < 1 % of the range after 3 T


def test_report_writes_table_json_and_plot(tmp_path):
    paths = write_report(tmp_path, ["cybership2"], faults=True, fault_runs=4,
                         fault_free_hours=0.5, runs=2)
    md = paths["md"].read_text()
    assert "| cybership2 | step | no |" in md and "| cybership2 | environment | yes |" in md
    assert "50 % surge thrust loss" in md
    data = json.loads(paths["json"].read_text())
    assert len(data["observer"]) == 2 * len(SCENARIOS)
    assert data["faults"][0]["detected"] == 1.0
    assert paths["png"].stat().st_size > 20_000


def test_cli_report(tmp_path, capsys):
    rc = main(["observer", "report", "--out", str(tmp_path), "--vessel", "cybership2",
               "--no-faults"])
    assert rc == 0
    out = capsys.readouterr().out
    assert "Disturbance observer validation" in out
    assert (tmp_path / "observer_report.png").exists()


def test_cli_unknown_vessel_is_reported(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        main(["observer", "report", "--out", str(tmp_path), "--vessel", "titanic",
              "--no-faults"])
    assert e.value.code == 2
    out, err = capsys.readouterr()
    assert "invalid choice: 'titanic'" in err and out == ""
