"""Gating and global nearest neighbour."""

from __future__ import annotations

import numpy as np
import pytest

from asvtwin.tracking import FORBIDDEN, gate_threshold, gated_costs, gnn_assign


def test_gate_threshold_is_the_chi2_quantile() -> None:
    assert gate_threshold(0.99, 2) == pytest.approx(9.2103, abs=1e-4)
    assert gate_threshold(0.95, 4) == pytest.approx(9.4877, abs=1e-4)


def test_mahalanobis_cost_by_hand_and_gate() -> None:
    pos = np.array([[0.0, 0.0]])
    Pp = np.array([[[3.0, 0.0], [0.0, 1.0]]])
    z = np.array([[2.0, 0.0], [0.0, 10.0]])
    R = np.tile(np.eye(2), (2, 1, 1))
    cost, d2 = gated_costs(pos, Pp, z, R, 9.21)
    assert d2[0, 0] == pytest.approx(4.0 / 4.0)  # S = diag(4, 2)
    assert cost[0, 0] == pytest.approx(1.0 + np.log(8.0))
    assert cost[0, 1] == FORBIDDEN  # d2 = 100 / 2 = 50 > gate


def test_gnn_beats_greedy_and_leaves_out_forbidden_pairs() -> None:
    # greedy would give track 0 its best (col 0, cost 1) and leave track 1 with cost 10
    cost = np.array([[1.0, 2.0, FORBIDDEN], [1.5, 10.0, FORBIDDEN], [FORBIDDEN, FORBIDDEN, FORBIDDEN]])
    r, c = gnn_assign(cost)
    assert dict(zip(r.tolist(), c.tolist())) == {0: 1, 1: 0}
    r, c = gnn_assign(np.full((3, 2), FORBIDDEN))
    assert r.size == 0 and c.size == 0
    r, c = gnn_assign(np.empty((0, 4)))
    assert r.size == 0
