"""Figure of the safety-filter demo: the paper's picture of a predictive safety filter
(predicted safe path green, critical regions red) over the filtered and unfiltered runs."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from asvtwin.plots.base import legend, new_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["psf_demo_figure"]


def psf_demo_figure(scene: Any, free: Any, run: Any, psf: Any, *, seed: int) -> Figure:
    """The demo's picture.

    Parameters
    ----------
    scene : the closed-loop scenario (``circles.centres`` (k, 2) and ``circles.radii``
        (k,) [m, NED], ``x0`` (6,))
    free, run : closed-loop runs without and with the filter (``x`` (T, 6) states,
        ``min_clearance_m``; ``run.results`` the filter's results per call)
    psf : the SafetyFilter (``d_safe_m``, ``d_f_m``, ``config.dt_s``, ``config.N``)
    seed : the scenario's seed, for the title

    The view holds both tracks, the plan shown and every obstacle the filter named
    (nothing is cut off); the legend sits outside the axes.
    """
    from matplotlib.patches import Circle

    res = run.results
    # the first call where the filter intervened: its plan is the picture's green path
    k_show = next((k for k, r in enumerate(res) if r.intervened), 0)
    shown = res[k_show]
    fig = new_figure(10.0, 7.5)
    ax = fig.add_subplot()
    centres, radii = np.asarray(scene.circles.centres), np.asarray(scene.circles.radii)
    for i, ((n, e), r) in enumerate(zip(centres, radii)):
        ax.add_patch(Circle((e, n), r, color="0.55", zorder=2,
                            label="obstacles" if i == 0 else None))
    crit_idx = sorted({a.index for r in res for a in r.active if a.kind == "circle"})
    for i, j in enumerate(crit_idx):  # critical region: obstacle grown by d_safe
        (n, e), r = centres[j], radii[j]
        ax.add_patch(Circle((e, n), r + psf.d_safe_m, color="red", alpha=0.25, zorder=1,
                            label="critical region (r + d_safe)" if i == 0 else None))
        ax.add_patch(Circle((e, n), r + psf.d_safe_m + psf.d_f_m, fill=False, ls=":",
                            color="red", zorder=1,
                            label="terminal clearance (r + d_safe + d_f)" if i == 0 else None))
    ax.plot(free.x[:, 1], free.x[:, 0], "--", color="0.3", lw=1.2,
            label="naive controller, unfiltered")
    ax.plot(run.x[:, 1], run.x[:, 0], color="tab:blue", lw=2.0, label="filtered (executed)")
    ax.plot(shown.x_pred[:, 1], shown.x_pred[:, 0], color="green", lw=2.5,
            label=f"predicted safe path at t = {k_show * psf.config.dt_s:.1f} s")
    ax.plot(shown.x_pred[0, 1], shown.x_pred[0, 0], "o", color="green")
    ax.plot(scene.x0[1], scene.x0[0], "k^", ms=9, label="start")
    # view: tracks, plan, and every obstacle within reach of them, with a margin
    pts = np.vstack([free.x[:, :2], run.x[:, :2], shown.x_pred[:, :2]])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    reach = psf.d_safe_m + psf.d_f_m
    near = np.all((centres >= lo - radii[:, None] - reach) &
                  (centres <= hi + radii[:, None] + reach), axis=1)
    if near.any():
        lo = np.minimum(lo, (centres[near] - radii[near, None]).min(axis=0))
        hi = np.maximum(hi, (centres[near] + radii[near, None]).max(axis=0))
    pad = 0.05 * float((hi - lo).max()) + 1.0
    ax.set_xlim(lo[1] - pad, hi[1] + pad)
    ax.set_ylim(lo[0] - pad, hi[0] + pad)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.grid(alpha=0.3)
    legend(ax)
    n_int = sum(r.intervened for r in res)
    ax.set_title(f"Predictive safety filter ({res[0].backend}, N={psf.config.N}, seed "
                 f"{seed})\nmin clearance {run.min_clearance_m:.2f} m filtered vs "
                 f"{free.min_clearance_m:.2f} m unfiltered; {n_int}/{len(res)} "
                 "steps corrected", fontsize=10)
    return fig
