"""The path-following and collision-avoidance world for n environments at once.

:class:`VecPathEnv` steps n own ships (CyberShip II, forward-only surge force and yaw
moment), each with its own random path and obstacles, in one compiled call per stage
(:func:`asvtwin.vessel.kernels.step_batch`), casts all LiDARs in one call
(:func:`asvtwin.rl.kernels.cast_circles`) and computes every path feature in one call
(:func:`asvtwin.rl.kernels.path_features`). Episodes that end are reset in place (the
vector-environment convention) and reported as :class:`EpisodeRecord`.

With a safety-filter setup each environment has its own
:class:`asvtwin.control.SafetyFilter` (plans and warm starts are per vessel), all built
once in the constructor (the compiled solver is loaded from its cache; never rebuilt in
the loop). The filter is called for an environment only when some obstacle of its set
could matter within the horizon (see :meth:`VecPathEnv._filter_obstacles`): beyond reach
no constraint can be active and u_0 = u_L.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import brentq

from asvtwin.checks import F8 as _F8
from asvtwin.rl.config import EnvConfig
from asvtwin.rl.kernels import cast_circles, filter_reach, lidar_selection, path_features
from asvtwin.rl.observation import N_NAV, action_to_tau, closeness, nav_features, ray_bearings
from asvtwin.rl.reward import reward
from asvtwin.rl.scenarios import N_MOVING, N_PATH, N_STATIC, Scenario, random_scenario
from asvtwin.vessel.kernels import step_batch
from asvtwin.vessel.params import VesselParams, cybership2

__all__ = ["EpisodeRecord", "VecPathEnv", "collision_width", "top_speed"]

_SUBSTEPS = 4  # RK4 stages per environment step (0.25 s at dt 1 s)
_WINDOW = 24  # path segments searched either side of the last closest one


def top_speed(params: VesselParams) -> float:
    """Steady surge speed at full forward thrust [m/s]: d11(u) u = F_u,max."""
    p = params.packed()
    F = params.actuators.tau_max[0]
    return float(brentq(lambda u: (-p[12] - p[13] * u - p[14] * u * u) * u - F, 0.0, 100.0))


@dataclass(frozen=True)
class EpisodeRecord:
    """One finished episode: sums of the reward and each term, outcome, CTE, filter use."""

    env: int
    seed_index: int
    length: int
    reward: float
    r_path: float
    r_colav: float
    r_psf: float
    r_exists: float
    r_collision: float
    collision: bool
    collision_moving: bool
    goal: bool
    truncated: bool
    mean_abs_cte_m: float
    progress: float
    interventions: int
    fallbacks: int
    filter_calls: int
    filter_time_s: float
    nan_actions: int

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


_SUMS = ("reward", "r_path", "r_colav", "r_psf", "r_exists", "r_collision", "abs_cte",
         "filter_time_s")
_COUNTS = ("length", "interventions", "fallbacks", "filter_calls", "nan_actions")


class VecPathEnv:
    """n path-following / collision-avoidance environments stepped together.

    Parameters
    ----------
    n_envs : int
        Number of environments.
    config : EnvConfig
        Setup, scenario family, time step, reward.
    seed : int
        Seed of every scenario draw (environment i uses child i of ``SeedSequence(seed)``).
    params : VesselParams, optional
        The vessel (default :func:`asvtwin.vessel.cybership2`).
    auto_reset : bool
        Reset ended environments inside :meth:`step` (vector convention).
    pre_cull : bool
        Decide in one compiled pass which environments can need the filter
        (:meth:`_may_need_filter`) before building their obstacles one by one (default);
        False builds them for every environment (the former path, same answers: kept
        for the benchmark's before/after comparison).
    """

    def __init__(self, n_envs: int, config: EnvConfig | None = None, *, seed: int = 0,
                 params: VesselParams | None = None, auto_reset: bool = True,
                 pre_cull: bool = True) -> None:
        self.config = cfg = config or EnvConfig()
        self.n = n = int(n_envs)
        self.params = params or cybership2()
        self.U_max = top_speed(self.params)
        self.collision_m = collision_width(self.params)
        self.auto_reset = auto_reset
        self.pre_cull = pre_cull
        self.tau_max = np.asarray(self.params.actuators.tau_max, dtype=float)
        self.u_max = np.maximum(np.abs(self.params.actuators.tau_min), self.tau_max)
        self._P = np.ascontiguousarray(self.params.packed()[None])
        self._A = np.ascontiguousarray(self.params.actuators.packed()[None])
        self._F = np.zeros((1, 2, 3))
        self._F[0, 0] = 1.0
        self._zero_d = np.zeros((n, 3))
        self.rel = ray_bearings(cfg.n_rays)
        self.obs_dim = cfg.n_rays + N_NAV
        self._rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(n)]
        self._episode_index = np.zeros(n, dtype=np.int64)
        # world state
        self.x = np.zeros((n, 6))
        self.tau = np.zeros((n, 3))
        self.t_s = np.zeros(n)
        self.steps = np.zeros(n, dtype=np.int64)
        self.path = np.zeros((n, N_PATH, 2))
        self.s_cum = np.zeros((n, N_PATH))
        self.idx = np.zeros(n, dtype=np.int64)
        self.static = np.zeros((n, N_STATIC, 3))
        self.moving0 = np.zeros((n, N_MOVING, 5))
        self.circles = np.zeros((n, N_STATIC + N_MOVING, 3))
        self.ranges = np.zeros((n, cfg.n_rays))
        self.hit = np.zeros((n, cfg.n_rays), dtype=np.int64)
        self.feat = np.zeros((n, 5))
        self._acc = {k: np.zeros(n) for k in _SUMS + _COUNTS}
        self.filters: list[Any] = []
        self._filter_live = np.zeros(n, dtype=bool)
        #: False for an ended episode that was not reset (auto_reset=False): not filtered
        self.active = np.ones(n, dtype=bool)
        if cfg.setup != "ppo":
            from asvtwin.control import SafetyFilter, plain_config

            # no coast in this world: no segment slots (each slot costs every QP iteration)
            # HPIPM's SPEED mode and no retry solve within a fallback streak: ~30 % less
            # CPU per solve, and ~40 % less per training step early in training (the
            # policy pushing at an obstacle for hundreds of steps), with the encounter
            # set's model-scale results unchanged (docs/rl.md, docs/psf.md); a retry
            # takes one SQP-RTI step; the plain filter (the defaults until 2026-12-07),
            # the one the policy was trained behind
            pc = plain_config(N=cfg.psf_horizon, backend=cfg.psf_backend,
                              n_circles=cfg.psf_solver_circles, n_segments=0,
                              hpipm_mode="SPEED", retry_in_streak=False, retry_rti_steps=1)
            self.filters = [SafetyFilter(self.params, config=pc) for _ in range(n)]
            f0 = self.filters[0]
            # the farthest the ship gets over the horizon plus the clearance it needs
            self._reach_m = (1.05 * self.U_max * f0.config.N * f0.config.dt_s + f0.d_safe_m
                            + f0.d_f_m)
            self._tk = np.arange(f0.config.N + 1) * f0.config.dt_s  # stage times [s]
            self._no_moving = np.zeros((n, 0, 3))
            # lidar_circles' own settings (circle radius, sectors, returns per sector),
            # read from its signature so the compiled selection follows them
            import inspect

            from asvtwin.control import lidar_circles

            lc = inspect.signature(lidar_circles).parameters
            self._lc_radius = float(lc["radius_m"].default)
            self._lc_sectors = int(lc["n_sectors"].default)
            self._lc_per = int(lc["per_sector"].default)
            self._sel = np.empty(self._lc_sectors * self._lc_per, dtype=np.int64)
        self.reset_all()

    # ------------------------------------------------------------------------- reset
    def reset_all(self) -> NDArray[np.float32]:
        """Reset every environment to a fresh scenario; the observations (n, obs_dim)."""
        self._reset(np.arange(self.n))
        return self._observe()

    def load_scenario(self, i: int, sc: Scenario) -> None:
        """Put environment ``i`` into scenario ``sc`` (held-out evaluation)."""
        self.path[i] = sc.path
        self.s_cum[i] = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(sc.path, axis=0).T))])
        self.static[i] = sc.static
        self.moving0[i] = sc.moving
        self.x[i] = sc.x0
        self.tau[i] = 0.0
        self.t_s[i] = 0.0
        self.steps[i] = 0
        self.idx[i] = 0
        self.active[i] = True
        for a in self._acc.values():
            a[i] = 0.0
        if self.filters:
            self.filters[i].reset()
            self._filter_live[i] = False
        self._sense(np.array([i]))

    def _reset(self, which: NDArray[np.int64]) -> None:
        for i in which.tolist():
            sc = random_scenario(self._rngs[i], self.config.family,
                                 length_m=self.config.path_length_m, U_max=self.U_max)
            self._episode_index[i] += 1
            self.load_scenario(i, sc)

    # ------------------------------------------------------------------------ sensing
    def _update_circles(self, which: NDArray[np.int64] | slice) -> None:
        self.circles[which, :N_STATIC] = self.static[which]
        m = self.moving0[which]
        t = self.t_s[which]
        t = t[:, None] if np.ndim(t) else t
        self.circles[which, N_STATIC:, 0] = m[..., 0] + m[..., 2] * t
        self.circles[which, N_STATIC:, 1] = m[..., 1] + m[..., 3] * t
        self.circles[which, N_STATIC:, 2] = m[..., 4]

    def _sense(self, which: NDArray[np.int64] | None = None) -> None:
        """LiDAR and path features of every environment (or of ``which``, after a reset)."""
        sel = slice(None) if which is None else which
        self._update_circles(sel)
        if which is None:
            cast_circles(self.x[:, :2], self.x[:, 2], self.rel, self.circles,
                         self.config.lidar_range_m, self.ranges, self.hit)
            path_features(self.x[:, :2], self.x[:, 2], self.path, self.s_cum, self.idx,
                          _WINDOW, self.config.lookahead_m, self.feat)
            return
        d = np.empty((len(which), self.config.n_rays))
        k = np.empty((len(which), self.config.n_rays), dtype=np.int64)
        cast_circles(np.ascontiguousarray(self.x[which, :2]),
                     np.ascontiguousarray(self.x[which, 2]), self.rel,
                     np.ascontiguousarray(self.circles[which]), self.config.lidar_range_m,
                     d, k)
        self.ranges[which], self.hit[which] = d, k
        f = np.empty((len(which), 5))
        idx = self.idx[which].copy()
        path_features(np.ascontiguousarray(self.x[which, :2]),
                      np.ascontiguousarray(self.x[which, 2]),
                      np.ascontiguousarray(self.path[which]),
                      np.ascontiguousarray(self.s_cum[which]), idx, _WINDOW,
                      self.config.lookahead_m, f)
        self.idx[which], self.feat[which] = idx, f

    def _observe(self) -> NDArray[np.float32]:
        obs = np.empty((self.n, self.obs_dim), dtype=np.float32)
        obs[:, : self.config.n_rays] = closeness(self.ranges, self.config.lidar_range_m)
        obs[:, self.config.n_rays:] = nav_features(self.x[:, 3:], self.feat[:, 3],
                                                   self.feat[:, 2], self.feat[:, 1],
                                                   self.U_max)
        return obs

    # ------------------------------------------------------------------------- filter
    def _filter_obstacles(self, i: int) -> list[Any]:
        """The safety filter's obstacles for environment ``i``, culled by reach.

        ``ppo_psf``: LiDAR returns within ``psf_lidar_range_m`` as 8 m circles (Vaaler et
        al. 2023). ``ppo_psf_moving``: the same for returns from static obstacles, plus
        the moving obstacles within ``psf_moving_range_m`` with their constant-velocity
        prediction over the horizon (the information the third setup adds). A circle
        whose every stage stays beyond the ship's reach (top speed × stage time +
        d_safe, + d_f at the end) cannot constrain the plan and is left out.
        """
        from asvtwin.control import CircleObstacles, MovingObstacles

        cfg = self.config
        f = self.filters[i]
        pos = self.x[i, :2]
        out: list[Any] = []
        # the rays whose returns become circles, chosen as lidar_circles chooses them
        # (returns within psf_lidar_range_m, the closest per_sector per sector; a return
        # of a moving obstacle is skipped in ppo_psf_moving), in one compiled call
        n_sel = lidar_selection(
            float(self.x[i, 2]), self.rel, self.ranges[i], self.hit[i],
            N_STATIC if cfg.setup == "ppo_psf_moving" else np.iinfo(np.int64).max,
            cfg.lidar_range_m, min(cfg.psf_lidar_range_m, self._reach_m),
            cfg.psf_lidar_range_m, self._lc_sectors, self._lc_per, self._sel)
        if n_sel:
            # the circles as lidar_circles builds them: radius R, centred R behind the
            # return along the ray (so each one's nearest point is the return)
            sel = self._sel[:n_sel]
            a = self.x[i, 2] + self.rel[sel]
            r = self.ranges[i, sel]
            R = self._lc_radius
            centres = pos + (r + R)[:, None] * np.stack([np.cos(a), np.sin(a)], axis=1)
            gap = np.hypot(*(centres - pos).T) - R
            keep = gap < self._reach_m
            if keep.any():
                out.append(CircleObstacles(centres=centres[keep],
                                           radii=np.full(int(keep.sum()), R)))
        if cfg.setup == "ppo_psf_moving":
            c = self.circles[i, N_STATIC:]
            m = self.moving0[i]
            act = c[:, 2] > 0
            gap0 = np.hypot(c[:, 0] - pos[0], c[:, 1] - pos[1]) - c[:, 2]
            near = act & (gap0 < cfg.psf_moving_range_m)
            if near.any():
                N, dt = f.config.N, f.config.dt_s
                tk = np.arange(N + 1) * dt
                traj = c[near, None, :2] + tk[None, :, None] * m[near, None, 2:4]
                gap = (np.hypot(traj[..., 0] - pos[0], traj[..., 1] - pos[1])
                       - c[near, None, 2] - 1.05 * self.U_max * tk[None, :])
                matter = gap.min(axis=1) < f.d_safe_m + f.d_f_m
                if matter.any():
                    sel = np.flatnonzero(near)[matter]
                    out.append(MovingObstacles.constant_velocity(
                        c[sel, :2], m[sel, 2:4], c[sel, 2], N=N, dt_s=dt))
        return out

    def _may_need_filter(self) -> NDArray[np.bool_]:
        """Environments where some obstacle could constrain the filter's plan, for all
        environments in one compiled pass (:func:`asvtwin.rl.kernels.filter_reach`): the
        necessary conditions of
        :meth:`_filter_obstacles` (a LiDAR return within ``psf_lidar_range_m`` and the
        ship's reach, or a moving obstacle within ``psf_moving_range_m`` whose predicted
        track comes within reach over the horizon). Only these environments go through
        the per-environment obstacle construction and the filter; for the others
        :meth:`_filter_obstacles` would return nothing, so u_0 = u_L is the same answer
        without the Python loop over them."""
        cfg = self.config
        f = self.filters[0]
        moving = cfg.setup == "ppo_psf_moving"
        need = np.empty(self.n, dtype=np.bool_)
        filter_reach(self.x[:, :2], self.ranges, self.hit,
                     N_STATIC if moving else np.iinfo(np.int64).max,
                     min(cfg.psf_lidar_range_m, self._reach_m, cfg.lidar_range_m),
                     self.circles[:, N_STATIC:] if moving else self._no_moving,
                     self.moving0[:, :, 2:4], cfg.psf_moving_range_m, self._tk,
                     1.05 * self.U_max, f.d_safe_m + f.d_f_m, self.active, need)
        return need

    def _apply_filter(self, u_L: _F8) -> _F8:
        u0 = u_L.copy()
        acc = self._acc
        need = self._may_need_filter() if self.pre_cull else self.active.copy()
        # an environment out of reach keeps no plan: its plan belongs to obstacles now gone
        stale = ~need & self._filter_live & self.active
        for i in np.flatnonzero(stale).tolist():
            self.filters[i].reset()
            self._filter_live[i] = False
        for i in np.flatnonzero(need).tolist():
            obs = self._filter_obstacles(i)
            f = self.filters[i]
            if not obs:
                if self._filter_live[i]:
                    f.reset()  # its plan belongs to obstacles now out of reach
                    self._filter_live[i] = False
                continue
            t0 = time.perf_counter()
            res = f.filter(self.x[i], u_L[i], obs, t_s=float(self.t_s[i]))
            acc["filter_time_s"][i] += time.perf_counter() - t0
            acc["filter_calls"][i] += 1
            acc["interventions"][i] += bool(res.intervened)
            acc["fallbacks"][i] += res.fallback != "none"
            self._filter_live[i] = True
            u0[i] = res.u0
        return u0

    # --------------------------------------------------------------------------- step
    def step(self, actions: NDArray[np.floating]
             ) -> tuple[NDArray[np.float32], _F8, NDArray[np.bool_], NDArray[np.bool_],
                        list[EpisodeRecord | None], NDArray[np.float32]]:
        """Advance every environment by ``dt_s``.

        Returns observations (n, obs_dim), rewards (n,), terminated (collision or goal),
        truncated (time limit), the finished episodes' records (None for the others) and
        the final observations of the finished episodes (rows of the others are the
        current ones). With ``auto_reset`` ended environments start a new episode and
        their row of the returned observations is its first.
        """
        cfg = self.config
        u_L, bad = action_to_tau(actions, self.tau_max)
        if u_L.shape[0] != self.n:
            from asvtwin.errors import StateError

            raise StateError(f"actions must have shape ({self.n}, 2), actually: "
                             f"{np.shape(actions)}")
        u0 = self._apply_filter(u_L) if self.filters else u_L
        h = cfg.dt_s / _SUBSTEPS
        x_next = np.empty_like(self.x)
        tau_next = np.empty_like(self.tau)
        cmd = np.ascontiguousarray(u0)
        for _ in range(_SUBSTEPS):
            step_batch(self.x, self.tau, cmd, self._zero_d, self._P, self._A, self._F, h,
                       x_next, tau_next)
            self.x, x_next = x_next, self.x
            self.tau, tau_next = tau_next, self.tau
        self.x[:, 2] = (self.x[:, 2] + np.pi) % (2 * np.pi) - np.pi
        self.t_s += cfg.dt_s
        self.steps += 1
        self._sense()
        collision = self.ranges.min(axis=1) < self.collision_m
        goal = (self.feat[:, 4] >= cfg.goal_progress) & ~collision
        truncated = (self.steps >= cfg.max_steps) & ~collision & ~goal
        terms = reward(cfg.reward, u=self.x[:, 3], U_max=self.U_max, psi_bar=self.feat[:, 2],
                       epsilon=self.feat[:, 1], d=self.ranges, theta=self.rel, u_L=u_L,
                       u_0=u0, u_max=self.u_max, collision=collision)
        self.last_terms = terms
        acc = self._acc
        acc["reward"] += terms.total
        acc["r_path"] += terms.r_path
        acc["r_colav"] += terms.r_colav
        acc["r_psf"] += terms.r_psf
        acc["r_exists"] += terms.r_exists
        acc["r_collision"] += terms.r_collision
        acc["abs_cte"] += np.abs(self.feat[:, 1])
        acc["length"] += 1
        acc["nan_actions"] += bad
        obs = self._observe()
        terminated = collision | goal
        done = terminated | truncated
        records: list[EpisodeRecord | None] = [None] * self.n
        final_obs = obs
        if done.any():
            final_obs = obs.copy()
            which = np.flatnonzero(done)
            for i in which.tolist():
                records[i] = self._record(i, bool(collision[i]), bool(goal[i]),
                                          bool(truncated[i]))
            if self.auto_reset:
                self._reset(which)
                obs = self._observe()
            else:
                self.active[which] = False
        return obs, terms.total, terminated, truncated, records, final_obs

    def _record(self, i: int, collision: bool, goal: bool, truncated: bool) -> EpisodeRecord:
        a = self._acc
        length = int(a["length"][i])
        return EpisodeRecord(
            env=i, seed_index=int(self._episode_index[i]), length=length,
            reward=float(a["reward"][i]), r_path=float(a["r_path"][i]),
            r_colav=float(a["r_colav"][i]), r_psf=float(a["r_psf"][i]),
            r_exists=float(a["r_exists"][i]), r_collision=float(a["r_collision"][i]),
            collision=collision,
            collision_moving=bool(collision and self.hit[i, np.argmin(self.ranges[i])]
                                  >= N_STATIC),
            goal=goal, truncated=truncated,
            mean_abs_cte_m=float(a["abs_cte"][i]) / max(length, 1),
            progress=float(self.feat[i, 4]), interventions=int(a["interventions"][i]),
            fallbacks=int(a["fallbacks"][i]), filter_calls=int(a["filter_calls"][i]),
            filter_time_s=float(a["filter_time_s"][i]), nan_actions=int(a["nan_actions"][i]),
        )

    def close(self) -> None:
        self.filters = []


def collision_width(params: VesselParams) -> float:
    """The LiDAR collision threshold [m]: the vessel's length, used as its width in the
    predecessors' collision check (a ray shorter than it is a collision)."""
    return float(params.length)

