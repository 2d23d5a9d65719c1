"""``asvtwin whatif SCENARIO_OR_RECORDING [--at T]``: ask the twin "what if?".

A scenario (a file or a library name) is run through the twin up to ``--at`` seconds and
forked at its last snapshot; a recording (``.mcap``) is forked at its snapshot nearest before ``--at``.
Each alternative (``--alt``, repeatable; default: follow the route with and without the
safety filter, keep course, 30° to starboard) is rolled out ``--rollouts`` times and the
answer printed: collision and grounding probability with 95 % intervals, closest
approach, filter interventions, the COLREG encounters and the recommendation.

Exit code 1 when no own-ship alternative has an acceptable risk.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from asvtwin.cli.argtypes import non_negative_float, positive_float, positive_int

__all__ = ["register"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "whatif",
        help="fork the twin at a time and compare alternatives by Monte Carlo risk",
        description=__doc__.split("\n\n", 1)[1] if __doc__ else None,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("source", metavar="SCENARIO_OR_RECORDING",
                   help="scenario file or library name, or a .mcap recording")
    p.add_argument("--at", type=non_negative_float, default=0.0, metavar="T",
                   help="fork at the twin's last snapshot at or before this simulation "
                        "time [s] (default: %(default)s)")
    p.add_argument("--alt", action="append", default=None, metavar="SPEC",
                   help="alternative: route, keep_course, starboard:DEG, port:DEG, "
                        "slow:FRAC, stop, target_turns:ID:DEG, target_speeds_up:ID:F, "
                        "wind:SPEED:FROM_DEG, each optionally +filter_off (repeatable)")
    p.add_argument("--rollouts", type=positive_int, default=100, metavar="N",
                   help="Monte Carlo futures per alternative (default: %(default)s)")
    p.add_argument("--horizon", type=positive_float, default=120.0, metavar="S",
                   help="how far ahead [s] (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="seed of the draws (default: 0)")
    p.add_argument("--workers", type=positive_int, default=1, metavar="K",
                   help="processes to split the rollouts over (default: %(default)s)")
    p.add_argument("--ray", metavar="ADDRESS", default=None,
                   help="split the rollouts over Ray tasks: 'local' starts a local Ray "
                        "with --workers CPUs, else an existing cluster's address")
    p.add_argument("--full-rate", action="store_true",
                   help="call the safety filter at the twin's full rate in every future "
                        "(no economy; slow)")
    p.add_argument("--json", action="store_true", help="print the answer as JSON")
    p.set_defaults(func=whatif)


def fork_source(source: str, at_s: float) -> tuple[Any, Any, Any]:
    """(fork, land, own params) from a recording or a scenario run up to ``at_s``."""
    from asvtwin.errors import ParameterError
    from asvtwin.scenarios import Scenario, load_any, resolve_scene
    from asvtwin.twin import Recording, Twin
    from asvtwin.twin.runtime import own_params
    from asvtwin.units import KNOT_M_S
    from asvtwin.whatif import fork

    path = Path(source)
    if path.suffix == ".mcap":
        rec = Recording(path)
        scen = Scenario.model_validate(rec.scenario) if rec.scenario else None
        end = rec.duration_s
        if at_s > end + 1.0:
            raise ParameterError(f"whatif --at {at_s:g} s is after the last snapshot of "
                                 f"{path} (t = {end:.1f} s); choose --at in [0, {end:.1f}]")
        msg = rec.message_at(at_s)
        cruise = scen.own_ship.cruise_speed_kn * KNOT_M_S if scen else None
        land = resolve_scene(scen).land if scen else None
        params = own_params(scen) if scen else None
        return fork(msg, cruise_speed_m_s=cruise), land, params
    scen = load_any(source)
    twin = Twin(scen)
    try:
        snap = twin.step()
        while twin.t_s + 1e-9 < at_s:
            snap = twin.step()
        snap = twin.latest()
    finally:
        twin.close()
    f = fork(snap, cruise_speed_m_s=scen.own_ship.cruise_speed_kn * KNOT_M_S)
    return f, twin.scene.land, twin.params


def _table(ans: Any) -> str:
    lines = [(f"what-if at t = {ans.t_s:.1f} s: {ans.rollouts} futures × "
             f"{len(ans.alternatives)} alternatives, {ans.horizon_s:.0f} s ahead, seed "
             f"{ans.seed} ({ans.timing['answer_s']:.1f} s)")]
    for e in ans.encounters:
        lines.append(f"  encounter: {e.describe()} — rule {e.rule or '-'}")
    lines.append(f"  {'alternative':<26} {'P(collision) [95 % CI]':>26} {'P(ground)':>10} "
                 f"{'closest [m] 5/50 %':>19} {'interv.':>8}")
    for a in ans.alternatives:
        lo, hi = a.p_collision_ci
        lines.append(f"  {a.label:<26} {100 * a.p_collision:7.1f} % [{100 * lo:5.1f}–"
                     f"{100 * hi:5.1f} %] {100 * a.p_grounding:8.1f} % "
                     f"{a.min_distance_m[0]:9.0f} {a.min_distance_m[1]:9.0f} "
                     f"{a.interventions:8.1f}")
    lines.append(f"recommendation: {ans.recommendation.label} (rule "
                 f"{ans.recommendation.rule or '-'})")
    lines.append(f"  {ans.recommendation.reason}")
    return "\n".join(lines)


def whatif(args: argparse.Namespace) -> int:
    from asvtwin.cli.run import native_stdout_to_stderr

    # acados prints QP warnings on fd 1: with --json they go to stderr
    with native_stdout_to_stderr(args.json) as out:
        return _whatif(args, out)


def _whatif(args: argparse.Namespace, out: Any) -> int:
    from asvtwin.cli import EXIT_CHECK_FAILED, EXIT_OK
    from asvtwin.whatif import RolloutConfig, ask, parse_alternative

    alts = [parse_alternative(s) for s in args.alt] if args.alt else None
    f, land, params = fork_source(args.source, args.at)
    cfg = RolloutConfig(horizon_s=args.horizon, economy=not args.full_rate)
    if args.ray:
        from asvtwin.whatif import RayExecutor

        rex = RayExecutor(args.ray, num_cpus=args.workers)
        try:
            ans = ask(f, alts, rollouts=args.rollouts, seed=args.seed, config=cfg, land=land,
                      params=params, executor=rex, workers=max(2, args.workers))
        finally:
            rex.shutdown()
    elif args.workers > 1:
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(args.workers) as ex:
            ans = ask(f, alts, rollouts=args.rollouts, seed=args.seed, config=cfg, land=land,
                      params=params, executor=ex, workers=args.workers)
    else:
        ans = ask(f, alts, rollouts=args.rollouts, seed=args.seed, config=cfg, land=land,
                  params=params)
    if args.json:
        json.dump(ans.to_dict(), out, indent=2, default=float)
        print(file=out)
    else:
        print(_table(ans), file=out)
    return EXIT_OK if ans.recommendation.acceptable else EXIT_CHECK_FAILED
