"""The twin's RL controller: contract signature, LiDAR resampling, and the Froude transfer
of one model-scale policy to the 88 m full-scale hull (measured on a path-following run)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from asvtwin.rl.controller import RlController
from asvtwin.rl.policy import FORMAT
from asvtwin.sensors import Lidar, LidarConfig
from asvtwin.vessel import VesselSimulator, cybership2, cybership2_full_scale


@pytest.fixture(scope="module")
def policy(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fixed random tanh policy (any policy is a feedback law: similarity must hold)."""
    rng = np.random.default_rng(7)
    meta = {"format": FORMAT, "obs_dim": 186, "n_rays": 180, "lidar_range_m": 150.0,
            "dt_s": 1.0, "lookahead_m": 150.0, "U_max": 0.5788,
            "reference_length_m": 1.255}
    path = tmp_path_factory.mktemp("pol") / "p.npz"
    W0 = rng.normal(0, 0.3, (16, 186))
    W0[:, 180:] *= 5  # let the navigation features steer
    np.savez(path, W0=W0, b0=rng.normal(0, 0.1, 16), W_out=rng.normal(0, 0.5, (2, 16)),
             b_out=np.array([0.2, 0.0]), meta=np.array(json.dumps(meta)))
    return path


def _run(params, policy: Path, scale: float, steps: int, scan_fn=None) -> np.ndarray:
    ctl = RlController(params, policy_path=policy)
    dt = 0.25 * math.sqrt(scale)
    sim = VesselSimulator(params, [0, 0, 0.2, 0.3 * math.sqrt(scale), 0, 0], dt_s=dt)
    route = np.array([[0.0, 0.0], [300.0, 40.0], [600.0, 0.0]]) * scale
    xs = []
    for k in range(steps):
        x = sim.state
        tau = ctl.act(k * dt, x, route, None if scan_fn is None else scan_fn(x))
        assert tau.shape == (3,) and tau[1] == 0.0
        sim.step(tau)
        xs.append(sim.state)
    return np.array(xs)


def test_froude_transfer_full_scale_matches_model_scale(policy: Path) -> None:
    model = _run(cybership2(), policy, 1.0, 400)
    s = cybership2_full_scale().length / cybership2().length
    full = _run(cybership2_full_scale(), policy, s, 400)
    # positions / s, heading, speeds / √s and yaw rate · √s agree along the whole run
    np.testing.assert_allclose(full[:, :2] / s, model[:, :2], atol=1e-6 * 600)
    np.testing.assert_allclose(full[:, 2], model[:, 2], atol=1e-6)
    np.testing.assert_allclose(full[:, 3:5] / math.sqrt(s), model[:, 3:5], atol=1e-8)
    np.testing.assert_allclose(full[:, 5] * math.sqrt(s), model[:, 5], atol=1e-8)


def test_scan_resampling_uses_the_nearest_ray(policy: Path) -> None:
    ctl = RlController(cybership2(), policy_path=policy)
    lidar = Lidar(LidarConfig(n_rays=360, max_range_m=150.0, range_std_m=0.0,
                              angle_std_rad=0.0))
    own = np.array([0.0, 0.0, 0.5, 0.3, 0.0, 0.0])
    target = np.array([[40 * math.cos(0.5), 40 * math.sin(0.5), 0.5, 0, 0, 0]])
    scan = lidar.scan(own, target, 20.0, 6.0, None, np.random.default_rng(0))
    obs = ctl.observation(own, np.array([[0.0, 0.0], [100.0, 0.0]]), scan)
    ahead = 90  # ray index of bearing 0 (dead ahead) in −π + 2πj/180
    d_ahead = 150.0 * 0 + np.expm1((1 - obs[ahead]) * np.log1p(150.0))
    assert d_ahead == pytest.approx(30.0, abs=0.2)  # the target's stern, 40 − 20/2 m
    assert obs[0] == pytest.approx(0.0, abs=1e-6)  # astern: free
    free = ctl.observation(own, np.array([[0.0, 0.0], [100.0, 0.0]]), None)
    assert (free[:180] == 0).all()


def test_bad_inputs_are_named(policy: Path) -> None:
    from asvtwin.errors import StateError

    ctl = RlController(cybership2(), policy_path=policy)
    with pytest.raises(StateError, match="route must be a finite"):
        ctl.act(0.0, np.zeros(6), np.zeros((1, 2)), None)
    with pytest.raises(StateError, match="nav_state"):
        ctl.act(0.0, np.full(6, np.nan), np.zeros((2, 2)), None)
