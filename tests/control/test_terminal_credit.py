"""The terminal clearance credit: a plan that ends slow needs only d_safe + d_f √V_N from
static obstacles and the coast (V_N = ν_Nᵀ P_f ν_N), because braking from ν_N travels at
most d_f √V_N. Checked by simulating the braking backup independently, at both scales."""

from __future__ import annotations

import numpy as np
import pytest

from asvtwin.control import CircleObstacles, PsfConfig, SafetyFilter
from asvtwin.control.fallback import damp_yaw
from asvtwin.vessel import cybership2_full_scale


@pytest.fixture(scope="module")
def psf_full(default_backend):
    return SafetyFilter(cybership2_full_scale(), config=PsfConfig(backend=default_backend))


def _braking_path(psf: SafetyFilter, x0: np.ndarray, horizons: int = 4) -> np.ndarray:
    """Positions (M, 2) of the braking backup (coasting, yaw damped) from ``x0``."""
    N = psf.config.N
    pts, x = [x0[:2]], x0.copy()
    for _ in range(horizons):
        U = np.zeros((N, 3))
        X = psf.rollout(x, U)
        for _ in range(2):
            damp_yaw(U, X, psf.terminal_set.k_r, psf.u_lb[2], psf.u_ub[2], 0)
            X = psf.rollout(x, U)
        pts.append(X[1:, :2])
        x = X[-1]
    return np.vstack(pts)


def _on_level(psf: SafetyFilter, rng: np.random.Generator, V: float) -> np.ndarray:
    """A random body velocity ν with νᵀ P_f ν = V."""
    nu = rng.standard_normal(3)
    return nu * np.sqrt(V / float(nu @ psf.terminal_set.P_f @ nu))


@pytest.mark.parametrize("which", ["model", "full"])
def test_braking_from_the_terminal_set_travels_at_most_d_f_sqrt_V(which, psf, psf_full):
    f = psf if which == "model" else psf_full
    rng = np.random.default_rng(4)
    for V in (0.05, 0.3, 0.9):
        for _ in range(6):
            x0 = np.zeros(6)
            x0[3:] = _on_level(f, rng, V)
            path = _braking_path(f, x0)
            reach = float(np.max(np.hypot(*(path - x0[:2]).T)))
            assert reach <= f.d_f_m * np.sqrt(V) * 1.01 + 1e-9, (V, x0[3:], reach)


@pytest.mark.parametrize("which", ["model", "full"])
def test_slow_plan_near_a_static_obstacle_is_certified_and_safe(which, psf, psf_full):
    """Drifting slowly towards a rock closer than d_safe + d_f: the old rule (d_f at N)
    rejected every plan; the credit certifies coasting, and braking from the plan's end
    (simulated independently) keeps d_safe."""
    f = psf if which == "model" else psf_full
    f.reset()
    L = f.params.length
    x = np.zeros(6)
    x[3] = 0.02 * np.sqrt(L / 1.255)  # slow ahead [m/s], Froude scaled
    D = f.d_safe_m + 0.5 * f.d_f_m + L  # rock ahead, inside d_safe + d_f
    rock = CircleObstacles(centres=[[D, 0.0]], radii=[0.5 * L])
    res = f.filter(x, np.zeros(3), rock, t_s=0.0)
    assert res.fallback == "none" and res.passed_through, res.explanation
    assert res.obstacle_margin_m[-1] >= 0.0
    end = res.x_pred[-1]
    V_N = float(end[3:] @ f.terminal_set.P_f @ end[3:])
    assert V_N < 1.0
    # independent check of what the credit promises: braking from the plan's end
    path = np.vstack([res.x_pred[:, :2], _braking_path(f, end)])
    gap = np.hypot(path[:, 0] - D, path[:, 1]) - 0.5 * L
    assert gap.min() >= f.d_safe_m - f.certify_tol_m
    # and the stage-N requirement is exactly d_safe + d_f √V_N
    dist_N = np.hypot(end[0] - D, end[1]) - 0.5 * L
    np.testing.assert_allclose(res.obstacle_margin_m[-1],
                               dist_N - f.d_safe_m - f.d_f_m * np.sqrt(V_N), atol=1e-6)


@pytest.mark.parametrize("which", ["model", "full"])
def test_credit_does_not_admit_a_plan_into_d_safe(which, psf, psf_full):
    """The same rock a little beyond d_safe at speed: coasting would come within d_safe,
    so u_L is not passed through and the applied plan keeps d_safe."""
    f = psf if which == "model" else psf_full
    f.reset()
    L = f.params.length
    x = np.zeros(6)
    x[3] = 0.3 * np.sqrt(L / 1.255)
    D = f.d_safe_m + 0.5 * L + 0.8 * L
    rock = CircleObstacles(centres=[[D, 0.0]], radii=[0.5 * L])
    res = f.filter(x, np.zeros(3), rock, t_s=0.0)
    assert not res.passed_through
    if res.success:
        assert res.obstacle_margin_m[1:].min() >= -f.certify_tol_m


def test_a_plan_short_of_room_to_stop_is_named_so_not_a_clearance_violation():
    """A straight plan at cruise that ends 3 m clear of a rock: every stage keeps d_safe,
    but stage N lacks d_safe + the braking distance. The reason must say so (it once read
    "plan violates obstacle clearance (closest +1.74 m against d_safe)")."""
    from asvtwin.control.certification import Certifier

    N, d_safe, d_f = 10, 1.0, 5.0
    cert = Certifier(N, d_safe, d_f, 0.02, np.eye(3), 2.0)
    X = np.zeros((N + 1, 6))
    X[:, 0] = np.linspace(0.0, 5.0, N + 1)
    X[:, 3] = 0.8  # V_N = 0.64: braking needs d_f·0.8 = 4 m beyond d_safe
    centres = np.array([[[8.0 + 1.0, 0.0]]] * (N + 1))  # a rock of radius 1 m at x = 9 m
    radii = np.ones((N + 1, 1))
    cert.start_call(np.array([False]), 0, np.zeros(3))
    margins, low, term, finite = cert.margins(X, centres, radii, np.zeros((0, 4)))
    ok, why, path_low = cert.judge(margins, low, term, finite, margins[0])
    assert not ok
    assert path_low == pytest.approx(3.0 - d_safe)  # the end is 3 m from the rock's edge
    assert "no room to stop" in why and "violates obstacle clearance" not in why
    assert "2.00 m short" in why and "4.00 m braking" in why
    # a rock that the path itself enters is still a clearance violation
    centres[:, 0, 0] = 5.5
    margins, low, term, finite = cert.margins(X, centres, radii, np.zeros((0, 4)))
    ok, why, _ = cert.judge(margins, low, term, finite, margins[0])
    assert not ok and "violates obstacle clearance" in why
