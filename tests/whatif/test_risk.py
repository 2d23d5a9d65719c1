"""The Monte Carlo risk estimate: Clopper–Pearson interval, its 1/√n shrink and its
coverage on a case whose collision probability is known in closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import beta, norm

from asvtwin.errors import ParameterError
from asvtwin.whatif import (
    Fork,
    RolloutConfig,
    draw_samples,
    parse_alternative,
    proportion_ci,
    simulate,
    summarise,
)


@pytest.mark.parametrize(("k", "n"), [(0, 10), (3, 10), (10, 10), (17, 250), (1, 1000)])
def test_clopper_pearson_against_beta_quantiles(k, n):
    lo, hi = proportion_ci(k, n)
    # Clopper and Pearson (1934): [B(α/2; k, n−k+1), B(1−α/2; k+1, n−k)]
    lo_ref = 0.0 if k == 0 else beta.ppf(0.025, k, n - k + 1)
    hi_ref = 1.0 if k == n else beta.ppf(0.975, k + 1, n - k)
    assert lo == pytest.approx(lo_ref, abs=1e-9)
    assert hi == pytest.approx(hi_ref, abs=1e-9)


def test_bad_counts_refused():
    with pytest.raises(ParameterError, match="k=5, n=3"):
        proportion_ci(5, 3)


# A target passes a stopped own ship on a straight line; its lateral offset is drawn from
# the track's N(μ, σ²): contact iff |y| < r_own + r_target, P = Φ((R−μ)/σ) − Φ((−R−μ)/σ).
MU_M, SIGMA_M = 50.0, 40.0


def _passing_fork(length_own_m: float = 88.0) -> Fork:
    return Fork(t_s=0.0, vessel="cybership2_full_scale", own_state=np.zeros(6),
                route=np.zeros((0, 2)), cruise_speed_m_s=0.0,
                track_ids=np.array([7]), track_mmsi=np.array([-1]),
                track_mean=np.array([[-300.0, MU_M, 5.0, 0.0]]),
                track_cov=np.diag([0.0, SIGMA_M**2, 0.0, 0.0])[None],
                track_length_m=np.array([60.0]), track_names=("track 7",))


def _true_p() -> float:
    R = 0.5 * 88.0 + 0.5 * 60.0
    return float(norm.cdf((R - MU_M) / SIGMA_M) - norm.cdf((-R - MU_M) / SIGMA_M))


def test_interval_covers_known_probability_and_shrinks_as_one_over_sqrt_n():
    f = _passing_fork()
    cfg = RolloutConfig(horizon_s=120.0, p_keep=1.0, p_turn=0.0, d_hat_rel_std=0.0)
    n = 1600
    samples = draw_samples(f, n, np.random.default_rng(11), cfg)
    res = simulate(f, [parse_alternative("stop+filter_off")], samples, config=cfg)
    # the simulation's own verdict equals the closed-form contact test on each draw
    y = samples.x0[:, 0, 1]
    clear = np.abs(np.abs(y) - 74.0) > 0.1  # away from the edge (time step: < 0.01 m)
    assert np.array_equal(res.collision[0][clear], (np.abs(y) < 74.0)[clear])
    p = _true_p()
    hits = res.collision[0]
    # coverage: 32 independent batches of 50 draws; each 95 % interval covers p with
    # probability ≥ 0.95, so < 26 covering has probability < 1e-3 (binomial tail)
    cover = []
    for b in range(32):
        k = int(hits[b * 50:(b + 1) * 50].sum())
        lo, hi = proportion_ci(k, 50)
        cover.append(lo <= p <= hi)
    assert sum(cover) >= 26, (sum(cover), p)
    risk = summarise([parse_alternative("stop+filter_off")], res)[0]
    assert risk.p_collision_ci[0] <= p <= risk.p_collision_ci[1]
    # 1/√n: the interval of 100 draws is about √16 = 4 times wider than that of 1600
    w100 = np.diff(proportion_ci(int(hits[:100].sum()), 100))[0]
    w1600 = np.diff(risk.p_collision_ci)[0]
    assert 3.0 < w100 / w1600 < 5.0
    assert math.isclose(risk.p_collision, hits.mean())
