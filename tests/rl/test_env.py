"""The environment: Gymnasium's checker, the batched kernels against shapely, seeds, NaN
actions, and the safety filter's reach culling."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from shapely.geometry import LineString, Point

from asvtwin.rl.config import EnvConfig
from asvtwin.rl.kernels import cast_circles, path_features
from asvtwin.rl.observation import SAFE_ACTION, action_to_tau, ray_bearings
from asvtwin.rl.scenarios import random_scenario
from asvtwin.rl.vec_env import VecPathEnv, top_speed
from asvtwin.vessel import VesselSimulator, cybership2

gym = pytest.importorskip("gymnasium")


def test_gymnasium_env_checker_without_filter() -> None:
    from gymnasium.utils.env_checker import check_env

    from asvtwin.rl.env import PathColavEnv

    env = PathColavEnv(setup="ppo")
    check_env(env, skip_render_check=True)
    assert env.observation_space.shape == (186,)


@pytest.mark.parametrize("setup", ["ppo_psf", "ppo_psf_moving"])
def test_gymnasium_env_checker_with_filter(setup: str) -> None:
    from gymnasium.utils.env_checker import check_env

    from asvtwin.rl.env import PathColavEnv

    env = PathColavEnv(EnvConfig(psf_horizon=40), setup=setup)
    check_env(env, skip_render_check=True)
    assert len(env.world.filters) == 1


def test_top_speed_is_the_steady_state_of_the_simulator() -> None:
    p = cybership2()
    sim = VesselSimulator(p, [0, 0, 0, 0, 0, 0], dt_s=0.5)
    for _ in range(800):
        x = sim.step([2.0, 0.0, 0.0])
    assert top_speed(p) == pytest.approx(x[3], rel=1e-6)
    assert top_speed(p) == pytest.approx(0.5788, abs=2e-3)  # "about 0.57 m/s" (Skjetne 2004)


def test_lidar_kernel_against_shapely() -> None:
    rng = np.random.default_rng(4)
    rel = ray_bearings(180)
    circles = np.zeros((2, 4, 3))
    circles[:, :, :2] = rng.uniform(-60, 60, (2, 4, 2))
    circles[:, :, 2] = rng.uniform(3, 20, (2, 4))
    circles[1, 3, 2] = 0.0  # an unused slot
    pos = np.array([[0.0, 0.0], [5.0, -3.0]])
    circles[:, :, :2] += 3 * (circles[:, :, 2:3] + 5) * np.sign(circles[:, :, :2])  # keep out
    psi = np.array([0.3, -2.0])
    d = np.empty((2, 180))
    k = np.empty((2, 180), dtype=np.int64)
    cast_circles(pos, psi, rel, circles, 150.0, d, k)
    for i in range(2):
        discs = [Point(c[0], c[1]).buffer(c[2], quad_segs=512) for c in circles[i] if c[2] > 0]
        union = shapely.union_all(discs)
        for j in range(0, 180, 7):
            a = psi[i] + rel[j]
            ray = LineString([pos[i], pos[i] + 150 * np.array([np.cos(a), np.sin(a)])])
            inter = ray.intersection(union)
            want = 150.0 if inter.is_empty else Point(pos[i]).distance(inter)
            assert d[i, j] == pytest.approx(want, abs=2e-3)
    # inside a circle every ray returns 0 (a collision)
    inside = circles.copy()
    inside[0, 0] = (pos[0, 0] + 1.0, pos[0, 1], 5.0)
    cast_circles(pos, psi, rel, inside, 150.0, d, k)
    assert (d[0] == 0).all() and (k[0] == 0).all()


def test_path_features_against_shapely() -> None:
    rng = np.random.default_rng(2)
    sc = random_scenario(rng, "static")
    path = sc.path
    line = LineString(path)
    s_cum = np.concatenate([[0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))])
    for _ in range(20):
        j = int(rng.integers(0, len(path) - 1))
        p = path[j] + rng.normal(0, 8, 2)
        out = np.empty((1, 5))
        idx = np.array([j])
        path_features(p[None], np.array([0.2]), path[None], s_cum[None], idx, 300, 150.0, out)
        assert out[0, 0] == pytest.approx(line.project(Point(p)), abs=1e-6)
        assert abs(out[0, 1]) == pytest.approx(line.distance(Point(p)), abs=1e-6)
        la = line.interpolate(min(out[0, 0] + 150.0, line.length))
        bearing = np.arctan2(la.y - p[1], la.x - p[0])
        assert np.cos(out[0, 3] - (bearing - 0.2)) == pytest.approx(1.0, abs=1e-9)
    # a ship 10 m east of a path heading north has ε = +10 (starboard of the path)
    straight = np.column_stack([np.linspace(0, 100, 11), np.zeros(11)])
    sc2 = np.linspace(0, 100, 11)
    path_features(np.array([[50.0, 10.0]]), np.array([0.0]), straight[None], sc2[None],
                  np.array([0]), 20, 150.0, out)
    assert out[0, 1] == pytest.approx(10.0) and out[0, 4] == pytest.approx(0.5)


def test_same_seed_same_rollout_and_vectorised_equals_single() -> None:
    a = VecPathEnv(3, EnvConfig(family="mixed"), seed=11)
    b = VecPathEnv(3, EnvConfig(family="mixed"), seed=11)
    rng = np.random.default_rng(0)
    for _ in range(50):
        act = rng.uniform(-1, 1, (3, 2))
        oa, ra, *_ = a.step(act)
        ob, rb, *_ = b.step(act)
    np.testing.assert_array_equal(oa, ob)
    np.testing.assert_array_equal(ra, rb)
    # one environment alone evolves exactly as its row in the batch
    c = VecPathEnv(1, EnvConfig(family="mixed"), seed=0)
    for i in range(3):
        d = VecPathEnv(3, EnvConfig(family="mixed"), seed=5)
        sc = random_scenario(np.random.default_rng(i), "moving")
        d.load_scenario(i, sc)
        c.load_scenario(0, sc)
        for _ in range(30):
            act = np.tile([0.2, 0.1], (3, 1))
            od, *_ = d.step(act)
            oc, *_ = c.step(act[:1])
        np.testing.assert_allclose(od[i], oc[0], rtol=0, atol=1e-6)


def test_nan_actions_become_the_safe_action_and_are_counted() -> None:
    tau, bad = action_to_tau(np.array([[np.nan, 0.5], [0.0, np.inf], [0.2, -0.3]]),
                             np.array([2.0, 0.0, 0.15]))
    assert bad.tolist() == [True, True, False]
    safe, _ = action_to_tau(SAFE_ACTION[None], np.array([2.0, 0.0, 0.15]))
    np.testing.assert_array_equal(tau[0], safe[0])
    np.testing.assert_array_equal(safe[0], [0.0, 0.0, 0.0])
    np.testing.assert_allclose(tau[2], [1.2, 0.0, -0.045])
    env = VecPathEnv(2, EnvConfig(max_steps=5), seed=1)
    for _ in range(5):
        _, _, _, _trunc, recs, _ = env.step(np.array([[np.nan, np.nan], [0.0, 0.0]]))
    assert recs[0] is not None and recs[0].nan_actions == 5 and recs[1].nan_actions == 0


def test_episode_ends_on_collision_with_the_collision_reward() -> None:
    env = VecPathEnv(1, EnvConfig(), seed=3)
    env.static[0, 0] = (env.x[0, 0] + 6 * np.cos(env.x[0, 2]),
                        env.x[0, 1] + 6 * np.sin(env.x[0, 2]), 4.0)
    for _ in range(60):
        _, r, term, _, recs, _ = env.step(np.array([[1.0, 0.0]]))
        if recs[0] is not None:
            break
    assert recs[0] is not None and recs[0].collision and term[0]
    assert r[0] == env.config.reward.r_collision


def test_filter_culling_is_exact_beyond_reach() -> None:
    """Where the environment skips the filter (no obstacle within reach), the filter
    itself would have passed u_L: checked on the real filter with the obstacle just
    beyond the reach radius."""
    from asvtwin.control import CircleObstacles

    env = VecPathEnv(1, EnvConfig(setup="ppo_psf", psf_horizon=40), seed=0)
    f = env.filters[0]
    reach = 1.05 * env.U_max * 40 * 0.5 + f.d_safe_m + f.d_f_m
    x = np.array([0, 0, 0, env.U_max, 0, 0])
    for u_L in ([2.0, 0.0, 0.0], [0.7, 0.0, 0.15], [1.4, 0.0, -0.1]):
        f.reset()
        obs = CircleObstacles(centres=[[reach + 8.0 + 0.5, 0.0]], radii=[8.0])
        res = f.filter(x, u_L, obs, t_s=0.0)
        assert res.fallback == "none"
        # within 1 % of each input's range (the filter's own tie-break ε)
        assert (np.abs(res.u0 - u_L) <= 0.01 * np.array([2, 1, 0.3])).all(), (res.u0, u_L)


@pytest.mark.parametrize("setup", ["ppo_psf", "ppo_psf_moving"])
def test_batched_pre_cull_never_skips_an_environment_the_filter_needs(setup: str) -> None:
    """The one-pass numpy pre-cull (:meth:`VecPathEnv._may_need_filter`) may only skip
    environments for which the per-environment obstacle construction returns nothing:
    ships put at random around the obstacles (0–120 m from a circle, random heading and
    time), every environment the per-environment rule would filter is kept, and some
    far ones are skipped."""
    env = VecPathEnv(16, EnvConfig(setup=setup, psf_horizon=40), seed=3)
    rng = np.random.default_rng(7)
    kept = skipped = 0
    for _ in range(40):
        k = rng.integers(0, env.circles.shape[1], env.n)
        env.t_s[:] = rng.uniform(0, 300, env.n)
        env._update_circles(slice(None))
        c = env.circles[np.arange(env.n), k]
        ang = rng.uniform(-np.pi, np.pi, env.n)
        dist = c[:, 2] + rng.uniform(0, 120, env.n)
        env.x[:, 0] = c[:, 0] + dist * np.cos(ang)
        env.x[:, 1] = c[:, 1] + dist * np.sin(ang)
        env.x[:, 2] = rng.uniform(-np.pi, np.pi, env.n)
        env._sense()
        need = env._may_need_filter()
        for i in range(env.n):
            if env._filter_obstacles(i):
                assert need[i], (setup, i)
                kept += 1
            else:
                skipped += not need[i]
    assert kept > 20 and skipped > 20, (kept, skipped)


def _lidar_circles_as_before(env: VecPathEnv, i: int) -> tuple[np.ndarray, np.ndarray]:
    """The static circles of environment i built the former way: the masked ranges
    through :func:`asvtwin.control.lidar_circles`, then culled by reach."""
    from asvtwin.control import lidar_circles
    from asvtwin.rl.scenarios import N_STATIC

    cfg = env.config
    rays = env.ranges[i]
    ranges = np.where(rays < cfg.lidar_range_m, rays, np.inf)
    if cfg.setup == "ppo_psf_moving":
        ranges = np.where(env.hit[i] >= N_STATIC, np.inf, ranges)
    if not np.min(ranges) < min(cfg.psf_lidar_range_m, env._reach_m):
        return np.zeros((0, 2)), np.zeros(0)
    circ = lidar_circles(env.x[i, :2], env.x[i, 2] + env.rel, ranges,
                         max_range_m=cfg.psf_lidar_range_m)
    keep = np.hypot(*(circ.centres - env.x[i, :2]).T) - circ.radii < env._reach_m
    return circ.centres[keep], circ.radii[keep]


@pytest.mark.parametrize("setup", ["ppo_psf", "ppo_psf_moving"])
def test_compiled_lidar_selection_builds_the_circles_of_lidar_circles(setup: str) -> None:
    """The filter's static circles come from a compiled selection of the LiDAR returns
    (:func:`asvtwin.rl.kernels.lidar_selection`); they are the circles
    :func:`asvtwin.control.lidar_circles` builds from the same returns, in the same
    order, bit for bit: ships at random 0-40 m from an obstacle's edge, random heading
    (including angles that wrap), with sectors holding more returns than are kept."""
    from asvtwin.control import CircleObstacles

    env = VecPathEnv(16, EnvConfig(setup=setup, psf_horizon=40), seed=5)
    rng = np.random.default_rng(11)
    compared = crowded = 0
    for _ in range(30):
        k = rng.integers(0, 8, env.n)  # the static circles
        c = env.static[np.arange(env.n), k]
        ang = rng.uniform(-np.pi, np.pi, env.n)
        dist = c[:, 2] + rng.uniform(0.5, 40, env.n)
        env.x[:, 0] = c[:, 0] + dist * np.cos(ang)
        env.x[:, 1] = c[:, 1] + dist * np.sin(ang)
        env.x[:, 2] = rng.uniform(-4 * np.pi, 4 * np.pi, env.n)
        env._sense()
        for i in range(env.n):
            want_c, want_r = _lidar_circles_as_before(env, i)
            got = [o for o in env._filter_obstacles(i) if isinstance(o, CircleObstacles)]
            assert len(got) <= 1
            got_c = got[0].centres if got else np.zeros((0, 2))
            got_r = got[0].radii if got else np.zeros(0)
            assert np.array_equal(got_c, want_c) and np.array_equal(got_r, want_r), i
            compared += len(want_r) > 0
            crowded += len(want_r) >= 10
    assert compared > 100 and crowded > 10, (compared, crowded)


def test_lidar_selection_keeps_the_closest_per_sector() -> None:
    """The selection on hand-made returns: per sector the closest, at most per_sector,
    sectors in order, ties by ray index, moving returns and far ones skipped, and nothing
    at all when no return is within ``lim``."""
    from asvtwin.rl.kernels import lidar_selection

    rel = np.deg2rad(np.arange(0, 360, 10.0))  # 36 rays, 9 sectors of 40 degrees: 4 each
    r = np.full(36, 150.0)
    r[[0, 1, 2, 3]] = [5.0, 3.0, 3.0, 4.0]  # sector 0: 1 and 2 tie, then 3, then 0
    r[4] = 20.0  # sector 1
    r[5] = 2.0  # sector 1, but from a moving obstacle
    r[35] = 29.0  # sector 8
    r[30] = 31.0  # beyond max_range
    hit = np.zeros(36, dtype=np.int64)
    hit[5] = 9
    out = np.empty(27, dtype=np.int64)
    n = lidar_selection(0.0, rel, r, hit, 8, 150.0, 30.0, 30.0, 9, 3, out)
    assert out[:n].tolist() == [1, 2, 3, 4, 35]
    assert lidar_selection(0.0, rel, r, hit, 8, 150.0, 2.5, 30.0, 9, 3, out) == 0
    # rotated by one sector: the same rays land one sector later (the order changes)
    n = lidar_selection(np.deg2rad(40.0), rel, r, hit, 8, 150.0, 30.0, 30.0, 9, 3, out)
    assert out[:n].tolist() == [35, 1, 2, 3, 4]


def test_filter_with_fewer_solver_slots_than_circles_keeps_d_safe_from_all() -> None:
    """The RL world gives the filter's OCP 8 circle slots and no coast slots
    (``EnvConfig.psf_solver_circles``); a ship heading into a static obstacle sees far
    more LiDAR circles than that. Whatever the filter applies is a plan that keeps
    d_safe from *every* circle (checked here by plain distances, not by the filter's own
    certification) or, failing that, a checked fallback."""
    env = VecPathEnv(1, EnvConfig(setup="ppo_psf", psf_horizon=40), seed=0)
    f = env.filters[0]
    assert (f.spec.n_circles, f.spec.n_segments) == (8, 0)
    psi = env.x[0, 2]
    ahead = np.array([np.cos(psi), np.sin(psi)])
    env.static[0, 0] = (*(env.x[0, :2] + 22.0 * ahead), 12.0)  # 10 m ahead, 12 m radius
    env._sense(np.array([0]))
    applied = 0
    for _ in range(6):
        obs = env._filter_obstacles(0)
        centres = np.concatenate([o.centres for o in obs])
        radii = np.concatenate([o.radii for o in obs])
        assert len(radii) > f.spec.n_circles
        res = f.filter(env.x[0], np.array([2.0, 0.0, 0.0]), obs, t_s=float(env.t_s[0]))
        if res.fallback == "none":
            gap = (np.hypot(*(res.x_pred[1:, None, :2] - centres[None]).transpose(2, 0, 1))
                   - radii[None])
            assert gap.min() >= f.d_safe_m - f.certify_tol_m, gap.min()
            applied += 1
        env.step(np.array([[1.0, 0.0]]))
    assert applied >= 1
