"""The figures' shared policy: Figure objects (no pyplot, no backend change), a coast
with its holes, legends outside the axes."""

from __future__ import annotations

import re
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import shapely

from asvtwin.plots import draw_coast, legend, new_figure, save
from asvtwin.plots.base import LAND_FACE, WATER

PACKAGE = Path(__file__).resolve().parents[2] / "asvtwin"


def _rgb(hex_colour: str) -> np.ndarray:
    return np.array([int(hex_colour[i:i + 2], 16) for i in (1, 3, 5)])


def _pixel(fig, ax, north: float, east: float) -> np.ndarray:
    fig.canvas.draw()
    img = np.asarray(fig.canvas.buffer_rgba())[..., :3].astype(int)
    x, y = ax.transData.transform((east, north))
    return img[img.shape[0] - round(y), round(x)]


@pytest.mark.parametrize("hole_clockwise", [True, False])
def test_draw_coast_leaves_holes_open(hole_clockwise):
    # an island of 1 km with a 400 m lake in it, the lake ring in either orientation
    lake = [(300, 300), (300, 700), (700, 700), (700, 300)]
    if not hole_clockwise:
        lake = lake[::-1]
    island = shapely.Polygon([(0, 0), (0, 1000), (1000, 1000), (1000, 0)], [lake])
    fig = new_figure(5, 5, layout=None)
    ax = fig.add_subplot()
    assert draw_coast(ax, shapely.MultiPolygon([island]), (-200, -200, 1200, 1200)) == 1
    land = _rgb(LAND_FACE)
    water = _rgb(WATER)
    assert np.abs(_pixel(fig, ax, 150, 150) - land).max() <= 2      # on the island
    assert np.abs(_pixel(fig, ax, 500, 500) - water).max() <= 2     # in the lake
    assert np.abs(_pixel(fig, ax, -100, 500) - water).max() <= 2    # at sea


def test_draw_coast_clips_to_the_window_and_sets_it():
    fig = new_figure(4, 4)
    ax = fig.add_subplot()
    land = shapely.box(0, 0, 5000, 5000)
    draw_coast(ax, land, (-100, -300, 100, 300))
    assert ax.get_xlim() == (-300, 300) and ax.get_ylim() == (-100, 100)
    (patch,) = ax.patches
    ext = patch.get_path().get_extents()
    assert ext.x0 >= 0 and ext.x1 <= 300 and ext.y1 <= 100  # clipped: east, north


def test_legend_sits_outside_the_axes():
    fig = new_figure(6, 4)
    ax = fig.add_subplot()
    ax.plot([0, 1], [0, 1], label="data")
    leg = legend(ax)
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    box, frame = leg.get_window_extent(r), ax.get_window_extent(r)
    assert box.x0 >= frame.x1 - 1  # right of the axes: covers no data
    assert legend(fig.add_subplot(2, 1, 2)) is None  # nothing labelled: no legend


def test_save_writes_a_png(tmp_path):
    fig = new_figure(3, 2)
    fig.add_subplot().plot([0, 1], [1, 0])
    data = save(fig, tmp_path / "f.png").read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_library_never_switches_backend_or_uses_pyplot():
    uses = [p for p in PACKAGE.rglob("*.py")
            if re.search(r"matplotlib\.use\(|import matplotlib\.pyplot|from matplotlib "
                         r"import pyplot", p.read_text(encoding="utf-8"))]
    assert uses == []


def test_a_figure_leaves_the_users_backend_alone():
    code = textwrap.dedent("""
        import sys
        import matplotlib
        matplotlib.use("svg")  # the user's choice
        import pathlib, tempfile
        import numpy as np
        from asvtwin.plots import manoeuvre_figure, save
        from asvtwin.vessel.manoeuvres import ManoeuvreResult
        t = np.linspace(0.0, 10.0, 11)
        x = np.zeros((11, 6))
        x[:, 0] = t
        x[:, 3] = 1.0
        result = ManoeuvreResult("thrust_step", "test", t, x, np.ones((11, 3)),
                                 {"final_speed_m_s": 1.0})
        save(manoeuvre_figure(result, length_m=1.0), pathlib.Path(tempfile.mkdtemp()) / "t.png")
        assert matplotlib.get_backend() == "svg", matplotlib.get_backend()
        assert "matplotlib.pyplot" not in sys.modules
    """)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300, check=False)
    assert proc.returncode == 0, proc.stderr
