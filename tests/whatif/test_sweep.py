"""Sweeps: refusal of malformed specifications, a short local grid, resumption, Parquet
and the HTML report (Ray against the local pool: test_ray.py)."""

from __future__ import annotations

import pyarrow.parquet as pq
import pytest

from asvtwin.errors import ScenarioError
from asvtwin.whatif.report import write_parquet, write_report
from asvtwin.whatif.sweep import SweepSpec, load_sweep_spec, parse_param, rows_of, run_cells


def _spec(**kw):
    base = {"files": ("model_scale_crossing",),
            "params": (("environment.current_speed_m_s", (0.0, 0.02)),),
            "seeds": 1, "duration_s": 2.0}
    base.update(kw)
    return SweepSpec(**base)


@pytest.mark.parametrize(("text", "match"), [
    ("scenarios: [model_scale_crossing]\nparams: {environment.current_speed: [0, 1]}\n",
     (r"bad\.yaml: model_scale_crossing: parameter environment\.current_speed: no field "
      r"'environment\.current_speed'")),
    ("scenarios: [model_scale_crossing]\nparams: {environment.current_speed_m_s: [-1]}\n",
     (r"bad\.yaml: model_scale_crossing with \{'environment\.current_speed_m_s': -1\}: "
      r"environment\.current_speed_m_s.*greater than or equal to 0")),
    ("scenarios: [model_scale_crossing]\nseeds: 0\n", r"bad\.yaml: field 'seeds' must be"),
    ("scenarios: [model_scale_crossing]\nseed: 3\n", r"bad\.yaml: field 'seed' is not allowed"),
    ("scenarios: []\n", r"bad\.yaml: field 'scenarios' must be a non-empty list"),
    ("scenarios: [model_scale_crossing]\nparams: {targets.5.speed_kn: [1]}\n",
     r"targets\.5 is not an index of a list of 1 items"),
])
def test_malformed_sweep_spec_is_refused_with_file_field_and_reason(tmp_path, text, match):
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    with pytest.raises(ScenarioError, match=match):
        load_sweep_spec(f).cells()


def test_param_syntax():
    assert parse_param("own_ship.controller=los,los_psf") == ("own_ship.controller",
                                                              ["los", "los_psf"])
    with pytest.raises(ScenarioError, match="expected NAME=V1,V2"):
        parse_param("environment.current_speed_m_s")


def test_local_sweep_resumes_and_writes_parquet_and_report(tmp_path):
    cells = _spec().cells()
    assert len(cells) == 2 and len({c.id for c in cells}) == 2
    seen = []
    s1 = run_cells(cells, tmp_path, workers=1, progress=lambda d, t, k: seen.append((d, t, k)))
    assert seen[0] == (0, 2, 0) and seen[-1] == (2, 2, 0)
    mtime = [(tmp_path / "cells" / c.id / "summary.json").stat().st_mtime_ns for c in cells]
    seen.clear()
    s2 = run_cells(cells, tmp_path, workers=1, progress=lambda d, t, k: seen.append((d, t, k)))
    assert seen == [(2, 2, 2)]  # nothing rerun
    assert [(tmp_path / "cells" / c.id / "summary.json").stat().st_mtime_ns
            for c in cells] == mtime
    assert s1 == s2
    rows = rows_of(cells, s1, tmp_path)
    table = pq.read_table(write_parquet(rows, tmp_path / "results.parquet")).to_pylist()
    assert [r["param.environment.current_speed_m_s"] for r in table] == ["0.0", "0.02"]
    assert all(r["duration_s"] == pytest.approx(2.0, abs=0.1) for r in table)
    html = write_report(rows, tmp_path / "report.html").read_text()
    assert "<svg" in html and "<script" not in html
    assert f'href="cells/{cells[0].id}/run.mcap"' in html
    assert (tmp_path / "cells" / cells[0].id / "run.mcap").exists()
