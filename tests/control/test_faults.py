"""The fault catalogue of the safety filter: each returns an input, never u_L when
uncertified, and an explanation naming the cause."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from asvtwin.control import (
    CircleObstacles,
    CoastSegments,
    MovingObstacles,
    PsfConfig,
    SafetyFilter,
    available_backends,
)
from asvtwin.control.backends.base import RawSolution
from asvtwin.errors import ConfigError
from asvtwin.vessel import cybership2_full_scale
from asvtwin.vessel.actuators import with_astern

FULL_AHEAD = np.array([2.0, 0.0, 0.0])


class _Raising:
    """A backend that raises something other than RuntimeError."""

    def __init__(self, inner, exc):
        self.inner, self.name, self.spec, self.exc = inner, inner.name, inner.spec, exc

    def solve(self, *a):
        raise self.exc

    def reset(self):
        pass


class _NaN(_Raising):
    def solve(self, x0, u_L, P, xg, ug):
        N = self.spec.N
        return RawSolution(x=np.full((N + 1, 6), np.nan), u=np.full((N, 3), np.nan),
                           max_slack=0.0, success=True, status="ok", iterations=1,
                           solve_time_s=0.0)


def _run(psf, x, u_L, obs, steps, dt=None):
    """Closed loop on the planning model; returns results and the distance history."""
    dt = dt or psf.config.dt_s
    out = []
    for k in range(steps):
        r = psf.filter(x, u_L, obs, t_s=k * dt)
        out.append((x.copy(), r))
        x = psf.rollout(x, r.u_pred)[1]
    return out, x


def _filter_with(psf, backend):
    """One call at 0.5 m/s towards a rock 7 m ahead with ``backend`` swapped in."""
    inner = psf.backend
    psf.reset()
    psf.backend = backend
    try:
        return psf.filter([0, 0, 0, 0.5, 0, 0], FULL_AHEAD, CircleObstacles([[9.0, 0]], [2.0]))
    finally:
        psf.backend = inner
        psf.reset()


@pytest.mark.parametrize("exc", [ValueError("bad"), ZeroDivisionError(), KeyError("k")])
def test_any_solver_exception_ends_in_a_checked_fallback(psf, exc):
    res = _filter_with(psf, _Raising(psf.backend, exc))
    assert res.fallback != "none" and not np.allclose(res.u0, FULL_AHEAD)
    assert type(exc).__name__ in res.reason and "obstacle 0" in res.explanation


def test_nan_plan_is_named_as_such(psf):
    res = _filter_with(psf, _NaN(psf.backend, None))
    assert "not finite" in res.reason and np.all(np.isfinite(res.u0))
    assert "violates obstacle clearance" not in res.reason


def test_sudden_rock_ahead_is_not_run_over_by_the_old_tail(psf):
    """A certified plan straight ahead, then a rock detected 8 m ahead (model scale)."""
    psf.reset()
    x = np.array([0.0, 0.0, 0.0, 0.55, 0.0, 0.0])
    free = psf.filter(x, [1.0, 0, 0], None, t_s=0.0)
    assert free.fallback == "none" and not free.intervened
    rock = CircleObstacles([[9.0, 0.0]], [1.0], ids=["rock 7"])  # edge 8 m ahead
    hist, _ = _run(psf, x, np.array([1.0, 0, 0]), rock, 60)
    dmin = min(np.hypot(xx[0] - 9.0, xx[1]) - 1.0 for xx, _ in hist)
    first = hist[1][1]
    assert "rock 7" in first.explanation
    assert dmin >= psf.d_safe_m * 0.95
    for xx, r in hist:
        if r.fallback != "none":
            assert not np.allclose(r.u0, [1.0, 0, 0])
            tail = [c for c in r.candidates if c[0] == "plan_tail"]
            assert not tail or max(c[2] for c in r.candidates) >= max(c[2] for c in tail)


def test_covariance_circle_over_the_own_ship_returns_an_input(psf):
    """A tracked vessel 3 m away with σ = 2 m: its inflated circle covers the own ship."""
    psf.reset()
    N = psf.config.N
    mover = MovingObstacles.constant_velocity([[3.0, 0.0]], [[0.0, 0.1]], [0.6], N=N,
                                              dt_s=psf.config.dt_s,
                                              covariances=[np.eye(2) * 4.0], ids=[2])
    res = psf.filter([0, 0, 0, 0.2, 0, 0], FULL_AHEAD, mover, t_s=0.0)
    assert res.recovery and "track 2" in res.explanation and "recovering" in res.explanation
    assert np.all(np.isfinite(res.u0)) and not np.allclose(res.u0, FULL_AHEAD)


def test_recovery_from_inside_d_safe_turns_away(psf):
    """At rest 0.8 m from a rock (d_safe 1.255 m): the ship gets out, it is not frozen."""
    psf.reset()
    x = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    rock = CircleObstacles([[3.8, 0.0]], [3.0])  # edge 0.8 m ahead
    hist, x_end = _run(psf, x, FULL_AHEAD, rock, 120)
    d = [np.hypot(xx[0] - 3.8, xx[1]) - 3.0 for xx, _ in hist]
    assert hist[0][1].recovery
    # never much closer than where it started (the turn on the spot drifts a few cm)
    assert min(d) >= 0.8 - 0.05 * psf.d_safe_m
    assert np.hypot(x_end[0] - 3.8, x_end[1]) - 3.0 >= psf.d_safe_m  # left the violated set


def test_explanation_names_track_bearing_cpa_and_change(psf):
    psf.reset()
    x = np.array([0.0, 0.0, 0.0, 0.3, 0.0, 0.0])
    N = psf.config.N
    # a vessel on the starboard bow crossing the own ship's track 3 m ahead in 13 s (3.5 m
    # in 20 s needs no intervention since the retry's SQP-RTI steps: a plan that keeps
    # full ahead for one stage and then gives way is certified)
    mover = MovingObstacles.constant_velocity([[3.0, 4.0]], [[0.0, -0.3]], [0.6], N=N,
                                              dt_s=psf.config.dt_s, ids=[2])
    res = psf.filter(x, FULL_AHEAD, mover, t_s=0.0)
    assert res.intervened
    e = res.explanation
    assert "track 2 on the starboard bow" in e and re.search(r"CPA [\d.]+ m in \d+ s", e)
    assert "thrust" in e or "turning" in e
    assert res.active and all(a.time_s == pytest.approx(a.stage * psf.config.dt_s)
                              for a in res.active)
    # the critical circle is the vessel's *predicted* position where it binds
    if res.critical:
        c = np.array(res.critical[0][:2])
        assert np.linalg.norm(c - [3.5, 6.0]) > 0.5


def test_no_intervention_has_no_active_constraints_and_says_so(psf):
    psf.reset()
    res = psf.filter([0, 0, 0, 0.3, 0, 0], [1.0, 0, 0.05],
                     [CircleObstacles([[60.0, 0.0]], [2.0]),
                      CoastSegments([[0.0, 40.0, 80.0, 40.0]])], t_s=0.0)
    assert not res.intervened and res.active == ()
    assert res.explanation.startswith("no intervention; nearest:")


def test_u_L_out_of_range_is_clipped_with_a_note_and_intervened_uses_the_range(psf):
    psf.reset()
    res = psf.filter([0, 0, 0, 0.3, 0, 0], [3.0, 0, 0.0], None, t_s=0.0)
    assert "clipped" in res.explanation and res.u0[0] == pytest.approx(2.0)
    assert not res.intervened  # clipping is not an intervention; δu = 1 N is reported
    assert res.delta_u[0] == pytest.approx(1.0)
    # 1 % of the yaw range (0.3 Nm) is 0.003 Nm: a 0.002 Nm change is not an intervention
    from dataclasses import replace
    assert not replace(res, u0=res.u0 + [0, 0, 0.002], u_L=res.u_L).intervened
    assert replace(res, u0=res.u0 + [0, 0, 0.004]).intervened


def test_full_scale_open_water_passes_and_short_horizons_are_refused():
    p = cybership2_full_scale()
    psf = SafetyFilter(p, config=PsfConfig(backend="casadi-ipopt"))
    assert psf.config.dt_s == pytest.approx(0.5 * math.sqrt(70.0))
    x = np.array([0.0, 0.0, 0.0, 4.0, 0.0, 0.0])
    u_cruise = np.array([0.8 * p.actuators.tau_max[0], 0.0, 0.0])
    for k in range(5):
        res = psf.filter(x, u_cruise, None, t_s=k * psf.config.dt_s)
        assert res.fallback == "none" and not res.intervened, res.explanation
        x = psf.rollout(x, res.u_pred)[1]
    with pytest.raises(ConfigError, match="shorter than the braking time"):
        SafetyFilter(p, config=PsfConfig(dt_s=0.5, backend="casadi-ipopt"))


def _stopped_ship_approached(params, p0, v):
    """Closest approach [m] of a stopped ship to a vessel (radius 0.5 L) starting at p0 [L]
    with velocity v [m/s], over 40 filter steps with u_L = no thrust, and whether the
    filter ever went astern."""
    psf = SafetyFilter(params, config=PsfConfig(backend=available_backends()[0]))
    N, dt, L = psf.config.N, psf.config.dt_s, params.length
    x, v = np.zeros(6), np.asarray(v, float)
    p0 = np.asarray(p0, float) * L
    closest, astern = np.inf, False
    for k in range(40):
        t = k * dt
        mover = MovingObstacles.constant_velocity([p0 + t * v], [v], [0.5 * L], N=N,
                                                  dt_s=dt, ids=[5])
        r = psf.filter(x, np.zeros(3), mover, t_s=t)
        astern |= bool(r.u0[0] < 0)
        closest = min(closest, float(np.linalg.norm(p0 + t * v - x[:2])) - 0.5 * L)
        x = psf.rollout(x, r.u_pred)[1]
    return closest, astern, psf.d_safe_m


def test_astern_gives_a_stopped_ship_an_escape():
    """Stopped, a vessel bearing down on the bow at 4 m/s: the astern-capable hull backs off
    and keeps d_safe; the forward-only hull must go ahead, towards it, to turn, and cannot
    (measured: 88.9 m against 19.0 m, d_safe 87.85 m). A vessel crossing 0.5 L ahead is
    passed at d_safe by both; the astern hull uses its astern thrust there too."""
    fwd = cybership2_full_scale()
    ast = with_astern(fwd)
    assert ast.actuators.tau_min[0] == pytest.approx(-0.6 * fwd.actuators.tau_max[0])
    head_on = ([4.0 * 120.0 / fwd.length, 0.0], [-4.0, 0.0])
    d_ast, went_astern, d_safe = _stopped_ship_approached(ast, *head_on)
    d_fwd, fwd_astern, _ = _stopped_ship_approached(fwd, *head_on)
    assert went_astern and not fwd_astern
    assert d_ast >= 0.99 * d_safe
    assert d_fwd < 0.8 * d_safe
    crossing = ([0.5, 4.0 * 120.0 / fwd.length], [0.0, -4.0])
    d_ast, went_astern, _ = _stopped_ship_approached(ast, *crossing)
    d_fwd, _, _ = _stopped_ship_approached(fwd, *crossing)
    assert went_astern
    assert min(d_ast, d_fwd) >= 0.99 * d_safe


def test_auto_backend_falls_back_to_ipopt_when_acados_cannot_build(monkeypatch):
    """No gcc/make: acados cannot build; 'auto' warns once, says why, and uses IPOPT."""
    import asvtwin.control.psf as psf_mod
    from asvtwin.errors import SolverError

    real = psf_mod.make_backend

    def fake(name, spec, **opts):
        if name == "acados":
            raise SolverError("building the acados solver failed: make: not found")
        return real(name, spec, **opts)

    monkeypatch.setattr(psf_mod, "make_backend", fake)
    monkeypatch.setattr(psf_mod, "available_backends", lambda: ["acados", "casadi-ipopt"])
    from asvtwin.vessel import cybership2

    with pytest.warns(RuntimeWarning, match="make: not found.*casadi-ipopt.*gcc and make"):
        f = SafetyFilter(cybership2(), config=PsfConfig(N=40))
    assert f.backend.name == "casadi-ipopt"
    with pytest.raises(SolverError):  # an explicit choice is not silently replaced
        SafetyFilter(cybership2(), config=PsfConfig(N=40, backend="acados"))


def _call_with(psf, backend, x, obs, t_s):
    """One full-ahead call with ``backend`` swapped in (the filter's state kept)."""
    inner = psf.backend
    psf.backend = backend
    try:
        return psf.filter(x, [1.0, 0, 0], obs, t_s=t_s)
    finally:
        psf.backend = inner


def _rock_then_brisk_tail(psf):
    """A rock 8 m ahead makes the first call turn hard; the next call's plan that keeps
    u_L (full ahead, then that turn's remainder) is safe but turns faster than ν_max,r."""
    psf.reset()
    x = np.array([0.0, 0.0, 0.0, 0.55, 0.0, 0.0])
    psf.filter(x, [1.0, 0, 0], None, t_s=0.0)
    rock = CircleObstacles([[9.0, 0.0]], [1.0], ids=["rock 7"])
    first = psf.filter(x, [1.0, 0, 0], rock, t_s=0.5)
    assert first.intervened and np.abs(first.x_pred[2:, 5]).max() > 1.5 * psf.nu_max[2]
    return psf.rollout(x, first.u_pred)[1], rock


def _comfort(params):
    # three SQP steps per retry: the rock's first call then falls back to a hard turn,
    # the brisk tail these tests need (converged retries find a certified plan keeping u_L)
    return SafetyFilter(params, config=PsfConfig(backend=available_backends()[0],
                                                 comfort_pass_through=True,
                                                 retry_rti_steps=3))


def test_a_brisk_plan_keeping_u_l_sends_the_filter_to_the_solver_first(params):
    """comfort_pass_through: u_L whose only certified continuation turns faster than the
    comfort bound is kept only after the solver found no gentler certified plan."""
    psf = _comfort(params)
    x, rock = _rock_then_brisk_tail(psf)
    calls = []

    class _Counting(_Raising):
        def solve(self, *a):
            calls.append(1)
            return self.inner.solve(*a)

    res = _call_with(psf, _Counting(psf.backend, None), x, rock, 1.0)
    assert calls  # the solver was asked although a certified plan kept u_L
    if res.passed_through:  # no gentler plan: u_L kept, and the explanation says why
        assert "comfort bound" in res.explanation and res.fallback == "none"
    else:  # a gentler certified plan was found and applied
        assert res.fallback == "none" and res.success
        assert np.abs(res.x_pred[2:, 5]).max() <= max(
            1.05 * psf.nu_max[2], abs(res.x_pred[1, 5]))


def test_a_failing_solver_keeps_the_brisk_but_certified_u_l(params):
    """The solver raises: u_L is still certified by its brisk plan, so it is applied (no
    fallback manoeuvre replaces a certified input)."""
    psf = _comfort(params)
    x, rock = _rock_then_brisk_tail(psf)
    res = _call_with(psf, _Raising(psf.backend, ValueError("solver down")), x, rock, 1.0)
    assert res.passed_through and res.fallback == "none"
    np.testing.assert_allclose(res.u0, [1.0, 0, 0])
    assert "no gentler certified plan" in res.explanation


def test_without_comfort_pass_through_the_brisk_plan_keeps_u_l_without_a_solve(params):
    """comfort_pass_through off: the brisk plan keeps u_L at once."""
    psf = SafetyFilter(params, config=PsfConfig(backend=available_backends()[0],
                                                comfort_pass_through=False,
                                                retry_rti_steps=3))  # (see _comfort)
    x, rock = _rock_then_brisk_tail(psf)
    res = _call_with(psf, _Raising(psf.backend, AssertionError("no solve expected")), x, rock,
                     1.0)
    assert res.passed_through and "comfort" not in res.explanation


class _Uncertifiable(_Raising):
    """A backend whose every plan is full ahead into the rock (solver "ok", never
    certified); counts its solves."""

    def __init__(self, inner, psf):
        super().__init__(inner, None)
        self.psf, self.solves = psf, 0

    def solve(self, x0, u_L, P, xg, ug):
        self.solves += 1
        U = np.tile(FULL_AHEAD, (self.spec.N, 1))
        return RawSolution(x=self.psf.rollout(x0, U), u=U, max_slack=0.0, success=True,
                           status="ok", iterations=1, solve_time_s=0.0)


@pytest.mark.parametrize("retry_in_streak", [True, False])
def test_a_fallback_streak_skips_the_retry_only_when_asked_and_still_falls_back(
        params, default_backend, retry_in_streak):
    """retry_in_streak=False: a call whose predecessor (less than a horizon earlier)
    fell back makes one solve, not two, and still ends on a checked fallback candidate,
    never on the uncertified u_L; the first fallback of a streak, and one after a gap
    longer than the horizon, still retry."""
    psf = SafetyFilter(params, config=PsfConfig(backend=default_backend,
                                                retry_in_streak=retry_in_streak))
    rock = CircleObstacles([[7.0, 0.0]], [2.0])  # no plan that keeps u_L certifies
    x = np.array([0.0, 0.0, 0.0, 0.5, 0.0, 0.0])
    fake = _Uncertifiable(psf.backend, psf)
    psf.reset()
    solves, results = [], []
    horizon = psf.config.N * psf.config.dt_s
    for t in (0.0, 0.5, 1.0, 1.0 + 1.5 * horizon):
        before = fake.solves
        res = _call_with(psf, fake, x, rock, t)
        solves.append(fake.solves - before)
        results.append(res)
    for res in results:
        assert res.fallback != "none" and not res.success
        assert "plan violates obstacle clearance" in res.reason
        assert not np.allclose(res.u0, [1.0, 0, 0])  # never the uncertified u_L
        # the applied input starts the plan of a scored (checked) candidate
        assert res.candidates and res.fallback in {c[0] for c in res.candidates}
        np.testing.assert_array_equal(res.u0, res.u_pred[0])
    # first call: cold start (cold_start_solves) plus one retry; later: 1 + 1 retry
    assert solves[0] == psf.config.cold_start_solves + 1
    assert solves[1:3] == ([2, 2] if retry_in_streak else [1, 1])
    assert solves[3] == 2  # more than a horizon after the last fallback: no streak


def test_hpipm_mode_is_checked():
    with pytest.raises(ConfigError, match="hpipm_mode"):
        PsfConfig(hpipm_mode="FAST")


@pytest.mark.parametrize("bad", [0.0, -1e-4, float("nan"), float("inf")])
def test_qp_tol_is_checked(bad):
    with pytest.raises(ConfigError, match="qp_tol"):
        PsfConfig(qp_tol=bad)


@pytest.mark.skipif("acados" not in available_backends(), reason="acados not installed")
def test_a_qp_the_twin_recorded_converges_at_either_tolerance():
    """A full-scale QP recorded in the twin's benchmark scene (50 extra vessels, seed 7;
    tests/control/data/twin_hard_qp.npz: the state, u_L, the 51 x 133 stage parameters
    and the warm start of one solve). While the velocity bounds' slacks were priced in
    the 88 m hull's own units (a yaw-rate slack 70 times cheaper per unit of the bound
    than a surge slack), HPIPM stopped on it at its iteration limit (100) at its own
    BALANCE tolerance and converged only at ``qp_tol=1e-4`` (the twin's setting). With
    the slacks in model-scale units it converges at both (measured 38 and 37
    iterations from a reset solver), and the plan starts inside the actuator range. The
    solver with a tolerance is built apart from the default one and carries it. The
    recording predates the thrusters' lag in the plan (6 solver states): it is replayed
    on the OCP it was recorded from (``model_actuator_lag=False``)."""
    params = cybership2_full_scale()
    six = {"backend": "acados", "model_actuator_lag": False}
    default = SafetyFilter(params, config=PsfConfig(**six)).backend
    loose = SafetyFilter(params, config=PsfConfig(**six, qp_tol=1e-4)).backend
    assert loose is not default
    opts = loose._solver.acados_ocp.solver_options  # type: ignore[attr-defined]
    assert opts.qp_solver_tol_stat == opts.qp_solver_tol_comp == 1e-4
    case = np.load(Path(__file__).parent / "data" / "twin_hard_qp.npz")
    assert case["P"].shape == (default.spec.N + 1, default.spec.n_p), (
        "the recorded QP no longer fits the OCP's parameters: re-record it")
    args = (case["x0"], case["u_L"], case["P"], case["x_guess"], case["u_guess"])
    lo, hi = np.asarray(default.spec.u_lb), np.asarray(default.spec.u_ub)
    for backend in (default, loose):
        backend.reset()
        done = backend.solve(*args)
        assert done.success, done.status
        iters = int(np.asarray(backend._solver.get_stats("qp_iter")).ravel()[-1])
        assert iters < 60
        assert np.all(done.u >= lo - 1e-6) and np.all(done.u <= hi + 1e-6)


@pytest.mark.skipif("acados" not in available_backends(), reason="acados not installed")
def test_hpipm_speed_mode_is_its_own_solver_and_keeps_the_ship_clear(params, psf):
    """HPIPM's SPEED mode (the RL world's) is a separately built solver; its plans are
    certified like any other: a full-ahead learner towards a rock stays ≥ d_safe − tol."""
    fast = SafetyFilter(params, config=PsfConfig(backend="acados", hpipm_mode="SPEED"))
    assert fast.backend is not psf.backend
    rock = CircleObstacles([[12.0, 0.3]], [1.5])
    out, _ = _run(fast, np.array([0.0, 0, 0, 0.5, 0, 0]), FULL_AHEAD, rock, 40)
    gaps = [math.hypot(x[0] - 12.0, x[1] - 0.3) - 1.5 for x, _ in out]
    assert min(gaps) >= fast.d_safe_m - fast.certify_tol_m
    assert any(r.intervened for _, r in out) and sum(r.success for _, r in out) > 30
