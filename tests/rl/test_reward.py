"""The paper's reward term by term, against hand computation and independent loops."""

from __future__ import annotations

import math

import numpy as np
import pytest

from asvtwin.errors import ConfigError
from asvtwin.rl.config import EnvConfig, PpoConfig, RewardConfig, check_setup
from asvtwin.rl.reward import r_colav, r_path, r_psf, reward


def test_r_path_hand_values() -> None:
    # on the path, heading along it, at top speed: (1 + γ_r)(1 + γ_r) − γ_r² = 1 + 2γ_r
    assert r_path(0.5, 0.5, 0.0, 0.0, gamma_r=0.1, gamma_e=0.05) == pytest.approx(1.2)
    # 20 m off, heading 60° off, half speed: by hand
    v = (0.5 * math.cos(math.pi / 3) + 0.1) * (math.exp(-0.05 * 20) + 0.1) - 0.01
    assert r_path(0.25, 0.5, math.pi / 3, -20.0, gamma_r=0.1, gamma_e=0.05) == pytest.approx(v)
    # symmetric in ε and in the heading error
    a = r_path([0.3, 0.3], 0.5, [0.4, -0.4], [7.0, -7.0], gamma_r=0.1, gamma_e=0.05)
    assert a[0] == pytest.approx(a[1])


def test_r_colav_is_the_weighted_mean_by_a_loop() -> None:
    rng = np.random.default_rng(1)
    d = rng.uniform(0, 150, 180)
    theta = -np.pi + 2 * np.pi * np.arange(180) / 180
    num = den = 0.0
    for di, ti in zip(d, theta):
        w = 1.0 / (1.0 + 10.0 * abs(ti))
        num += w * math.exp(-0.1 * di)
        den += w
    assert r_colav(d, theta, gamma_theta=10.0, gamma_d=0.1) == pytest.approx(-num / den)
    # nothing near: ~0; everything touching: −1
    assert r_colav(np.full(180, 150.0), theta, gamma_theta=10, gamma_d=0.1) > -1e-6
    assert r_colav(np.zeros(180), theta, gamma_theta=10, gamma_d=0.1) == pytest.approx(-1.0)


def test_r_psf_is_the_equation_not_the_predecessors_bug() -> None:
    u_max = np.array([2.0, 0.0, 0.15])
    # a pure yaw intervention of the full yaw range counts ‖δ‖/‖u_max‖ = 0.3/2.0056
    got = r_psf([1.0, 0.0, 0.15], [1.0, 0.0, -0.15], u_max, gamma_psf=1.0)
    assert got == pytest.approx(-0.3 / math.hypot(2.0, 0.15))
    assert got < -0.1  # the operator-precedence bug gave ~200 times less
    both = r_psf([2.0, 0, 0.15], [0.0, 0, -0.15], u_max, gamma_psf=2.0)
    assert both == pytest.approx(-2.0 * math.hypot(2.0, 0.3) / math.hypot(2.0, 0.15))
    assert r_psf([1, 0, 0], [1, 0, 0], u_max, gamma_psf=1.0) == 0.0


def test_total_reward_and_collision_override() -> None:
    cfg = RewardConfig()
    theta = -np.pi + 2 * np.pi * np.arange(8) / 8
    d = np.array([[150.0] * 8, [3.0] * 8])
    t = reward(cfg, u=[0.4, 0.4], U_max=0.58, psi_bar=[0.1, 0.1], epsilon=[5.0, 5.0], d=d,
               theta=theta, u_L=[[2, 0, 0.1]] * 2, u_0=[[1.5, 0, 0.1]] * 2,
               u_max=[2, 0, 0.15], collision=[False, True])
    lam = cfg.lambda_
    want = (lam * r_path(0.4, 0.58, 0.1, 5.0, gamma_r=cfg.gamma_r, gamma_e=cfg.gamma_e)
            + (1 - lam) * r_colav(d[0], theta, gamma_theta=10, gamma_d=0.1)
            + r_psf([2, 0, 0.1], [1.5, 0, 0.1], [2, 0, 0.15], gamma_psf=1.0) + cfg.r_exists)
    assert t.total[0] == pytest.approx(want)
    assert t.total[1] == cfg.r_collision
    assert t.r_path[1] == t.r_colav[1] == t.r_psf[1] == 0.0
    parts = t.r_path + t.r_colav + t.r_psf + t.r_exists + t.r_collision
    np.testing.assert_allclose(parts, t.total)


@pytest.mark.parametrize("field,value", [("gamma_psf", -1.0), ("lambda_", 1.5),
                                         ("r_collision", 10.0), ("gamma_d", float("nan"))])
def test_bad_reward_config_names_the_field(field: str, value: float) -> None:
    with pytest.raises(ConfigError, match=f"RewardConfig.{field}"):
        RewardConfig(**{field: value})


def test_bad_setup_and_configs() -> None:
    with pytest.raises(ConfigError, match="unknown setup 'dqn'.*ppo, ppo_psf, ppo_psf_moving"):
        check_setup("dqn")
    with pytest.raises(ConfigError, match="EnvConfig.family"):
        EnvConfig(family="harbour")
    with pytest.raises(ConfigError, match="EnvConfig.psf_solver_circles"):
        EnvConfig(psf_solver_circles=0)
    with pytest.raises(ConfigError, match="PpoConfig.gamma"):
        PpoConfig(gamma=1.5)
    with pytest.raises(ConfigError, match="does not fit EnvConfig"):
        EnvConfig.from_dict({"setup": "ppo", "speed": 3}, source="run.json")
