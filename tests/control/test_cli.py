from __future__ import annotations

import csv

from asvtwin.cli import main
from asvtwin.control import Fallback


def test_psf_demo_writes_png_and_csv(tmp_path, psf):
    rc = main(["psf", "demo", "--out", str(tmp_path), "--seed", "3", "--duration", "20",
               "--backend", psf.backend.name.split("-rti")[0]])
    assert rc == 0
    png = tmp_path / "psf_demo.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rows = list(csv.DictReader((tmp_path / "psf_delta_u.csv").open()))
    assert len(rows) == 40  # 20 s of 0.5 s stages
    for r in rows:
        du = float(r["delta_u_surge_N"])
        assert abs(du - (float(r["u_L_surge_N"]) - float(r["u0_surge_N"]))) < 2e-4
        assert r["fallback"] in [f.value for f in Fallback]
        # the columns agree: clearance = d_safe + margin; a certified plan keeps d_safe
        assert abs(float(r["plan_clearance_m"]) - float(r["d_safe_margin_m"]) - 1.255) < 2e-3
        if r["fallback"] == "none":
            assert float(r["d_safe_margin_m"]) > -0.03  # certification tolerance 2 % L
        if r["intervened"] == "1":
            assert "no intervention" not in r["explanation"]
        else:
            assert r["explanation"].startswith("no intervention") or r["fallback"] != "none"


def test_psf_help(capsys):
    try:
        main(["psf", "demo", "--help"])
    except SystemExit as exc:
        assert exc.code == 0
    assert "--seed" in capsys.readouterr().out
