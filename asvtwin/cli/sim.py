"""``asvtwin sim``: run a standard manoeuvre and write a CSV and a PNG plot."""

from __future__ import annotations

import argparse
import csv
import math
from pathlib import Path

__all__ = ["plot_manoeuvre", "register", "write_csv"]


def register(sub: argparse._SubParsersAction) -> None:
    from asvtwin.vessel.manoeuvres import MANOEUVRES
    from asvtwin.vessel.params import VESSELS

    p = sub.add_parser(
        "sim",
        help="run a manoeuvre (turning circle, zig-zag, thrust step); write CSV + PNG",
        description="Simulate a standard manoeuvre with the 3-DOF model and thruster "
                    "dynamics; print its numbers, write <out>/<vessel>_<manoeuvre>.csv "
                    "and .png.",
    )
    p.add_argument("--vessel", choices=sorted(VESSELS), default="cybership2_fullscale",
                   help="parameter set (default: %(default)s)")
    p.add_argument("--manoeuvre", choices=sorted(MANOEUVRES), default="turning-circle",
                   help="manoeuvre (default: %(default)s)")
    p.add_argument("--surge-fraction", type=float, default=None,
                   help="surge thrust as a fraction of the largest (default: 1.0; "
                        "0.2 for the zig-zag, where CyberShip II is course-unstable "
                        "at higher speed)")
    p.add_argument("--yaw-fraction", type=float, default=1.0,
                   help="yaw moment as a fraction of the largest (turning circle, "
                        "zig-zag; default: %(default)s)")
    p.add_argument("--switch-deg", type=float, default=10.0,
                   help="zig-zag heading switch angle [deg] (default: %(default)s)")
    p.add_argument("--dt", type=float, default=None, help="time step [s] (default: L/U/50)")
    p.add_argument("--out", type=Path, default=Path("out"),
                   help="output folder (default: %(default)s)")
    p.add_argument("--no-plot", action="store_true", help="write the CSV only")
    p.add_argument("--scene", default=None, metavar="SCENE",
                   help="run the manoeuvre at the origin of a scene ('default' for the "
                        "embedded Trondheim Fjord, or a scene file); draws the coast and "
                        "reports the closest approach to the shore")
    p.add_argument("--start-heading-deg", type=float, default=0.0,
                   help="initial heading [deg from north] (default: %(default)s)")
    p.set_defaults(func=_run)


def write_csv(path: Path, result) -> None:
    """Time series of a manoeuvre as CSV (SI units, heading in degrees)."""
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t_s", "x_m", "y_m", "psi_deg", "u_m_s", "v_m_s", "r_deg_s",
                    "tau_u_n", "tau_v_n", "tau_r_nm"])
        for t, x, tau in zip(result.t_s, result.x, result.tau):
            w.writerow([f"{t:.4f}", f"{x[0]:.4f}", f"{x[1]:.4f}",
                        f"{math.degrees(x[2]):.4f}", f"{x[3]:.5f}", f"{x[4]:.5f}",
                        f"{math.degrees(x[5]):.5f}", f"{tau[0]:.6g}", f"{tau[1]:.6g}",
                        f"{tau[2]:.6g}"])


def plot_manoeuvre(path: Path, result, scene=None) -> None:
    """Track (north up) and time series of a manoeuvre as a PNG; with a scene, the
    coast around the track is drawn too."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    x = result.x
    span = float(np.ptp(x[:, :2], axis=0).max()) or 1.0
    hull_len = span / 15.0
    fig = plt.figure(figsize=(11, 5.5), constrained_layout=True)
    gs = fig.add_gridspec(3, 2, width_ratios=[1.1, 1])
    ax = fig.add_subplot(gs[:, 0])
    ax.plot(x[:, 1], x[:, 0], "-", color="tab:blue", lw=1.5)
    k = np.arange(0, len(x), max(1, len(x) // 16))
    ax.quiver(x[k, 1], x[k, 0], np.sin(x[k, 2]), np.cos(x[k, 2]), color="tab:blue",
              angles="xy", scale_units="xy", scale=1.0 / hull_len,
              width=0.004, label="heading")
    ax.plot(x[0, 1], x[0, 0], "o", color="k", label="start")
    if scene is not None:
        import shapely

        pad = max(span, 300.0)
        box = shapely.box(x[:, 0].min() - pad, x[:, 1].min() - pad,
                          x[:, 0].max() + pad, x[:, 1].max() + pad)
        near = scene.land.polygons.intersection(box)
        for poly in shapely.get_parts(near):
            if poly.geom_type != "Polygon":
                continue
            n_, e_ = poly.exterior.xy
            ax.fill(e_, n_, color="#d9c9a3", edgecolor="#8a7a55", lw=0.8, zorder=0)
        ax.set_xlim(box.bounds[1], box.bounds[3])
        ax.set_ylim(box.bounds[0], box.bounds[2])
        ax.set_aspect("equal", adjustable="box")
        ax.set_facecolor("#e6f0f7")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    if scene is None:
        ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    where = f" — {scene.name}" if scene is not None else ""
    ax.set_title(f"{result.name} — {result.vessel}{where}")
    text = "\n".join(f"{k} = {v:.3g}" for k, v in result.metrics.items())
    ax.text(0.02, 0.02, text, transform=ax.transAxes, fontsize=8, va="bottom",
            bbox={"facecolor": "white", "alpha": 0.8, "edgecolor": "0.7"})
    t = result.t_s
    a1 = fig.add_subplot(gs[0, 1])
    a1.plot(t, np.degrees(x[:, 2]), color="tab:purple")
    a1.set_ylabel("heading ψ [deg]")
    a2 = fig.add_subplot(gs[1, 1], sharex=a1)
    a2.plot(t, x[:, 3], label="u")
    a2.plot(t, x[:, 4], label="v")
    a2.set_ylabel("speed [m/s]")
    a2.legend(loc="best", fontsize=8)
    a3 = fig.add_subplot(gs[2, 1], sharex=a1)
    a3.plot(t, np.degrees(x[:, 5]), color="tab:red")
    a3.set_ylabel("yaw rate r [deg/s]")
    a3.set_xlabel("time [s]")
    for a in (a1, a2, a3):
        a.grid(alpha=0.3)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _run(args: argparse.Namespace) -> int:
    from rich.console import Console
    from rich.table import Table

    from asvtwin.errors import AsvTwinError
    from asvtwin.vessel.manoeuvres import MANOEUVRES
    from asvtwin.vessel.params import vessel_by_name

    console = Console()
    params = vessel_by_name(args.vessel)
    kwargs: dict = {}
    if args.dt is not None:
        kwargs["dt_s"] = args.dt
    if args.manoeuvre != "thrust-step":
        kwargs["yaw_fraction"] = args.yaw_fraction
    surge = args.surge_fraction
    if surge is None:
        surge = 0.2 if args.manoeuvre == "zigzag" else 1.0
    kwargs["surge_fraction"] = surge
    if args.manoeuvre == "zigzag":
        kwargs["switch_deg"] = args.switch_deg
    if args.start_heading_deg != 0.0:
        kwargs["psi0_rad"] = math.radians(args.start_heading_deg)
    scene = None
    try:
        if args.scene is not None:
            from asvtwin.geo import default_scene, load_scene

            scene = default_scene() if args.scene == "default" else load_scene(args.scene)
        result = MANOEUVRES[args.manoeuvre](params, **kwargs)
    except AsvTwinError as exc:
        console.print(f"[red]error:[/red] {exc}")
        return 1
    if scene is not None:
        import numpy as np

        track = result.x[:, :2]
        on_land = scene.land.contains(track)
        clearance = float(np.min(scene.land.distance_to_shore(track)))
        result.metrics["min_distance_to_shore_m"] = 0.0 if on_land.any() else clearance
        if on_land.any():
            t_ground = float(result.t_s[np.argmax(on_land)])
            console.print(f"[red]aground[/red] at t = {t_ground:.1f} s in {scene.name}")
    table = Table(title=f"{args.manoeuvre} — {params.name} (L = {params.length:g} m)")
    table.add_column("metric")
    table.add_column("value", justify="right")
    for k, v in result.metrics.items():
        table.add_row(k, f"{v:.4g}")
    console.print(table)
    args.out.mkdir(parents=True, exist_ok=True)
    stem = args.out / f"{params.name}_{args.manoeuvre}"
    write_csv(stem.with_suffix(".csv"), result)
    console.print(f"wrote {stem.with_suffix('.csv')}")
    if not args.no_plot:
        plot_manoeuvre(stem.with_suffix(".png"), result, scene)
        console.print(f"wrote {stem.with_suffix('.png')}")
    return 0
