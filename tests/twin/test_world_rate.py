"""The default scenario's world rate (10 Hz for the 88 m hull) against the schema's 20 Hz.

The default scene runs its world at 10 Hz (Froude scaling of the paper's 20 Hz model-scale
rate gives 2.4 Hz for the full-scale hull). The same scenario at 20 Hz is the reference:
the ships' tracks sampled every simulated second must agree and the outcome must be the
same. Short version by default; ``ASVTWIN_FULL=1`` runs the whole 600 s scenario.
"""

from __future__ import annotations

import numpy as np
import pytest

from asvtwin.scenarios import default_scenario
from tests.conftest import full_run
from tests.twin.conftest import run_sampled


def _both_rates(controller: str):
    """The default scene under ``controller`` with the world at 10 and at 20 Hz: the own
    ship's and the targets' largest track differences [m] and the two summaries, after
    the checks both controllers share (the ship moved, no contact, the targets agree)."""
    sc = default_scenario().with_controller(controller)
    assert sc.rates.sim_hz == 10.0 and sc.sensors.lidar_rate_hz == 10.0
    duration = 600.0 if full_run() else 60.0
    own10, tg10, s10 = run_sampled(sc, duration, sim_hz=10.0)
    own20, tg20, s20 = run_sampled(sc, duration, sim_hz=20.0)
    d_own = float(np.hypot(*(own10 - own20).T).max())
    d_tg = np.hypot(tg10[..., 0] - tg20[..., 0], tg10[..., 1] - tg20[..., 1])
    assert d_tg.max() < 0.5  # 0.12 m over 600 s under either controller
    # the ship moved: the agreement is not that of two ships at rest
    assert np.hypot(*(own20[-1] - own20[0])) > 100.0
    assert s10.collisions == s20.collisions == 0
    assert s10.groundings == s20.groundings == 0
    return d_own, s10, s20


@pytest.mark.slow
def test_default_world_at_10_hz_follows_the_20_hz_world() -> None:
    """LOS guidance through the filter (the rate was chosen with it): the tracks agree."""
    d_own, s10, s20 = _both_rates("los_psf")
    # measured: 0.02 m after 60 s, 17.4 m over 600 s (own ship, closed loop through the
    # filter; 2.4 m while the filter ran at 2 Hz: a yaw moment held for the 4 s between
    # the 0.25 Hz calls turns a small difference into a later switch of the rudder);
    # 31.9 m with the twin's HPIPM mode SPEED_ABS (2026-12-03)
    assert d_own < (40.0 if full_run() else 0.5)
    for name, d20 in s20.min_distance_targets_m.items():
        # 2,302 against 2,318 m for the ferry over 600 s (the track difference above);
        # 2,309 against 2,283 m with SPEED_ABS
        assert abs(s10.min_distance_targets_m[name] - d20) < 40.0
    assert s10.fallbacks == s20.fallbacks


@pytest.mark.slow
def test_default_world_at_10_hz_keeps_the_policy_as_safe_as_at_20_hz() -> None:
    """The default controller, the trained policy through the filter (rl_psf): its closed
    loop parts further between the rates than LOS does (measured 2026-12-03: 0.01 m after
    60 s, 93.6 m after 600 s; with the twin's HPIPM mode SPEED_ABS 1.05 m after 60 s and
    319 m after 600 s, 1,031 and 848 m sailed), with the same outcome: no contact, land
    131.2 against 129.2 m (SPEED_ABS: 130.5 against 101.1 m, both above the 50 m
    criterion), the ferry 2,634 against 2,572 m (2,575 against 2,664 m), the same filter
    calls."""
    assert default_scenario().own_ship.controller == "rl_psf"
    d_own, s10, s20 = _both_rates("rl_psf")
    assert d_own < (400.0 if full_run() else 2.0)
    assert min(s10.min_distance_land_m, s20.min_distance_land_m) >= (
        default_scenario().criteria.min_distance_land_m)
    assert abs(s10.min_distance_land_m - s20.min_distance_land_m) < 40.0
    for name, d20 in s20.min_distance_targets_m.items():
        assert abs(s10.min_distance_targets_m[name] - d20) < 100.0
    assert s10.filter_calls == s20.filter_calls
