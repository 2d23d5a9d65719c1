"""Figure of a standard manoeuvre: the track (on the coast when a scene is given), the
heading, speeds, yaw rate and the thrust that reached the hull, and its numbers in words."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from asvtwin.plots.base import draw_coast, legend, new_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from asvtwin.vessel.manoeuvres import ManoeuvreResult

__all__ = ["manoeuvre_figure", "metric_text"]


def metric_text(result: ManoeuvreResult) -> str:
    """The metrics as lines "meaning = value unit", NaN shown as "undefined"."""
    from asvtwin.vessel.manoeuvres import METRICS

    lines = []
    for key, value in result.metrics.items():
        words, unit = METRICS.get(key, (key, ""))
        shown = "undefined (see notes)" if math.isnan(value) else f"{value:.3g} {unit}"
        lines.append(f"{words} = {shown}")
    for c in result.criteria:
        verdict = "pass" if c.passed else "FAIL"
        lines.append(f"IMO {c.name}: {c.value:.3g} ≤ {c.limit:.3g} {c.unit}: {verdict}")
    return "\n".join(lines)


def _thrust_units(values: np.ndarray, unit: str) -> tuple[float, str]:
    big = float(np.nanmax(np.abs(values))) if values.size else 0.0
    if big >= 1e6:
        return 1e-6, f"M{unit}"
    if big >= 1e3:
        return 1e-3, f"k{unit}"
    return 1.0, unit


def manoeuvre_figure(result: ManoeuvreResult, *, length_m: float | None = None,
                     scene: Any = None) -> Figure:
    """Track, time series and metrics of a manoeuvre.

    Parameters
    ----------
    result : ManoeuvreResult
    length_m : float, optional
        Ship length [m]; sets the heading arrows and the coast margin (default: from the
        track's extent).
    scene : Scene, optional
        Draw the coast around the track, with three times its extent (at least 8 ship
        lengths and 600 m) of margin so the manoeuvre can be placed.
    """
    x, t, tau = result.x, result.t_s, result.tau
    span = float(np.ptp(x[:, :2], axis=0).max()) or 1.0
    L = length_m or span / 15.0
    fig = new_figure(13.0, 6.5)
    gs = fig.add_gridspec(4, 3, width_ratios=[1.2, 1.0, 0.75])
    ax = fig.add_subplot(gs[:, 0])
    ax.plot(x[:, 1], x[:, 0], "-", color="tab:blue", lw=1.5, label="track")
    # heading arrows: 12 along the run, at most a ship length and 1/10 of the track long
    k = np.arange(0, len(x), max(1, len(x) // 12))
    arrow = min(L, span / 10.0) if span > 0 else L
    ax.quiver(x[k, 1], x[k, 0], np.sin(x[k, 2]), np.cos(x[k, 2]), color="tab:blue",
              angles="xy", scale_units="xy", scale=1.0 / arrow, width=0.004,
              label="heading")
    ax.plot(x[0, 1], x[0, 0], "o", color="k", label="start")
    if scene is not None:
        pad = max(3.0 * span, 8.0 * L, 600.0)
        draw_coast(ax, scene.land, (x[:, 0].min() - pad, x[:, 1].min() - pad,
                                    x[:, 0].max() + pad, x[:, 1].max() + pad))
    else:
        ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.grid(alpha=0.3)
    where = f" in {scene.name}" if scene is not None else ""
    ax.set_title(f"{result.name.replace('_', ' ')}, {result.vessel}{where}")
    legend(ax, where="below")

    a1 = fig.add_subplot(gs[0, 1])
    a1.plot(t, np.degrees(x[:, 2]), color="tab:purple")
    a1.set_ylabel("heading ψ [deg]")
    a2 = fig.add_subplot(gs[1, 1], sharex=a1)
    a2.plot(t, x[:, 3], label="surge u")
    a2.plot(t, x[:, 4], label="sway v")
    a2.set_ylabel("speed [m/s]")
    a3 = fig.add_subplot(gs[2, 1], sharex=a1)
    a3.plot(t, np.degrees(x[:, 5]), color="tab:red")
    a3.set_ylabel("yaw rate r [deg/s]")
    a4 = fig.add_subplot(gs[3, 1], sharex=a1)
    kf, uf = _thrust_units(tau[:, 0], "N")
    a4.plot(t, kf * tau[:, 0], color="tab:green", label=f"surge thrust τ_u [{uf}]")
    a4.set_ylabel(f"surge τ_u [{uf}]", color="tab:green")
    if np.any(tau[:, 2] != 0.0):
        km, um = _thrust_units(tau[:, 2], "Nm")
        a4b = a4.twinx()
        a4b.plot(t, km * tau[:, 2], color="tab:orange")
        a4b.set_ylabel(f"yaw τ_r [{um}]", color="tab:orange")
    a4.set_xlabel("time [s]")
    for a in (a1, a2, a3, a4):
        a.grid(alpha=0.3)
    for a in (a1, a2, a3):
        a.tick_params(labelbottom=False)
    legend(a2)

    at = fig.add_subplot(gs[:, 2])
    at.axis("off")
    text = metric_text(result)
    if result.notes:
        text += "\n\nundefined:\n" + "\n".join(f"{k}: {v}" for k, v in result.notes.items())
    at.text(0.0, 1.0, text, va="top", ha="left", fontsize=7.5, wrap=True,
            transform=at.transAxes)
    return fig
