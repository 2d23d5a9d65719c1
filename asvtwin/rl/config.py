"""Typed configuration of the RL environment, its reward and PPO (one place, with sources).

Every coefficient names where it comes from: the paper (Menges, Von Brandis, Rasheed:
"Digital Twin of Autonomous Surface Vessels for Safe Maritime Navigation Enabled through
Predictive Modeling and Reinforcement Learning"), its predecessors (Meyer, Robinson,
Rasheed, San 2020: "Taming an autonomous surface vehicle for path following and collision
avoidance using deep reinforcement learning", gym-auv; Vaaler et al. 2023: "Modular
control architecture for safe marine navigation: reinforcement learning and predictive
safety filters"), or our choice with the reason.

Lengths and speeds are model scale (CyberShip II, 1.255 m); other hulls see the same
numbers through Froude scaling (:mod:`asvtwin.rl.controller`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from asvtwin.errors import ConfigError

__all__ = ["SETUPS", "EnvConfig", "PpoConfig", "RewardConfig", "check_setup"]

#: The paper's three training setups: PPO alone, PPO behind the safety filter fed with the
#: LiDAR's obstacles, and PPO behind the filter that also knows the moving obstacles'
#: predicted motion.
SETUPS = ("ppo", "ppo_psf", "ppo_psf_moving")


def check_setup(name: str) -> str:
    """Return ``name`` if it is one of :data:`SETUPS`; raise :class:`ConfigError` else."""
    if name not in SETUPS:
        raise ConfigError(f"unknown setup {name!r}; expected one of {', '.join(SETUPS)}")
    return name


def _check(owner: str, checks: list[tuple[str, Any, bool, str]]) -> None:
    for name, value, ok, expected in checks:
        if not ok:
            raise ConfigError(f"{owner}.{name} must be {expected}, actually: {value!r}")


def _finite(v: float) -> bool:
    return isinstance(v, (int, float)) and math.isfinite(v)


@dataclass(frozen=True)
class RewardConfig:
    """Coefficients of the paper's reward (section "Reward Function").

    Attributes
    ----------
    lambda_ : float
        λ, the path-following / collision-avoidance trade-off, in [0, 1]. 0.5: Meyer et al.
        2020.
    gamma_e : float
        γ_ε [1/m], CTE decay of r_path. 0.05: Meyer's 5 on ε/100 m.
    gamma_r : float
        γ_r, the floor of the velocity and CTE factors of r_path, >= 0. 0.1: our choice
        (same magnitude as Meyer's distance constant): at 20 m CTE exp(−1) = 0.37 still
        pays for speed along the path.
    gamma_theta : float
        γ_θ [1/rad], angular weight of r_colav, >= 0. 10: Meyer et al. 2020.
    gamma_d : float
        γ_d [1/m], distance decay of r_colav, >= 0. 0.1: Meyer's γ_x.
    gamma_psf : float
        γ_PSF, weight of r_PSF, >= 0. 1.0: our choice; the paper gives the form only.
        The paper's equation is implemented (the predecessor's yaw term had an operator
        precedence bug that made it ~200 times too small).
    r_exists : float
        Constant per-step reward, <= 0. −0.1: our choice, below the best λ·r_path ≈ 0.6
        so that following the path at speed pays while loitering does not.
    r_collision : float
        Reward of a colliding step, <= 0. −500: our choice. Meyer et al. 2020 used
        −10000·(1 − λ) = −5000 over 1 M steps; in our first study run (150 k steps per
        setup) that penalty taught every agent to stop in place within 15 k steps
        (progress 0.00–0.02 per episode, every episode at the 2000-step limit): one
        collision outweighed 10 episodes of following the path. −500 is still worth
        about two episodes of path following (λ r_path ≤ 0.6 per step).
    """

    lambda_: float = 0.5
    gamma_e: float = 0.05
    gamma_r: float = 0.1
    gamma_theta: float = 10.0
    gamma_d: float = 0.1
    gamma_psf: float = 1.0
    r_exists: float = -0.1
    r_collision: float = -500.0

    def __post_init__(self) -> None:
        _check("RewardConfig", [
            ("lambda_", self.lambda_, _finite(self.lambda_) and 0 <= self.lambda_ <= 1,
             "in [0, 1]"),
            ("gamma_e", self.gamma_e, _finite(self.gamma_e) and self.gamma_e >= 0, ">= 0"),
            ("gamma_r", self.gamma_r, _finite(self.gamma_r) and self.gamma_r >= 0, ">= 0"),
            ("gamma_theta", self.gamma_theta,
             _finite(self.gamma_theta) and self.gamma_theta >= 0, ">= 0"),
            ("gamma_d", self.gamma_d, _finite(self.gamma_d) and self.gamma_d >= 0, ">= 0"),
            ("gamma_psf", self.gamma_psf, _finite(self.gamma_psf) and self.gamma_psf >= 0,
             ">= 0"),
            ("r_exists", self.r_exists, _finite(self.r_exists) and self.r_exists <= 0,
             "finite and <= 0"),
            ("r_collision", self.r_collision,
             _finite(self.r_collision) and self.r_collision <= 0, "finite and <= 0"),
        ])


@dataclass(frozen=True)
class EnvConfig:
    """The path-following and collision-avoidance environment (model scale).

    Attributes
    ----------
    setup : str
        One of :data:`SETUPS`.
    family : str
        Scenario family: ``"static"`` (8 static circles), ``"moving"`` (5 static and 5
        moving) or ``"mixed"`` (either, half the episodes each). Predecessor families.
    dt_s : float
        Environment step [s]; the policy acts once per step. 1 s: predecessor.
    max_steps : int
        Time limit [steps]. 2000: predecessor.
    path_length_m : float
        Nominal path length [m]. 500: predecessor.
    n_rays, lidar_range_m : int, float
        LiDAR rays over 360° and range [m]. 180 and 150 m: predecessor.
    lookahead_m : float
        Look-ahead distance of the look-ahead heading error [m]. 150: predecessor.
    goal_progress : float
        Progress (arc length / path length) that ends an episode as reached. 0.99.
    psf_lidar_range_m, psf_moving_range_m : float
        LiDAR returns within the first become 8 m filter circles; moving obstacles within
        the second enter the filter with their predicted motion. 30 and 100 m: Vaaler et
        al. 2023.
    psf_horizon : int
        Filter stages N (of 0.5 s). 50: Vaaler et al. 2023.
    psf_backend : str
        Safety-filter backend (``"auto"``: acados if installed).
    psf_solver_circles : int
        Circle slots of the filter's OCP (``PsfConfig.n_circles``): the circles nearest
        to the predicted paths go to the solver, the certification checks all of them.
        8, our choice (measured, docs/rl.md): the solve's cost grows with the slots
        (20 circles and 12 coast segments: 20.5 ms CPU per SQP-RTI step; 8 and none:
        7.7 ms) and the fallback share stayed the same. The world has no coast, so the
        OCP has no segment slots.
    """

    setup: str = "ppo"
    family: str = "moving"
    dt_s: float = 1.0
    max_steps: int = 2000
    path_length_m: float = 500.0
    n_rays: int = 180
    lidar_range_m: float = 150.0
    lookahead_m: float = 150.0
    goal_progress: float = 0.99
    psf_lidar_range_m: float = 30.0
    psf_moving_range_m: float = 100.0
    psf_horizon: int = 50
    psf_backend: str = "auto"
    psf_solver_circles: int = 8
    reward: RewardConfig = dataclasses.field(default_factory=RewardConfig)

    def __post_init__(self) -> None:
        check_setup(self.setup)
        _check("EnvConfig", [
            ("family", self.family, self.family in ("static", "moving", "mixed"),
             "one of static, moving, mixed"),
            ("dt_s", self.dt_s, _finite(self.dt_s) and 0 < self.dt_s <= 10, "in (0, 10]"),
            ("max_steps", self.max_steps,
             isinstance(self.max_steps, int) and self.max_steps >= 1, "an int >= 1"),
            ("path_length_m", self.path_length_m,
             _finite(self.path_length_m) and self.path_length_m >= 100, ">= 100"),
            ("n_rays", self.n_rays, isinstance(self.n_rays, int) and 8 <= self.n_rays <= 720,
             "an int in [8, 720]"),
            ("lidar_range_m", self.lidar_range_m,
             _finite(self.lidar_range_m) and self.lidar_range_m > 0, "> 0"),
            ("lookahead_m", self.lookahead_m,
             _finite(self.lookahead_m) and self.lookahead_m > 0, "> 0"),
            ("goal_progress", self.goal_progress,
             _finite(self.goal_progress) and 0 < self.goal_progress <= 1, "in (0, 1]"),
            ("psf_lidar_range_m", self.psf_lidar_range_m,
             _finite(self.psf_lidar_range_m) and self.psf_lidar_range_m > 0, "> 0"),
            ("psf_moving_range_m", self.psf_moving_range_m,
             _finite(self.psf_moving_range_m) and self.psf_moving_range_m > 0, "> 0"),
            ("psf_horizon", self.psf_horizon,
             isinstance(self.psf_horizon, int) and 5 <= self.psf_horizon <= 200,
             "an int in [5, 200]"),
            ("psf_solver_circles", self.psf_solver_circles,
             isinstance(self.psf_solver_circles, int) and 1 <= self.psf_solver_circles <= 60,
             "an int in [1, 60]"),
        ])

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, source: str = "<dict>") -> EnvConfig:
        try:
            d = dict(data)
            reward = RewardConfig(**d.pop("reward", {}))
            return cls(**d, reward=reward)
        except TypeError as exc:
            raise ConfigError(f"{source}: environment config does not fit EnvConfig: "
                              f"{exc}") from exc


@dataclass(frozen=True)
class PpoConfig:
    """PPO hyper-parameters (stable-baselines3).

    From the predecessor (Vaaler et al. 2023 after Meyer et al. 2020): GAE λ = 0.98,
    entropy 0.01, learning rate 2e-4, 8 environments. Our choices: γ = 0.99 (predecessor
    0.999) and 10 epochs per rollout (predecessor 4, SB3's default 10), because our study
    has a tenth of their 1 M steps: with γ = 0.999 and 4 epochs our first 100 k-step runs
    had not started to follow the path at all. For throughput on 2 cores: 256 steps per environment per rollout (2048 in
    all, predecessor 1024 each) and mini-batches of 256 (predecessor 32: eight times the
    gradient steps for the same data, which on a shared 2-core machine would cost more
    than the environment); an MLP [128, 64] (tanh) for policy and value instead of the
    predecessor's Conv1d feature extractor, so the shipped policy evaluates in numpy.
    ``log_std_init`` −1 (exploration std 0.37 instead of SB3's 1.0): our choice, measured:
    this CyberShip II model is directionally unstable (the Munk moment (M22 − M11) u v
    exceeds the 0.15 Nm yaw authority above u ≈ 0.45 m/s), so a policy that explores
    with std 1 in yaw only spins (progress 0.00–0.01 per 2000-step episode over the first
    50 k steps of our first run), while a linear heading feedback at 0.6 N follows the
    path (progress 0.99).
    ``warm_start_steps``: batched steps (16 environments) of the line-of-sight expert
    whose actions the policy's mean is cloned to before PPO starts
    (:mod:`asvtwin.rl.warm_start`; 0 disables it): our choice, see there.
    """

    n_envs: int = 8
    n_steps: int = 256
    batch_size: int = 256
    n_epochs: int = 10
    gamma: float = 0.99
    gae_lambda: float = 0.98
    ent_coef: float = 0.01
    learning_rate: float = 2e-4
    clip_range: float = 0.2
    net_arch: tuple[int, ...] = (128, 64)
    log_std_init: float = -1.0
    warm_start_steps: int = 500

    def __post_init__(self) -> None:
        _check("PpoConfig", [
            ("n_envs", self.n_envs, isinstance(self.n_envs, int) and self.n_envs >= 1,
             "an int >= 1"),
            ("n_steps", self.n_steps, isinstance(self.n_steps, int) and self.n_steps >= 2,
             "an int >= 2"),
            ("batch_size", self.batch_size,
             isinstance(self.batch_size, int) and self.batch_size >= 2, "an int >= 2"),
            ("n_epochs", self.n_epochs, isinstance(self.n_epochs, int) and self.n_epochs >= 1,
             "an int >= 1"),
            ("gamma", self.gamma, _finite(self.gamma) and 0 < self.gamma <= 1, "in (0, 1]"),
            ("gae_lambda", self.gae_lambda,
             _finite(self.gae_lambda) and 0 <= self.gae_lambda <= 1, "in [0, 1]"),
            ("ent_coef", self.ent_coef, _finite(self.ent_coef) and self.ent_coef >= 0,
             ">= 0"),
            ("learning_rate", self.learning_rate,
             _finite(self.learning_rate) and self.learning_rate > 0, "> 0"),
            ("clip_range", self.clip_range, _finite(self.clip_range) and self.clip_range > 0,
             "> 0"),
            ("log_std_init", self.log_std_init,
             _finite(self.log_std_init) and -5 <= self.log_std_init <= 2, "in [-5, 2]"),
            ("warm_start_steps", self.warm_start_steps,
             isinstance(self.warm_start_steps, int) and self.warm_start_steps >= 0,
             "an int >= 0"),
            ("net_arch", self.net_arch,
             len(self.net_arch) >= 1 and all(int(h) >= 1 for h in self.net_arch),
             "a non-empty tuple of layer widths >= 1"),
        ])
