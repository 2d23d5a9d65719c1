"""``asvtwin figures tracking`` writes the four PNGs."""

from __future__ import annotations

from pathlib import Path

from asvtwin.cli import main


def test_cli_writes_the_tracking_figures(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(["figures", "tracking", "--out", str(tmp_path)]) == 0
    names = {"rectangle_fit.png", "multi_target_ellipses.png", "prediction_cone.png", "near_coast.png"}
    assert {p.name for p in tmp_path.iterdir()} == names
    for n in names:
        data = (tmp_path / n).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000
    assert capsys.readouterr().out.count(".png") == 4
