"""Figures of the twin, on matplotlib's Figure-object API (no pyplot state, no backend
change): one coast, one legend policy (:mod:`asvtwin.plots.base`), one module per area.

Each ``*_figure`` function returns a :class:`matplotlib.figure.Figure`; :func:`save`
writes it as PNG. The CLI handlers and the reports call these; computation never draws.
"""

from __future__ import annotations

from asvtwin.plots.base import draw_coast, legend, new_figure, save, track_colours
from asvtwin.plots.manoeuvre import manoeuvre_figure, metric_text

__all__ = [
    "draw_coast",
    "legend",
    "manoeuvre_figure",
    "metric_text",
    "new_figure",
    "save",
    "track_colours",
]
