"""The tracker's fused per-tick kernels against the numpy code they replaced.

``update_and_fuse`` (per-sensor Kalman updates specialised for ``H_POSITION``/``H_FULL``,
track starts, product fusion) and ``bookkeeping`` (history, confirmation, deletion tests)
must give the numbers of the generic kernels and numpy formulas bit for bit, so that a
speed-up never moves a track (docs/tracking.md, "Speed").
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

from asvtwin.tracking import FORBIDDEN, Tracker, gnn_assign
from asvtwin.tracking.fusion import _product_kernel
from asvtwin.tracking.kalman import H_FULL, H_POSITION, _update_kernel
from asvtwin.tracking.tracker_kernels import bookkeeping, update_and_fuse


def _spd(rng: np.random.Generator, n: int, m: int, scale: float) -> np.ndarray:
    M = rng.normal(size=(n, m, m))
    return scale * (M @ M.transpose(0, 2, 1) + 0.5 * np.eye(m))


def _tracks(rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
    x = rng.normal(0.0, 300.0, (n, 4))
    x[:, 2:] = rng.normal(0.0, 3.0, (n, 2))
    d = {"x": x, "P": _spd(rng, n, 4, 4.0)}
    for s in "LA":
        d["x" + s] = x + rng.normal(0.0, 2.0, (n, 4))
        d["P" + s] = _spd(rng, n, 4, 3.0)
        d["G" + s] = rng.normal(size=(n, 4, 4))
        d["has" + s] = rng.uniform(size=n) < 0.7
        d["t" + s] = rng.uniform(0.0, 5.0, n)
        d["got" + s] = rng.uniform(size=n) < 0.6
    d["zL"] = x[:, :2] + rng.normal(0.0, 3.0, (n, 2))
    d["RL"] = _spd(rng, n, 2, 5.0)
    d["zA"] = x + rng.normal(0.0, 3.0, (n, 4))
    d["RA"] = _spd(rng, n, 4, 2.0)
    d["RA"][::3, 2, 2] = 1.0e6  # AIS without a usable velocity: the start ignores it
    return d


@pytest.mark.parametrize("seed", range(3))
def test_update_and_fuse_equals_the_generic_kernels_bit_for_bit(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n, t = 300, 7.0
    d = _tracks(rng, n)
    tr = Tracker()
    v2 = tr.config.init_velocity_std_m_s ** 2
    # reference: the generic Joseph update of the rows with a filter, _initial_state for the others,
    # then the product of the fused prediction with both measurements (the tracker's former code)
    ref = {k: v.copy() for k, v in d.items()}
    for s, z, R, H in (("L", ref["zL"], ref["RL"], H_POSITION), ("A", ref["zA"], ref["RA"], H_FULL)):
        got, has = ref["got" + s], ref["has" + s]
        upd = np.flatnonzero(got & has)
        xn, Pn, K, _, _, _ = _update_kernel(ref["x" + s][upd], ref["P" + s][upd], z[upd], R[upd], np.ascontiguousarray(H))
        ref["x" + s][upd], ref["P" + s][upd], ref["G" + s][upd] = xn, Pn, K @ H
        init = np.flatnonzero(got & ~has)
        xi, Pi = tr._initial_state(z[init], R[init])
        ref["x" + s][init], ref["P" + s][init], ref["G" + s][init] = xi, Pi, np.eye(4)
        has[init] = True
        ref["t" + s][got] = t
    ref["x"], ref["P"] = _product_kernel(ref["x"], ref["P"], ref["zL"], ref["RL"], ref["gotL"], H_POSITION,
                                         ref["zA"], ref["RA"], ref["gotA"], H_FULL)
    got = {k: v.copy() for k, v in d.items()}
    update_and_fuse(got["x"], got["P"], got["xL"], got["PL"], got["GL"], got["hasL"], got["tL"], got["gotL"], got["zL"],
                    got["RL"], got["xA"], got["PA"], got["GA"], got["hasA"], got["tA"], got["gotA"],
                    got["zA"], got["RA"], t, v2, True)
    assert (d["gotL"] & d["hasL"]).sum() > 50 and (d["gotA"] & ~d["hasA"]).sum() > 20  # all cases present
    for k, want in ref.items():
        np.testing.assert_array_equal(got[k], want, err_msg=k)
    # without product fusion the fused estimate is left to the caller
    again = {k: v.copy() for k, v in d.items()}
    update_and_fuse(again["x"], again["P"], again["xL"], again["PL"], again["GL"], again["hasL"], again["tL"],
                    again["gotL"], again["zL"], again["RL"], again["xA"], again["PA"], again["GA"],
                    again["hasA"], again["tA"], again["gotA"], again["zA"], again["RA"], t, v2, False)
    np.testing.assert_array_equal(again["x"], d["x"])
    np.testing.assert_array_equal(again["xA"], ref["xA"])


def test_bookkeeping_equals_the_numpy_rules() -> None:
    rng = np.random.default_rng(3)
    n, t, M, N = 400, 50.0, 3, 5
    x = rng.normal(0.0, 100.0, (n, 4))
    P = _spd(rng, n, 4, 1.0) * rng.uniform(0.01, 30.0, n)[:, None, None]
    x[7, 1], P[9, 2, 3] = np.nan, np.inf
    gotL, gotA = rng.uniform(size=n) < 0.5, rng.uniform(size=n) < 0.3
    hist = rng.integers(0, 1 << N, n).astype(np.int64)
    age = rng.integers(1, 9, n).astype(np.int64)
    n_ais = rng.integers(0, 2, n).astype(np.int64)
    t_last = t - rng.uniform(0.0, 80.0, n)
    axes = np.where(rng.uniform(size=(n, 1)) < 0.5, np.nan, rng.uniform(2.0, 30.0, (n, 2)))
    fit = np.where(rng.uniform(size=(n, 1)) < 0.5, np.nan, rng.uniform(2.0, 30.0, (n, 2)))
    confirmed = rng.uniform(size=n) < 0.5
    mmsi = np.where(rng.uniform(size=n) < 0.4, 200000000 + np.arange(n), -1).astype(np.int64)
    vstd, coast, coast_ais, max_std = 0.8, 10.0, 60.0, 4.0
    # numpy reference (the tracker's former step code)
    hit = gotL | gotA
    r_hist = ((hist << 1) | hit.astype(np.int64)) & ((1 << N) - 1)
    r_age, r_nais = age + 1, n_ais + gotA
    r_tl = np.where(hit, t, t_last)
    fa = ~np.isnan(fit[:, 0])
    r_axes = axes.copy()
    r_axes[fa] = np.where(np.isnan(axes[fa]), fit[fa], 0.7 * axes[fa] + 0.3 * fit[fa])
    hits = np.bitwise_count(r_hist).astype(np.int64)
    Pv = P[:, 2:, 2:]
    tr, det = Pv[:, 0, 0] + Pv[:, 1, 1], Pv[:, 0, 0] * Pv[:, 1, 1] - Pv[:, 0, 1] ** 2
    with np.errstate(invalid="ignore"):
        settled = (mmsi >= 0) | (0.5 * tr + np.sqrt(np.maximum(0.25 * tr * tr - det, 0.0)) <= vstd ** 2)
    newly = ~confirmed & (((hits >= M) & settled) | (r_nais >= 2))
    r_conf = confirmed | newly
    window = np.minimum(r_age, N)
    dead = ~r_conf & (mmsi < 0) & (window - hits > N - M)
    dead |= (t - r_tl) > np.where(mmsi >= 0, coast_ais, coast)
    pos = P[:, :2, :2]
    tr, det = pos[:, 0, 0] + pos[:, 1, 1], pos[:, 0, 0] * pos[:, 1, 1] - pos[:, 0, 1] ** 2
    with np.errstate(invalid="ignore"):
        lmax = 0.5 * tr + np.sqrt(np.maximum(0.25 * tr * tr - det, 0.0))
        dead |= np.sqrt(lmax) > max_std
    bad = ~(np.isfinite(x).all(axis=1) & np.isfinite(P).all(axis=(1, 2)))
    dead |= bad
    k_newly, k_dead, k_bad, k_lmax = bookkeeping(x, P, gotL, gotA, hist, age, n_ais, t_last, axes, fit, confirmed, mmsi,
                                                 t, (1 << N) - 1, M, N, True, vstd ** 2, coast, coast_ais, max_std)
    assert k_newly == newly.sum() > 0 and 0 < dead.sum() < n and bad.sum() == 2
    for got, want in ((hist, r_hist), (age, r_age), (n_ais, r_nais), (t_last, r_tl), (axes, r_axes),
                      (confirmed, r_conf), (k_dead, dead), (k_bad, bad), (k_lmax, lmax)):
        np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("seed", range(4))
def test_gnn_assign_equals_scipy_on_the_allowed_block(seed: int) -> None:
    rng = np.random.default_rng(seed)
    cost = rng.uniform(0.0, 20.0, (40, 30))
    cost[rng.uniform(size=cost.shape) < 0.8] = FORBIDDEN
    cost[3] = FORBIDDEN  # a track with no gated measurement
    cost[:, 5] = 2.0 * FORBIDDEN  # and a measurement with none (above FORBIDDEN counts as forbidden too)
    rows, cols = gnn_assign(cost)
    r_idx = np.flatnonzero((cost < FORBIDDEN).any(axis=1))
    c_idx = np.flatnonzero((cost < FORBIDDEN).any(axis=0))
    sub = np.minimum(cost[np.ix_(r_idx, c_idx)], FORBIDDEN)
    rr, cc = linear_sum_assignment(sub)
    ok = sub[rr, cc] < FORBIDDEN
    np.testing.assert_array_equal(rows, r_idx[rr[ok]])
    np.testing.assert_array_equal(cols, c_idx[cc[ok]])
    assert rows.dtype == cols.dtype == np.int64 and rows.size > 5
    assert 3 not in rows and 5 not in cols


def test_box_orientation_equals_the_per_angle_search() -> None:
    # the orientation search's areas in one pass per stage (_box_areas) pick the angle the
    # per-angle _box_area search picks, on ellipses, L-shapes and near-collinear flanks
    from numba import njit

    from asvtwin.tracking.hull_model import _ANGLES, _COARSE, _FINE, _box_area, _box_orientation

    @njit
    def per_angle(pts, s, n):  # type: ignore[no-untyped-def]
        best, th, cb = np.inf, 0.0, 0
        for i in range(_COARSE):
            v = _box_area(pts, s, n, _ANGLES[i, 1], _ANGLES[i, 2])
            if v < best:
                best, th, cb = v, _ANGLES[i, 0], i
        for i in range(_FINE):
            r = _COARSE + cb * _FINE + i
            v = _box_area(pts, s, n, _ANGLES[r, 1], _ANGLES[r, 2])
            if v < best:
                best, th = v, _ANGLES[r, 0]
        return th

    rng = np.random.default_rng(1)
    for k in range(600):
        n = int(rng.integers(1, 80))
        L, B = rng.uniform(5.0, 60.0), rng.uniform(2.0, 15.0)
        u = rng.uniform(0.0, 1.0, n)
        if k % 3 == 0:
            p = np.column_stack([L * np.cos(2 * np.pi * u), B * np.sin(2 * np.pi * u)])
        elif k % 3 == 1:
            side = rng.uniform(size=n) < 0.5
            p = np.where(side[:, None], np.column_stack([u * L, np.zeros(n)]), np.column_stack([np.zeros(n), u * B]))
        else:
            p = np.column_stack([u * L, rng.normal(0.0, 0.02, n)])
        a = rng.uniform(-np.pi, np.pi)
        p = p @ np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]]) + rng.uniform(-1500.0, 1500.0, 2)
        p = np.ascontiguousarray(p + rng.normal(0.0, 0.05, p.shape))
        assert _box_orientation(p, 0, n) == per_angle(p, 0, n)
