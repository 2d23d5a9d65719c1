"""What every figure of the package shares: the Figure object, the coast, the legend.

Figures are built on matplotlib's object API (:class:`matplotlib.figure.Figure`), never
through ``pyplot``'s global state, and the library never calls ``matplotlib.use``: a
notebook user's backend stays theirs, and a figure made here is garbage-collected like any
object. :func:`save` writes a PNG through the Agg canvas directly.

One legend policy (:func:`legend`): outside the axes, to the right (or below, for wide
panels), so a legend never hides data or land. One coast (:func:`draw_coast`): land
polygons clipped to a window, filled with their holes (lakes, islands in lakes) left open.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure
    from matplotlib.legend import Legend

__all__ = [
    "LAND_EDGE",
    "LAND_FACE",
    "WATER",
    "draw_coast",
    "legend",
    "new_figure",
    "save",
    "track_colours",
]

#: Colours of land, its outline and water.
LAND_FACE = "#d9c9a3"
LAND_EDGE = "#8a7a55"
WATER = "#e6f0f7"


def new_figure(width_in: float, height_in: float, **kw: Any) -> Figure:
    """A Figure not registered with pyplot (no global state, no backend change), on an
    Agg canvas of its own so it can be drawn and saved anywhere."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    kw.setdefault("layout", "constrained")
    fig = Figure(figsize=(width_in, height_in), **kw)
    FigureCanvasAgg(fig)
    return fig


def save(fig: Figure, path: str | Path, *, dpi: int = 130) -> Path:
    """Write ``fig`` as PNG; return the path."""
    path = Path(path)
    fig.savefig(path, dpi=dpi)
    return path


def legend(ax: Axes, *, where: str = "right", **kw: Any) -> Legend | None:
    """The one legend policy: outside the axes (``where`` = "right" or "below"), so it
    covers neither data nor land. Returns None when nothing is labelled."""
    handles, labels = ax.get_legend_handles_labels()
    if not handles:
        return None
    kw.setdefault("fontsize", 8)
    kw.setdefault("frameon", False)
    if where == "below":
        return ax.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, -0.12),
                         ncol=min(3, len(handles)), **kw)
    return ax.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.02, 1.0),
                     borderaxespad=0.0, **kw)


def draw_coast(ax: Axes, land: Any, bounds_ne: Sequence[float], *,
               label: str | None = "land") -> int:
    """Fill the land inside a window of the scene frame, holes kept open.

    Parameters
    ----------
    ax : Axes
        Axes with east [m] on x and north [m] on y (north up).
    land : LandMask or shapely geometry
        The scene's land (``scene.land``), or polygons in scene NED [m] (north, east).
    bounds_ne : (4,) sequence
        Window ``(north_min, east_min, north_max, east_max)`` [m]; the axes are set to it
        (equal aspect) and the water coloured.
    label : str or None
        Legend label of the land (once).

    Returns
    -------
    int
        The number of polygons drawn.
    """
    import shapely
    from matplotlib.patches import PathPatch
    from matplotlib.path import Path as MplPath
    from shapely.geometry.polygon import orient

    geom = getattr(land, "polygons", land)
    n0, e0, n1, e1 = (float(b) for b in bounds_ne)
    clipped = geom.intersection(shapely.box(n0, e0, n1, e1))
    count = 0
    for part in shapely.get_parts(clipped):
        if part.geom_type != "Polygon" or part.is_empty:
            continue
        # exterior counter-clockwise, holes clockwise: the non-zero fill leaves holes open
        poly = orient(part, sign=1.0)
        verts, codes = [], []
        for ring in (poly.exterior, *poly.interiors):
            ne = np.asarray(ring.coords)
            en = ne[:, ::-1]  # (north, east) -> plot (x = east, y = north)
            verts.append(en)
            codes += [MplPath.MOVETO] + [MplPath.LINETO] * (len(en) - 2) + [MplPath.CLOSEPOLY]
        patch = PathPatch(MplPath(np.concatenate(verts), codes), facecolor=LAND_FACE,
                          edgecolor=LAND_EDGE, lw=0.8, zorder=0,
                          label=label if count == 0 else None)
        ax.add_patch(patch)
        count += 1
    ax.set_xlim(e0, e1)
    ax.set_ylim(n0, n1)
    ax.set_aspect("equal", adjustable="box")
    ax.set_facecolor(WATER)
    return count


def track_colours(n: int) -> list[tuple[float, float, float, float]]:
    """``n`` distinct colours for per-track drawing (tab10, then tab20 beyond ten)."""
    from matplotlib import colormaps

    cmap = colormaps["tab10" if n <= 10 else "tab20"]
    return [cmap(i % cmap.N) for i in range(n)]
