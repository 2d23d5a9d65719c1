"""``asvtwin sim``: run a standard manoeuvre and write a CSV and a PNG plot."""

from __future__ import annotations

import argparse
import csv
import json
import math
from pathlib import Path

from asvtwin.cli.argtypes import fraction, out_dir

__all__ = ["register", "write_csv"]

#: The CSV's columns: name, meaning, unit (also in docs/vessel.md).
CSV_COLUMNS = (
    ("t_s", "time since the start of the manoeuvre", "s"),
    ("x_m", "north position (scene frame, or the start point)", "m"),
    ("y_m", "east position", "m"),
    ("psi_deg", "heading from north, clockwise", "deg"),
    ("u_m_s", "surge speed (body frame)", "m/s"),
    ("v_m_s", "sway speed (body frame)", "m/s"),
    ("r_deg_s", "yaw rate", "deg/s"),
    ("tau_u_n", "surge thrust reaching the hull (after the thruster lag)", "N"),
    ("tau_v_n", "sway thrust reaching the hull", "N"),
    ("tau_r_nm", "yaw moment reaching the hull", "Nm"),
)


def register(sub: argparse._SubParsersAction) -> None:
    from asvtwin.vessel.manoeuvres import MANOEUVRES
    from asvtwin.vessel.params import VESSELS

    p = sub.add_parser(
        "sim",
        help="run a manoeuvre (turning circle, zig-zag, thrust step); write CSV + PNG",
        description="Simulate a standard manoeuvre with the 3-DOF model and thruster "
                    "dynamics; print its numbers with the IMO MSC.137(76) criteria, write "
                    "<out>/<vessel>_<manoeuvre>.csv and .png.",
    )
    p.add_argument("--vessel", choices=sorted(VESSELS), default="cybership2_full_scale",
                   help="parameter set (default: %(default)s)")
    p.add_argument("--manoeuvre", choices=sorted(MANOEUVRES), default="turning_circle",
                   type=lambda s: s.replace("-", "_"),
                   help="manoeuvre (default: %(default)s)")
    p.add_argument("--surge-fraction", type=fraction, default=None, metavar="F",
                   help="surge thrust as a fraction in (0, 1] of the largest (default: 1.0; "
                        "0.2 for the zig-zag, where CyberShip II is course-unstable "
                        "at higher speed)")
    p.add_argument("--yaw-fraction", type=fraction, default=1.0, metavar="F",
                   help="yaw moment as a fraction in (0, 1] of the largest (turning "
                        "circle, zig-zag; default: %(default)s)")
    p.add_argument("--switch-deg", type=float, default=10.0, metavar="DEG",
                   help="zig-zag heading switch angle in (0, 90) [deg] (default: "
                        "%(default)s)")
    p.add_argument("--dt", type=float, default=None, metavar="S",
                   help="time step [s], below the RK4 stability limit (default: L/U/50)")
    p.add_argument("--out", type=Path, default=out_dir("sim"), metavar="DIR",
                   help="output folder (default: %(default)s)")
    p.add_argument("--no-plot", action="store_true", help="write the CSV only")
    p.add_argument("--json", action="store_true",
                   help="print the metrics, notes and criteria as one JSON object")
    p.add_argument("--scene", default=None, metavar="SCENE",
                   help="run the manoeuvre at the origin of a scene ('default' for the "
                        "embedded Trondheim Fjord, or a scene file); draws the coast and "
                        "reports the closest approach to the shore")
    p.add_argument("--start-heading-deg", type=float, default=0.0, metavar="DEG",
                   help="initial heading [deg from north] (default: %(default)s)")
    p.set_defaults(func=_run)


def write_csv(path: Path, result) -> None:
    """Time series of a manoeuvre as CSV (columns: :data:`CSV_COLUMNS`)."""
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow([c[0] for c in CSV_COLUMNS])
        for t, x, tau in zip(result.t_s, result.x, result.tau):
            w.writerow([f"{t:.4f}", f"{x[0]:.4f}", f"{x[1]:.4f}",
                        f"{math.degrees(x[2]):.4f}", f"{x[3]:.5f}", f"{x[4]:.5f}",
                        f"{math.degrees(x[5]):.5f}", f"{tau[0]:.6g}", f"{tau[1]:.6g}",
                        f"{tau[2]:.6g}"])


def _run(args: argparse.Namespace) -> int:
    from asvtwin.vessel.manoeuvres import MANOEUVRES, METRICS
    from asvtwin.vessel.params import vessel_by_name

    params = vessel_by_name(args.vessel)
    kwargs: dict = {}
    if args.dt is not None:
        kwargs["dt_s"] = args.dt
    if args.manoeuvre != "thrust_step":
        kwargs["yaw_fraction"] = args.yaw_fraction
    surge = args.surge_fraction
    if surge is None:
        surge = 0.2 if args.manoeuvre == "zigzag" else 1.0
    kwargs["surge_fraction"] = surge
    if args.manoeuvre == "zigzag":
        kwargs["switch_deg"] = args.switch_deg
    if args.start_heading_deg != 0.0:
        kwargs["psi0_rad"] = math.radians(args.start_heading_deg)
    # refuse an unusable output path before minutes of simulation
    args.out.mkdir(parents=True, exist_ok=True)
    scene = None
    if args.scene is not None:
        from asvtwin.geo import default_scene, load_scene

        scene = default_scene() if args.scene == "default" else load_scene(args.scene)
    result = MANOEUVRES[args.manoeuvre](params, **kwargs)
    aground = None
    if scene is not None:
        import numpy as np

        track = result.x[:, :2]
        on_land = scene.land.contains(track)
        clearance = float(np.min(scene.land.distance_to_shore(track)))
        result.metrics["min_distance_to_shore_m"] = 0.0 if on_land.any() else clearance
        if on_land.any():
            aground = float(result.t_s[np.argmax(on_land)])
    stem = args.out / f"{params.name}_{args.manoeuvre}"
    write_csv(stem.with_suffix(".csv"), result)
    written = [stem.with_suffix(".csv")]
    if not args.no_plot:
        from asvtwin.plots import manoeuvre_figure, save

        fig = manoeuvre_figure(result, length_m=params.length, scene=scene)
        written.append(save(fig, stem.with_suffix(".png"), dpi=110))
    if args.json:
        print(json.dumps({
            "manoeuvre": result.name, "vessel": params.name, "length_m": params.length,
            "metrics": {k: (None if math.isnan(v) else v) for k, v in result.metrics.items()},
            "notes": result.notes,
            "criteria": [{"name": c.name, "value": None if math.isnan(c.value) else c.value,
                          "limit": c.limit, "unit": c.unit, "passed": c.passed,
                          "clause": c.clause} for c in result.criteria],
            "aground_at_s": aground,
            "files": [str(p) for p in written]}))
        return 0
    from rich.console import Console
    from rich.table import Table

    console = Console()
    if aground is not None and scene is not None:
        console.print(f"[red]aground[/red] at t = {aground:.1f} s in {scene.name}")
    table = Table(title=f"{args.manoeuvre} — {params.name} (L = {params.length:g} m)")
    table.add_column("quantity")
    table.add_column("value", justify="right")
    table.add_column("unit")
    table.add_column("key", style="dim")
    for k, v in result.metrics.items():
        words, unit = METRICS.get(k, (k, ""))
        table.add_row(words, "undefined" if math.isnan(v) else f"{v:.4g}", unit, k)
    console.print(table)
    for k, why in result.notes.items():
        console.print(f"[yellow]{k} undefined:[/yellow] {why}")
    if result.criteria:
        crit = Table(title="IMO MSC.137(76) manoeuvring criteria (for orientation: the "
                           "Standards apply to ships ≥ 100 m with a rudder)")
        for col in ("criterion", "value", "limit", "result", "clause"):
            crit.add_column(col)
        for c in result.criteria:
            crit.add_row(c.name, "undefined" if math.isnan(c.value) else f"{c.value:.3g} {c.unit}",
                         f"≤ {c.limit:.3g} {c.unit}",
                         "[green]pass[/green]" if c.passed else "[red]fail[/red]", c.clause)
        console.print(crit)
    for path in written:
        print(f"wrote {path}")
    return 0
