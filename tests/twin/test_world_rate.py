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


@pytest.mark.slow
def test_default_world_at_10_hz_follows_the_20_hz_world() -> None:
    sc = default_scenario()
    assert sc.rates.sim_hz == 10.0 and sc.sensors.lidar_rate_hz == 10.0
    duration = 600.0 if full_run() else 60.0
    own10, tg10, s10 = run_sampled(sc, duration, sim_hz=10.0)
    own20, tg20, s20 = run_sampled(sc, duration, sim_hz=20.0)
    d_own = np.hypot(*(own10 - own20).T)
    d_tg = np.hypot(tg10[..., 0] - tg20[..., 0], tg10[..., 1] - tg20[..., 1])
    # measured: 0.02 m after 60 s, 17.4 m over 600 s (own ship, closed loop through the
    # filter; 2.4 m while the filter ran at 2 Hz: a yaw moment held for the 4 s between
    # the 0.25 Hz calls turns a small difference into a later switch of the rudder);
    # 0.12 m for the targets
    assert d_own.max() < (25.0 if full_run() else 0.5)
    assert d_tg.max() < 0.5
    # the ship moved: the agreement is not that of two ships at rest
    assert np.hypot(*(own20[-1] - own20[0])) > 100.0
    assert s10.collisions == s20.collisions == 0
    assert s10.groundings == s20.groundings == 0
    for name, d20 in s20.min_distance_targets_m.items():
        # 2,302 against 2,318 m for the ferry over 600 s (the track difference above)
        assert abs(s10.min_distance_targets_m[name] - d20) < 25.0
    assert s10.fallbacks == s20.fallbacks
