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

from asvtwin.cli.argtypes import PSF_BACKENDS, out_dir, positive_float

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
                   choices=PSF_BACKENDS,
                   help="solver backend (default: %(default)s)")
    d.add_argument("--duration", type=positive_float, default=60.0,
                   help="simulated time [s], > 0")
    d.set_defaults(func=_demo)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])


def _demo(args: argparse.Namespace) -> int:
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
    from asvtwin.plots import save
    from asvtwin.plots.psf import psf_demo_figure

    png = save(psf_demo_figure(scene, free, run, psf, seed=args.seed), out / "psf_demo.png",
               dpi=110)

    path = out / "psf_delta_u.csv"
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        # columns (docs/psf.md): plan_clearance_m is the plan's closest approach to an
        # obstacle's edge over stages 1..N; d_safe_margin_m that minus d_safe (>= 0: the
        # plan keeps d_safe); terminal_margin_m the stage-N distance minus d_safe + d_f
        w.writerow(["t_s", "u_L_surge_N", "u_L_yaw_Nm", "u0_surge_N", "u0_yaw_Nm",
                    "delta_u_surge_N", "delta_u_sway_N", "delta_u_yaw_Nm", "intervened",
                    "fallback", "plan_clearance_m", "d_safe_margin_m", "terminal_margin_m",
                    "solve_ms", "explanation"])
        for k, r in enumerate(res):
            uL = r.u0 + r.delta_u
            m = r.obstacle_margin_m
            d_margin = min(float(m[1:-1].min()), float(m[-1]) + psf.d_f_m)
            w.writerow([f"{k * psf.config.dt_s:.2f}", f"{uL[0]:.4f}", f"{uL[2]:.4f}",
                        f"{r.u0[0]:.4f}", f"{r.u0[2]:.4f}", f"{r.delta_u[0]:.4f}",
                        f"{r.delta_u[1]:.4f}", f"{r.delta_u[2]:.4f}", int(r.intervened),
                        r.fallback, f"{d_margin + psf.d_safe_m:.3f}", f"{d_margin:.3f}",
                        f"{float(m[-1]):.3f}", f"{r.solve_time_s * 1e3:.2f}", r.explanation])
    print(f"wrote {png} and {path}; min clearance {run.min_clearance_m:.2f} m (filtered), "
          f"{free.min_clearance_m:.2f} m (unfiltered)")
    return 0
