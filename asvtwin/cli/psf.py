"""``asvtwin psf``: the predictive safety filter from the command line.

``asvtwin psf demo`` runs a naive controller (full thrust straight ahead) into a seeded
adversarial scene with and without the filter and writes ``psf_demo.png`` (the paper's
picture: predicted safe path green, critical region red) and ``psf_delta_u.csv`` (the
intervention δ_u = u_L − u_0 over time).
"""

from __future__ import annotations

import argparse
import csv
import logging
from pathlib import Path

from asvtwin.cli.argtypes import out_dir, positive_float

__all__ = ["register"]

log = logging.getLogger(__name__)


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("psf", help="predictive safety filter tools",
                              description="Predictive safety filter (NMPC) tools.")
    sub = p.add_subparsers(title="psf commands", metavar="COMMAND")
    d = sub.add_parser("demo", help="closed-loop demo: plot and δ_u CSV",
                       description="Run a naive full-thrust controller at obstacles with "
                                   "and without the safety filter; write a PNG and a CSV.")
    d.add_argument("--out", type=Path, default=out_dir("psf"),
                   help="output directory (default: %(default)s)")
    d.add_argument("--seed", type=int, default=7, help="scenario seed (default 7)")
    d.add_argument("--backend", default="auto",
                   choices=("auto", "acados", "casadi-ipopt", "casadi-fatrop"),
                   help="solver backend (default: %(default)s)")
    d.add_argument("--duration", type=positive_float, default=60.0,
                   help="simulated time [s], > 0")
    d.set_defaults(func=_demo)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])


def _demo(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from asvtwin.control import PsfConfig, SafetyFilter
    from asvtwin.control.closed_loop import adversarial_scenario, run_closed_loop
    from asvtwin.vessel import cybership2

    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    params = cybership2()
    rng = np.random.default_rng(args.seed)
    scene = adversarial_scenario(rng, "obstacle", n_clutter=10)
    psf = SafetyFilter(params, config=PsfConfig(backend=args.backend))
    free = run_closed_loop(params, scene, None, mode="unfiltered", duration_s=args.duration)
    run = run_closed_loop(params, scene, psf, duration_s=args.duration)
    res = run.results
    # the first call where the filter intervened: its plan is the picture's green path
    k_show = next((k for k, r in enumerate(res) if r.intervened), 0)
    shown = res[k_show]

    fig, ax = plt.subplots(figsize=(7.5, 7.5))
    for (n, e), r in zip(scene.circles.centres, scene.circles.radii):
        ax.add_patch(plt.Circle((e, n), r, color="0.55", zorder=2))
    crit_idx = sorted({a.index for r in res for a in r.active if a.kind == "circle"})
    for j in crit_idx:  # critical region: obstacle grown by d_safe
        (n, e), r = scene.circles.centres[j], scene.circles.radii[j]
        ax.add_patch(plt.Circle((e, n), r + psf.d_safe_m, color="red", alpha=0.25, zorder=1,
                                label="critical region (r + d_safe)" if j == crit_idx[0]
                                else None))
        ax.add_patch(plt.Circle((e, n), r + psf.d_safe_m + psf.d_f_m, fill=False, ls=":",
                                color="red", zorder=1,
                                label="terminal clearance (r + d_safe + d_f)"
                                if j == crit_idx[0] else None))
    ax.plot(free.x[:, 1], free.x[:, 0], "--", color="0.3", lw=1.2,
            label="naive controller, unfiltered")
    ax.plot(run.x[:, 1], run.x[:, 0], color="tab:blue", lw=2.0, label="filtered (executed)")
    ax.plot(shown.x_pred[:, 1], shown.x_pred[:, 0], color="green", lw=2.5,
            label=f"predicted safe path at t = {k_show * psf.config.dt_s:.1f} s")
    ax.plot(shown.x_pred[0, 1], shown.x_pred[0, 0], "o", color="green")
    ax.plot(scene.x0[1], scene.x0[0], "k^", ms=9, label="start")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.set_aspect("equal")
    ax.set_xlim(-25, 25)
    ax.set_ylim(-5, 45)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    n_int = sum(r.intervened for r in res)
    ax.set_title(f"Predictive safety filter ({res[0].backend}, N={psf.config.N}, seed "
                 f"{args.seed})\nmin clearance {run.min_clearance_m:.2f} m filtered vs "
                 f"{free.min_clearance_m:.2f} m unfiltered; {n_int}/{len(res)} "
                 "steps corrected", fontsize=10)
    png = out / "psf_demo.png"
    fig.savefig(png, dpi=110, bbox_inches="tight")
    plt.close(fig)

    path = out / "psf_delta_u.csv"
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t_s", "u_L_surge_N", "u_L_yaw_Nm", "u0_surge_N", "u0_yaw_Nm",
                    "delta_u_surge_N", "delta_u_sway_N", "delta_u_yaw_Nm", "fallback",
                    "min_margin_m", "solve_ms"])
        for k, r in enumerate(res):
            uL = r.u0 + r.delta_u
            w.writerow([f"{k * psf.config.dt_s:.2f}", f"{uL[0]:.4f}", f"{uL[2]:.4f}",
                        f"{r.u0[0]:.4f}", f"{r.u0[2]:.4f}", f"{r.delta_u[0]:.4f}",
                        f"{r.delta_u[1]:.4f}", f"{r.delta_u[2]:.4f}", r.fallback,
                        f"{r.obstacle_margin_m[1:].min():.3f}", f"{r.solve_time_s * 1e3:.2f}"])
    print(f"wrote {png} and {path}; min clearance {run.min_clearance_m:.2f} m (filtered), "
          f"{free.min_clearance_m:.2f} m (unfiltered)")
    return 0
