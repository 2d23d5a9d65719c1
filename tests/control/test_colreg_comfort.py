"""COLREG side of the fallbacks, the comfort yaw-rate bound of the filter's own turns,
stage N's requirement given to the solver, and open water after an encounter."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math

import casadi as ca
import numpy as np
import pytest

from asvtwin.control import MovingObstacles, PsfConfig, SafetyFilter, available_backends
from asvtwin.control.backends import ocp
from asvtwin.control.certification import Certifier
from asvtwin.control.encounters import OPEN_WATER_L, encounter_cases, run_encounter
from asvtwin.control.fallback import Fallback, Scored, plan_side, select_candidate
from asvtwin.errors import ConfigError
from asvtwin.vessel import cybership2, cybership2_full_scale


def _arc(psi0: float, r: float, n: int = 30, dt: float = 0.5, u: float = 0.3) -> np.ndarray:
    """States of a constant-rate turn (exact kinematics, independent of the model)."""
    X = np.zeros((n + 1, 6))
    for k in range(1, n + 1):
        psi = psi0 + r * k * dt
        X[k, 2] = psi
        X[k, 0] = X[k - 1, 0] + u * dt * math.cos(psi)
        X[k, 1] = X[k - 1, 1] + u * dt * math.sin(psi)
    X[0, 2] = psi0
    X[:, 3], X[:, 5] = u, r
    return X


@pytest.mark.parametrize("psi0", [0.0, 1.2, -2.5])
def test_plan_side_is_measured_across_the_initial_heading(psi0):
    assert plan_side(_arc(psi0, +0.1), 1.255) == 1  # r > 0 turns to starboard (NED)
    assert plan_side(_arc(psi0, -0.1), 1.255) == -1
    assert plan_side(_arc(psi0, 0.0), 1.255) == 0
    assert plan_side(_arc(psi0, +0.001), 1.255) == 0  # within a quarter length


class _Failing:
    """A backend that always fails: every call ends in the scored fallback."""

    def __init__(self, inner):
        self.name, self.spec = inner.name, inner.spec

    def solve(self, *a):
        raise RuntimeError("QP failed (test)")

    def reset(self):
        pass


class _Spy:
    """A backend that records the stage parameters it is given."""

    def __init__(self, inner):
        self.inner, self.name, self.spec, self.P = inner, inner.name, inner.spec, []

    def solve(self, x0, u_L, P, xg, ug):
        self.P.append((P.copy(), xg.copy()))
        return self.inner.solve(x0, u_L, P, xg, ug)

    def reset(self):
        self.inner.reset()


def _head_on(psf, offset_east):
    """A vessel 9 ship lengths ahead on the reciprocal course, ``offset_east`` [L] to
    starboard, at the own speed (0.3 m/s at model scale)."""
    L, sq = psf.params.length, math.sqrt(psf.params.length / 1.255)
    v = 0.3 * sq
    x = np.array([0.0, 0.0, 0.0, v, 0.0, 0.0])
    tgt = MovingObstacles.constant_velocity([[9.0 * L, offset_east * L]], [[-v, 0.0]],
                                            [0.5 * L], N=psf.config.N,
                                            dt_s=psf.config.dt_s, ids=[7])
    return x, tgt


@pytest.mark.parametrize("hull", [cybership2, cybership2_full_scale])
def test_head_on_fallback_goes_to_starboard_when_port_is_only_slightly_better(hull):
    p = hull()
    psf = SafetyFilter(p, config=PsfConfig(backend=available_backends()[0]))
    x, tgt = _head_on(psf, offset_east=0.3)  # slightly to starboard: port looks roomier
    psf.backend = _Failing(psf.backend)
    res = psf.filter(x, [0.3 * float(psf.u_ub[0]), 0.0, 0.0], tgt, t_s=0.0)
    assert res.fallback != "none"
    assert plan_side(res.x_pred, p.length) == 1, res.explanation
    if any(c[3] for c in res.candidates):  # a certified starboard plan was available
        assert "not certified" not in res.explanation, res.explanation
    else:  # a comparable closest approach: within 10 % of d_safe of the best candidate
        best = max(c[2] for c in res.candidates)
        chosen = min(res.obstacle_margin_m[1:-1]) + psf.d_safe_m
        assert chosen >= best - 0.1 * psf.d_safe_m - 1e-9, (chosen, best)
    # without the preference the roomier port side wins (the test can tell them apart)
    ports = [c for c in res.candidates if c[0] == "turn_port"]
    assert ports and max(c[2] for c in ports) > min(res.obstacle_margin_m[1:-1]) + psf.d_safe_m


def _row(kind, side, closest, certified=False, dist=1.0, r=0.1):
    """A scored candidate whose plan turns at ``side`` · r [rad/s] (exact arc)."""
    X = _arc(0.0, side * r)
    return Scored(kind, f"{kind} test", X, np.zeros((30, 3)), np.zeros((31, 1)), 0.5,
                  certified, "", closest, dist)


def _select(rows, prefer, m0=None):
    cert = Certifier(30, 1.255, 7.53, 0.0251, np.eye(3), 2.0)
    return select_candidate(rows, np.zeros(6), np.zeros(1) if m0 is None else m0, cert,
                            length_m=1.255, r_comfort=0.1575, prefer_starboard=prefer)[0]


def test_selection_prefers_starboard_only_when_the_margin_is_comparable():
    port, stb = Fallback.TURN_PORT, Fallback.TURN_STARBOARD
    near = [_row(port, -1, 1.00), _row(stb, +1, 0.90), _row(Fallback.BRAKING, 0, 0.2, r=0)]
    assert _select(near, prefer=False).kind is port  # the roomier side
    pick = _select(near, prefer=True)
    assert pick.kind is stb and "starboard preferred (COLREG)" in pick.detail
    assert "0.10 m further off" in pick.detail
    far = [_row(port, -1, 1.00), _row(stb, +1, 0.80)]  # 0.2 m > 10 % of d_safe
    assert _select(far, prefer=True).kind is port
    edge = [_row(port, -1, 0.05), _row(stb, +1, -0.05)]  # never into d_safe for COLREG
    assert _select(edge, prefer=True).kind is port


def test_selection_among_certified_candidates_colreg_then_comfort_then_least_change():
    port, stb = Fallback.TURN_PORT, Fallback.TURN_STARBOARD
    rows = [_row(port, -1, 0.5, True, dist=0.1), _row(stb, +1, 0.5, True, dist=0.4)]
    assert _select(rows, prefer=False).kind is port  # least change
    assert _select(rows, prefer=True).kind is stb
    # same side: a plan within the yaw-rate bound wins over a nearer brisk one
    brisk = _row(stb, +1, 0.5, True, dist=0.1, r=0.3)
    calm = _row(stb, +1, 0.5, True, dist=0.3, r=0.1)
    assert _select([brisk, calm], prefer=True) is calm
    assert _select([brisk, calm], prefer=True).X[1:, 5].max() <= 0.1575
    # none within the bound: the one that exceeds it least, though further from u_L
    brisker = _row(stb, +1, 0.5, True, dist=0.05, r=0.39)
    assert _select([brisker, brisk], prefer=True) is brisk


@pytest.mark.parametrize("hull", [cybership2, cybership2_full_scale])
@pytest.mark.parametrize("d_planar_share", [0.0, 0.05])
def test_stage_n_asks_the_solver_what_certification_asks(hull, d_planar_share):
    """The OCP's stage-N constraints, evaluated on end states from stopped to fast,
    against the certification's stage-N margins: equal (less the planning tolerance) at
    the warm start's end speed, never less conservative elsewhere (the tangent of
    √V_N), and a moving vessel asks d_safe only. The solver thus trades ending slower
    against ending farther from static obstacles as its plan is judged. With and
    without a disturbance that halves the braking credit."""
    from asvtwin.control import CircleObstacles, CoastSegments
    from asvtwin.control.backends.ocp import margin_scale, terminal_constraints
    from asvtwin.control.obstacles import stage_circles
    from asvtwin.control.slots import MIN_ROOT_V

    p = hull()
    psf = SafetyFilter(p, config=PsfConfig(backend="casadi-ipopt", max_iter=5))
    L = p.length
    spy = _Spy(psf.backend)
    psf.backend = spy
    x, tgt = _head_on(psf, offset_east=0.0)
    rock = CircleObstacles([[6.0 * L, -2.0 * L]], [0.5 * L])
    quay = CoastSegments([[4.0 * L, 3.0 * L, 12.0 * L, 3.0 * L]])
    d_hat = np.array([d_planar_share * float(psf.u_ub[0] - psf.u_lb[0]), 0.0, 0.0])
    obstacles = [rock, tgt, quay]
    psf.filter(x, [float(psf.u_ub[0]), 0.0, 0.0], obstacles, d_hat, t_s=0.0)
    assert spy.P
    spec = spy.spec
    h_N = terminal_constraints(spec)
    cert = psf._cert
    assert cert.credit_factor == pytest.approx(1.0 - d_planar_share / 0.1)
    centres, radii, segs = stage_circles(obstacles, psf.config.N)
    radii[-1, 1] -= psf.d_f_m  # as the filter gives a moving circle at stage N
    k0 = spec.credit_index
    kappa = cert.credit_factor * psf.d_f_m
    P_f = psf.terminal_set.P_f
    rng = np.random.default_rng(3)
    for P, xg in spy.P:
        assert P[0, 3] == pytest.approx(psf.d_safe_m + psf.certify_tol_m)
        assert P[-1, k0 + 1: k0 + 3].tolist() == [1.0, 0.0]  # the rock, the vessel
        nu_g = xg[-1, 3:]
        s = min(max(math.sqrt(float(nu_g @ P_f @ nu_g)), MIN_ROOT_V), 1.0)
        for k in range(21):
            pos = np.array([rng.uniform(0, 10 * L), rng.uniform(-4 * L, 4 * L)])
            nu = rng.uniform(-1, 1, 3) * psf.nu_max * rng.choice([0.02, 0.3, 1.0])
            if k == 0:  # at the tangent point: exact
                nu = nu / math.sqrt(float(nu @ P_f @ nu)) * s
            X = np.tile(np.concatenate([pos, [0.0], nu]), (psf.config.N + 1, 1))
            margins, _, term, _ = cert.margins(X, centres, radii, segs)
            h = np.asarray(h_N(X[-1], P[-1])).ravel()
            V = 1.0 - term
            more = kappa * (s / 2 + V / (2 * s) - math.sqrt(min(V, 1.0)))
            assert more >= -1e-9
            if k == 0:
                assert more == pytest.approx(0.0, abs=1e-6 * L)
            # slots (margins in model-scale metres): the rock, the vessel, dummies; the
            # quay, dummies; the ellipsoid
            got = margin_scale(spec) * np.array([h[0], h[1], h[spec.n_circles]])
            want = margins[-1] - psf.certify_tol_m - np.array([more, 0.0, more])
            assert got == pytest.approx(want, abs=1e-4), (pos, nu)  # |·| smoothing
            assert h[-1] == pytest.approx(term)


@pytest.mark.parametrize("hull", [cybership2, cybership2_full_scale])
def test_open_water_after_an_encounter_is_left_to_the_learner(hull):
    p = hull()
    psf = SafetyFilter(p, config=PsfConfig(backend=available_backends()[0]))
    case = next(c for c in encounter_cases(include=("open_water",)))
    r = run_encounter(case, p, psf)
    assert r.collisions == 0 and r.goal_reached, r.to_dict()
    assert r.open_water_calls >= 400, r.open_water_calls  # most of the 130 m route
    # nothing within OPEN_WATER_L ship lengths: the filter does not touch u_L
    assert r.open_water_interventions == 0, (r.open_water_interventions, OPEN_WATER_L)
    assert r.starboard is True  # the head-on part: rule 14


def test_an_overtaking_in_sight_leaves_the_side_free(psf):
    """Rule 13 leaves the side of an overtaking free: a head-on vessel asks for
    starboard (warm start and ranking); with a slower vessel ahead on the same course
    (the own ship overtaking) the warm start stays but the ranking does not force it."""
    N, dt = psf.config.N, psf.config.dt_s
    x = np.array([0.0, 0.0, 0.0, 0.3, 0.0, 0.0])
    head_on = MovingObstacles.constant_velocity([[12.0, 0.2]], [[-0.3, 0.0]], [0.6], N=N,
                                                dt_s=dt)
    both = MovingObstacles.constant_velocity([[12.0, 0.2], [5.0, 0.0]],
                                             [[-0.3, 0.0], [0.1, 0.0]], [0.6, 0.6], N=N,
                                             dt_s=dt)
    from asvtwin.control.obstacles import obstacle_labels, stage_circles

    for obs, expected in ((head_on, (True, True)), (both, (True, False))):
        centres, _, _ = stage_circles(obs, N)
        _, moving = obstacle_labels(obs)
        assert psf._starboard_expected(x, centres, moving) == expected


@pytest.mark.parametrize("hull", [cybership2, cybership2_full_scale])
def test_velocity_slacks_count_model_scale_units(hull):
    """Eq. (c)'s slacks are priced per model-scale unit: the velocity bounds of either
    hull, multiplied by the slack scale, are the model's bounds, so the same relative
    excess (a yaw rate 20 % above the comfort bound) costs the same at every size. At
    model scale the scale is one (nothing changes there)."""
    from asvtwin.control.backends.ocp import margin_scale, velocity_slack_scale

    model = SafetyFilter(cybership2(), config=PsfConfig(backend="casadi-ipopt", max_iter=5))
    psf = SafetyFilter(hull(), config=PsfConfig(backend="casadi-ipopt", max_iter=5))
    spec = psf.backend.spec
    f = velocity_slack_scale(spec)
    np.testing.assert_allclose(f * np.asarray(spec.nu_max), model.nu_max, rtol=1e-12)
    lam = margin_scale(spec)
    assert f[2] == pytest.approx(math.sqrt(lam)) and f[0] == pytest.approx(1 / math.sqrt(lam))
    if lam == 1.0:
        np.testing.assert_array_equal(f, np.ones(3))
    excess = 0.2 * psf.nu_max[2] * f[2]  # what the L1 penalty sees of a 20 % excess
    assert excess == pytest.approx(0.2 * model.nu_max[2])


def test_the_yaw_rate_slack_weight_prices_only_the_yaw_rate():
    """``PsfConfig.yaw_slack_weight`` multiplies the yaw-rate slack's price alone; at its
    default the spec's cache key is the one it had before the option existed (the
    generated solvers already built stay valid), and another weight is another key."""
    p = cybership2_full_scale()
    # (lag-free plans, clearance priced 1: the formulation's key before those options)
    older = {"model_actuator_lag": False, "clearance_slack_weight": 1.0}
    one = SafetyFilter(p, config=PsfConfig(backend="casadi-ipopt", max_iter=5,
                                           **older)).backend.spec
    ten = SafetyFilter(p, config=PsfConfig(backend="casadi-ipopt", max_iter=5, **older,
                                           yaw_slack_weight=10.0)).backend.spec
    f1, f10 = ocp.velocity_slack_scale(one), ocp.velocity_slack_scale(ten)
    np.testing.assert_allclose(f10, f1 * np.array([1.0, 1.0, 10.0]), rtol=1e-12)
    assert one.key() != ten.key()
    d = dataclasses.asdict(one)
    for later in ("yaw_slack_weight", "actuator_tc", "clearance_slack_weight"):
        d.pop(later)  # (fields added since, at their defaults: the older key)
    blob = json.dumps(d, sort_keys=True, default=float).encode()
    blob += ocp.FORMULATION.encode() + ca.CasadiMeta.version().encode()
    assert one.key() == hashlib.sha256(blob).hexdigest()[:16]
    for bad in (0.0, -1.0, math.inf, math.nan):
        with pytest.raises(ConfigError, match="yaw_slack_weight"):
            PsfConfig(yaw_slack_weight=bad)
