"""The tracking figures of the paper, reproduced (``asvtwin figures tracking``).

1. ``rectangle_fit.png`` — the paper's Fig. RectEllipseS: Halir–Flusser ellipse on the outline
   of a rectangle, without and with noise.
2. ``multi_target_ellipses.png`` — Fig. ellipse_fitting_in_Unity: noisy LiDAR points (red)
   of several vessels and their fitted ellipses (orange).
3. ``prediction_cone.png`` — Fig. DT_Kalman_predictions: a fused track and its predicted
   path with the broadening 2-σ band (green).
4. ``near_coast.png`` — a scene in the Trondheim Fjord close to the shore: coast returns
   removed, vessels tracked, cones drawn.

Everything is simulated from a seed. Figures are built on the Figure-object API
(:mod:`asvtwin.plots.base`): no pyplot state, no backend change, one legend policy (outside
the axes), one coast drawing (holes kept), one colour and one ID label per track.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from asvtwin.plots.base import draw_coast, legend, new_figure, save, track_colours
from asvtwin.sensors import HIT_COAST, Lidar, LidarConfig, hull_polygons
from asvtwin.tracking.clustering import cluster_scan
from asvtwin.tracking.ellipse import fit_ellipse
from asvtwin.tracking.measurement import AisMeasurement, lidar_measurements
from asvtwin.tracking.prediction import predict_tracks, uncertainty_polygon
from asvtwin.tracking.tracker import Tracker, TrackerConfig

__all__ = ["make_tracking_figures"]


def _ellipse_xy(centre, axes, angle, n=100):  # type: ignore[no-untyped-def]
    t = np.linspace(0, 2 * np.pi, n)
    c, s = np.cos(angle), np.sin(angle)
    u, v = axes[0] * np.cos(t), axes[1] * np.sin(t)
    return centre[0] + c * u - s * v, centre[1] + s * u + c * v  # (north, east)


def _plot_ne(ax, north, east, *args, **kw):  # type: ignore[no-untyped-def]
    """Plot NED data on a chart: east to the right, north up."""
    return ax.plot(east, north, *args, **kw)


def _rectangle(ax_pair, rng):  # type: ignore[no-untyped-def]
    s = np.linspace(-1.0, 1.0, 16)[:-1]
    L2, B2 = 10.0, 3.0
    # the rectangle lies east-west (long side along east) so the panels read left to right
    edges = [np.column_stack([np.full_like(s, B2), L2 * s]), np.column_stack([-B2 * s, np.full_like(s, L2)]),
             np.column_stack([np.full_like(s, -B2), -L2 * s]), np.column_stack([B2 * s, np.full_like(s, -L2)])]
    rect = np.vstack(edges)
    for ax, noise, title in ((ax_pair[0], 0.0, "(a) without noise"), (ax_pair[1], 0.4, "(b) with noise σ = 0.4 m")):
        pts = rect + (rng.normal(0.0, noise, rect.shape) if noise else 0.0)
        fit = fit_ellipse(pts)
        ax.plot(pts[:, 1], pts[:, 0], "o", color="tab:blue", ms=4, label="LiDAR points")
        n, e = _ellipse_xy(fit.centre, fit.semi_axes, fit.angle_rad)
        ax.plot(e, n, "-", color="tab:orange", lw=2, label="Halir–Flusser fit")
        ax.plot(fit.centre[1], fit.centre[0], "+", color="tab:orange", ms=12)
        ax.set_title(f"{title}\nsemi-axes {fit.semi_axes[0]:.2f} × {fit.semi_axes[1]:.2f} m, "
                     f"residual {fit.residual_m:.2f} m", fontsize=9)
        ax.set_aspect("equal")
        ax.set_xlabel("east [m]")
        ax.grid(alpha=0.3)
    ax_pair[0].set_ylabel("north [m]")
    ax_pair[0].set_ylim(-7.5, 7.5)
    legend(ax_pair[1])


def _multi_target(ax, rng):  # type: ignore[no-untyped-def]
    targets = np.array([[60.0, -40.0, 0.3], [90.0, 35.0, 2.0], [-55.0, 70.0, -1.2], [-70.0, -60.0, 0.9],
                        [20.0, 110.0, 1.6], [130.0, -5.0, -0.4]])
    L = np.array([30.0, 22.0, 40.0, 18.0, 26.0, 35.0])
    states = np.column_stack([targets, np.zeros((6, 3))])
    lidar = Lidar(LidarConfig(n_rays=1440, max_range_m=300.0, range_std_m=0.15, angle_std_rad=0.002,
                              hull_shape="ellipse"))
    scan = lidar.scan(np.zeros(6), states, L, L / 3.5, None, rng)
    meas = lidar_measurements(cluster_scan(scan))
    for poly in hull_polygons(states, L, L / 3.5, shape="ellipse"):
        _plot_ne(ax, poly[:, 0], poly[:, 1], "-", color="0.6", lw=1)
    pts = scan.points
    ax.plot(pts[:, 1], pts[:, 0], ".", color="tab:red", ms=3, label="noisy LiDAR returns")
    for i in range(len(meas)):
        f = meas.fits[i]
        if f.ok:
            n, e = _ellipse_xy(f.centre, f.semi_axes, f.angle_rad)
            ax.plot(e, n, "-", color="tab:orange", lw=2)
    ax.plot([], [], "-", color="tab:orange", lw=2, label="fitted ellipses")
    ax.plot([], [], "-", color="0.6", lw=1, label="true hulls")
    ax.plot(0, 0, "k^", ms=9, label="own ship (LiDAR)")
    ax.set_aspect("equal")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.set_title("Multi-target ellipse fitting on synthetic LiDAR\n(1440 rays, σ_r = 0.15 m)",
                 fontsize=10)
    legend(ax, where="below")
    ax.grid(alpha=0.3)


def _track_and_predict(rng, *, land=None, own=None, x0, L, T=120, ais_std=10.0):  # type: ignore[no-untyped-def]
    own = np.zeros(6) if own is None else own
    lidar = Lidar(LidarConfig(n_rays=720, max_range_m=500.0))
    tracker = Tracker(TrackerConfig(), land=land)
    hist = {}
    scan = None
    for k in range(T):
        t = float(k)
        x = x0.copy()
        x[:, :2] += x0[:, 2:] * t
        scan = lidar.scan(own, x, L, L / 4, land, rng, t_s=t)
        ais = [AisMeasurement(257000000 + i, t, *(x[i, :2] + rng.normal(0, ais_std, 2)), float(np.hypot(*x[i, 2:])),
                              float(np.arctan2(x[i, 3], x[i, 2]))) for i in range(len(x0)) if k % 10 == i % 10]
        snap = tracker.step(t, scan, ais)
        for i, tid in enumerate(snap.ids):
            hist.setdefault(int(tid), []).append(snap.mean[i, :2].copy())
    return snap, scan, hist


def _cone(ax, snap, x0, T, horizon=120.0, colours=None):  # type: ignore[no-untyped-def]
    c = snap.confirmed()
    times = snap.t_s + np.linspace(0.0, horizon, 25)
    pred = predict_tracks(c.mean, c.cov, snap.t_s, times, TrackerConfig().q)
    for i in range(len(c)):
        colour = "tab:green" if colours is None else colours[int(c.ids[i])]
        poly = uncertainty_polygon(pred.positions[i], pred.cov[i, :, :2, :2], k_sigma=2.0)
        ax.fill(poly[:, 1], poly[:, 0], color=colour, alpha=0.25, lw=0)
        ax.plot(pred.positions[i, :, 1], pred.positions[i, :, 0], "--" if colours else "-",
                color=colour, lw=2)
    return pred


def make_tracking_figures(out_dir: str | Path, *, seed: int = 0) -> list[Path]:
    """Write the four tracking figures as PNG files.

    Parameters
    ----------
    out_dir : str or Path
        Directory to write into (created if missing).
    seed : int
        Seed of every random draw.

    Returns
    -------
    list of Path
        The files written.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    files = []

    fig = new_figure(12.5, 4.6)
    axs = fig.subplots(1, 2, sharey=True)
    _rectangle(axs, rng)
    fig.suptitle("Numerically stable direct least-squares ellipse fit to a 20 × 6 m rectangle")
    files.append(save(fig, out / "rectangle_fit.png"))

    fig = new_figure(7.5, 8.0)
    _multi_target(fig.add_subplot(), rng)
    files.append(save(fig, out / "multi_target_ellipses.png"))

    # one crossing vessel, AIS + LiDAR, 120 s of tracking, 120 s prediction
    x0 = np.array([[-250.0, -30.0, 2.5, 1.5]])  # passes ~110 m from the own ship
    snap, _, hist = _track_and_predict(rng, x0=x0, L=np.array([30.0]), T=90)
    fig = new_figure(10.0, 6.0)
    ax = fig.add_subplot()
    pred = _cone(ax, snap, x0, 90)
    for h in hist.values():
        h = np.array(h)
        ax.plot(h[:, 1], h[:, 0], "-", color="tab:blue", lw=1.5)
    tt = np.linspace(0, 210, 50)
    ax.plot(x0[0, 1] + x0[0, 3] * tt, x0[0, 0] + x0[0, 2] * tt, "k--", lw=1, label="true path 0–210 s")
    ax.plot([], [], "-", color="tab:blue", label="fused track (AIS + LiDAR), 0–90 s")
    ax.plot([], [], "-", color="tab:green", lw=2, label="predicted path 90–210 s, 2σ band")
    ax.plot(0, 0, "k^", ms=9, label="own ship")
    std = pred.position_std_max()[0]
    ax.set_title(f"Predicted path with cumulative uncertainty (2σ: {2 * std[0]:.1f} m now, "
                 f"{2 * std[-1]:.1f} m at +120 s)", fontsize=10)
    ax.set_aspect("equal")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    legend(ax)
    ax.grid(alpha=0.3)
    files.append(save(fig, out / "prediction_cone.png"))

    files.append(_near_coast(out, rng))
    return files


def _near_coast(out: Path, rng):  # type: ignore[no-untyped-def]
    from asvtwin.geo import default_scene

    scene = default_scene()
    land = scene.land
    own = np.array([-250.0, -1750.0, 0.3, 0.0, 0.0, 0.0])  # on water, ~320 m off the shore
    near = land.nearest_shore_point(own[None, :2])[0]
    away = (own[:2] - near) / np.linalg.norm(own[:2] - near)
    along = np.array([-away[1], away[0]])
    starts = [near + away * d - along * s for d, s in ((110.0, 250.0), (180.0, -200.0), (400.0, 150.0))]
    vel = [along * 2.5, -along * 2.0, along * 1.5]
    x0 = np.array([[*p, *v] for p, v in zip(starts, vel)])
    L = np.array([35.0, 20.0, 28.0])
    snap, scan, hist = _track_and_predict(rng, land=land, own=own, x0=x0, L=L, T=100)
    fig = new_figure(10.0, 7.5)
    ax = fig.add_subplot()
    draw_coast(ax, land, (own[0] - 600, own[1] - 600, own[0] + 600, own[1] + 600))
    pts = scan.points_ned[scan.hit]
    is_coast = scan.hit_id[scan.hit] == HIT_COAST
    ax.plot(pts[is_coast, 1], pts[is_coast, 0], ".", color="0.35", ms=3, label="coast returns (removed)")
    ax.plot(pts[~is_coast, 1], pts[~is_coast, 0], ".", color="tab:red", ms=4, label="vessel returns")
    c = snap.confirmed()
    ids = sorted(hist)
    colours = dict(zip(ids, track_colours(len(ids))))
    _cone(ax, snap, x0, 100, horizon=60.0, colours=colours)
    confirmed = {int(i) for i in c.ids}
    for tid in ids:
        h = np.array(hist[tid])
        shown = tid in confirmed
        ax.plot(h[:, 1], h[:, 0], "-", color=colours[tid], lw=1.5 if shown else 0.8,
                alpha=1.0 if shown else 0.5,
                label=f"track {tid}" + ("" if shown else " (not confirmed)"))
        ax.annotate(f"{tid}", (h[-1, 1], h[-1, 0]), xytext=(4, 4), textcoords="offset points",
                    fontsize=8, color=colours[tid], fontweight="bold")
    ax.plot(own[1], own[0], "k^", ms=9, label="own ship")
    ax.plot([], [], "--", color="0.3", lw=2, label="60 s prediction, 2σ band (track colour)")
    d = land.distance_to_shore(c.mean[:, :2])
    ax.set_title(f"Near the coast, Trondheim Fjord: tracks {', '.join(f'{v:.0f}' for v in sorted(d))} m off "
                 f"the shore,\n{snap.counters['coast_points']} coast returns removed, "
                 f"{snap.counters['tracks_created'] - 3} spurious tracks", fontsize=10)
    ax.set_xlabel("east [m] (scene frame)")
    ax.set_ylabel("north [m]")
    legend(ax)
    return save(fig, out / "near_coast.png")
