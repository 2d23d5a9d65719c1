"""Figure of the disturbance observer's validation: true τ_d against the estimate d̂."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from asvtwin.plots.base import legend, new_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["observer_figure"]

_DOF = ("surge force X", "sway force Y", "yaw moment N")


def observer_figure(panels: Sequence[tuple[str, Any, Any, NDArray[np.float64]]]) -> Figure:
    """One row per scenario, one column per degree of freedom.

    Parameters
    ----------
    panels : sequence of (title, VesselParams, RunResult, d_hat)
        ``RunResult`` with ``t_s`` (k,) [s] and ``tau_d`` (k, n, 3) [N, N, Nm]; ``d_hat``
        (k, n, 3) the observer's estimate; vessel 0 is drawn. Full-scale vessels (L > 20 m)
        are shown in kN and kNm.
    """
    fig = new_figure(15.0, 2.6 * len(panels) + 0.6)
    axes = fig.subplots(len(panels), 3, squeeze=False)
    for row, (title, p, res, dh) in enumerate(panels):
        full = p.length > 20
        k = 1e-3 if full else 1.0
        units = ("kN", "kN", "kNm") if full else ("N", "N", "Nm")
        for j in range(3):
            ax = axes[row, j]
            ax.plot(res.t_s, res.tau_d[:, 0, j] * k, color="k", lw=1.3, label="true τ_d")
            ax.plot(res.t_s, dh[:, 0, j] * k, color="tab:red", lw=0.8, alpha=0.8,
                    label="estimate d̂")
            ax.set_title(f"{title}: {_DOF[j]}", fontsize=9)
            ax.set_ylabel(f"{_DOF[j].split()[-1]} [{units[j]}]", fontsize=8)
            ax.tick_params(labelsize=7)
            ax.grid(alpha=0.3)
        if row == 0:
            legend(axes[0, 2])
    for j in range(3):
        axes[-1, j].set_xlabel("time [s]", fontsize=8)
    fig.suptitle("Disturbance observer: true τ_d and estimate d̂ (with sensor noise; first "
                 "of the seeded runs)", fontsize=11)
    return fig
