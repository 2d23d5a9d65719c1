"""Figures of tracking quality: consistency of the LiDAR centre measurement by aspect angle.

A single hull is scanned from many random poses (range 60-400 m, any bearing and heading,
length 15-80 m, length/beam 3-7, 720 rays); each scan that gives one cluster is turned into
a centre measurement by three models: the hull-centre model with the course known to 3°
(as a track lends it), the same without a heading (a new track), and the paper's fitted
ellipse / centroid. Per aspect sector (0° end-on, 90° broadside) the figure shows the
average normalised error :math:`e^T R^{-1} e` (2 dof: 2 is consistent, above is
overconfident) and the mean error along the line of sight (negative: towards the sensor).
Built on matplotlib's Figure object (:func:`asvtwin.plots.base.new_figure`).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from asvtwin.plots.base import legend, new_figure, save
from asvtwin.sensors import Lidar, LidarConfig
from asvtwin.tracking.clustering import cluster_scan
from asvtwin.tracking.measurement import LidarModel, hull_centres, lidar_measurements

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["AspectStudy", "aspect_consistency", "consistency_by_aspect_figure", "save_consistency_by_aspect"]

#: Models compared, in plotting order.
MODELS = ("hull, course known", "hull, no heading", "fitted ellipse (paper)")


@dataclass(frozen=True)
class AspectStudy:
    """Per pose: aspect [rad] (0 end-on, π/2 broadside); per model: NEES (2 dof) and the
    error along the line of sight [m] (negative towards the sensor)."""

    aspect_rad: NDArray[np.float64]
    nees: dict[str, NDArray[np.float64]]
    los_error_m: dict[str, NDArray[np.float64]]
    hull_shape: str

    def by_sector(self, edges_deg: tuple[float, ...] = (0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 90.0)
                  ) -> dict[str, dict[str, list[float]]]:
        """Mean NEES and mean line-of-sight error per aspect sector and model."""
        e = np.deg2rad(np.asarray(edges_deg))
        out: dict[str, dict[str, list[float]]] = {}
        for m in self.nees:
            out[m] = {"nees": [], "los_error_m": []}
            for lo, hi in itertools.pairwise(e):
                s = (self.aspect_rad >= lo) & (self.aspect_rad < hi + (1e-9 if hi == e[-1] else 0.0))
                out[m]["nees"].append(float(self.nees[m][s].mean()) if s.any() else float("nan"))
                out[m]["los_error_m"].append(float(self.los_error_m[m][s].mean()) if s.any() else float("nan"))
        return out


def aspect_consistency(n_poses: int = 1500, *, seed: int = 0, hull_shape: str = "pointed",
                       heading_std_rad: float = float(np.deg2rad(3.0))) -> AspectStudy:
    """Scan single hulls from random poses and score the three centre models.

    Parameters
    ----------
    n_poses : int
        Number of scans that gave one cluster.
    seed : int
        Seed of the poses, noise and heading errors.
    hull_shape : {"pointed", "ellipse"}
        The simulated hull.
    heading_std_rad : float
        Standard deviation of the course error given to the "course known" model [rad].
    """
    rng = np.random.default_rng(seed)
    lidar = Lidar(LidarConfig(n_rays=720, max_range_m=500.0, hull_shape=hull_shape))
    known, unknown, paper = LidarModel(), LidarModel(), LidarModel(centre="ellipse")
    asp: list[float] = []
    nees: dict[str, list[float]] = {m: [] for m in MODELS}
    los: dict[str, list[float]] = {m: [] for m in MODELS}
    while len(asp) < n_poses:
        L = rng.uniform(15.0, 80.0)
        B = L / rng.uniform(3.0, 7.0)
        r, brg, psi = rng.uniform(60.0, 400.0), rng.uniform(-np.pi, np.pi), rng.uniform(-np.pi, np.pi)
        x = np.array([r * np.cos(brg), r * np.sin(brg), psi, 0.0, 0.0, 0.0])
        cl = cluster_scan(lidar.scan(np.zeros(6), x[None, :], [L], [B], None, rng), None)
        if len(cl) != 1:
            continue
        asp.append(abs((psi - brg + 0.5 * np.pi) % np.pi - 0.5 * np.pi))
        u = x[:2] / r
        zk, Rk, _ = hull_centres(cl, [psi + rng.normal(0.0, heading_std_rad)], [heading_std_rad], known)
        mu = lidar_measurements(cl, unknown)
        mp = lidar_measurements(cl, paper)
        for m, z, R in ((MODELS[0], zk[0], Rk[0]), (MODELS[1], mu.z[0], mu.R[0]), (MODELS[2], mp.z[0], mp.R[0])):
            e = z - x[:2]
            nees[m].append(float(e @ np.linalg.solve(R, e)))
            los[m].append(float(e @ u))
    return AspectStudy(np.array(asp), {m: np.array(v) for m, v in nees.items()},
                       {m: np.array(v) for m, v in los.items()}, hull_shape)


def consistency_by_aspect_figure(study: AspectStudy) -> Figure:
    """NEES and line-of-sight bias of the centre models by aspect sector (two panels)."""
    edges = (0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 90.0)
    mid = 0.5 * (np.array(edges[:-1]) + np.array(edges[1:]))
    sec = study.by_sector(edges)
    fig = new_figure(9.0, 3.6)
    ax1, ax2 = fig.subplots(1, 2)
    for m, mk in zip(MODELS, ("o-", "s--", "^:")):
        ax1.semilogy(mid, sec[m]["nees"], mk, label=m)
        ax2.plot(mid, sec[m]["los_error_m"], mk, label=m)
    ax1.axhline(2.0, color="k", lw=0.8)
    ax1.text(1.0, 2.15, "2 dof: consistent", fontsize=8)
    ax1.set_xlabel("aspect [deg] (0 end-on, 90 broadside)")
    ax1.set_ylabel("mean NEES of the centre [-]")
    ax2.axhline(0.0, color="k", lw=0.8)
    ax2.set_xlabel("aspect [deg] (0 end-on, 90 broadside)")
    ax2.set_ylabel("mean error along line of sight [m]")
    ax1.set_title(f"{study.hull_shape} hulls, {len(study.aspect_rad)} scans", fontsize=9)
    legend(ax2)
    return fig


def save_consistency_by_aspect(path: str | Path, *, n_poses: int = 1500, seed: int = 0) -> Path:
    """Run :func:`aspect_consistency` and save its figure as a PNG."""
    return save(consistency_by_aspect_figure(aspect_consistency(n_poses, seed=seed)), path)
