"""Choosing among uncertified fallback candidates: the coast before a vessel's predicted
clearance circle, and the same manoeuvre from one call to the next.

The twin's hour-long benchmark run (50 extra vessels within 3 km, half of them turning at
waypoints) left the full-scale filter without a certified plan for minutes: each tracked
vessel's 95 % circle had grown to ~600 m by the end of the 209 s horizon. Choosing the
candidate with the largest closest approach to *anything* then traded metres of shore
clearance for metres of distance to those circles, and re-deciding every call alternated
port turn, starboard turn and coasting, which together held the course towards the shore:
three groundings."""

from __future__ import annotations

import numpy as np

from asvtwin.control.certification import Certifier
from asvtwin.control.fallback import Fallback, Scored, select_candidate, static_low

D_SAFE = 1.255


def _cert() -> Certifier:
    cert = Certifier(30, D_SAFE, 7.53, 0.0251, np.eye(3), 2.0)
    # one moving obstacle (column 0) and one coast segment (column 1)
    cert.start_call(np.array([True]), 1, np.zeros(3))
    return cert


def _row(kind, moving_low, coast_low, detail="test", side=0.0):
    """A candidate whose per-stage margins reach ``moving_low`` against the vessel and
    ``coast_low`` against the coast (stage 15 of 30) [m beyond d_safe]."""
    X = np.zeros((31, 6))
    X[:, 1] = side * np.linspace(0.0, 5.0, 31)
    X[:, 3] = 0.3
    m = np.full((31, 2), 3.0)
    m[15, 0], m[15, 1] = moving_low, coast_low
    m[-1, 1] = 3.0 + 7.53  # the terminal requirement met with room
    return Scored(kind, detail, X, np.zeros((30, 3)), m, 0.5, False, "not certified",
                  min(moving_low, coast_low), 1.0)


def test_static_low_reads_only_the_coast_columns():
    cert = _cert()
    r = _row(Fallback.BRAKING, -4.0, 0.7)
    assert static_low(r, cert) == 0.7
    cert.start_call(np.array([True]), 0, np.zeros(3))  # no static columns: no constraint
    r0 = r._replace(margins=r.margins[:, :1])
    assert static_low(r0, cert) == np.inf


def test_without_a_certified_plan_the_coast_comes_before_a_vessels_circle():
    cert = _cert()
    ashore = _row(Fallback.BRAKING, 2.0, -0.5)  # nearest thing is the shore, 0.5 m in
    clear = _row(Fallback.TURN_PORT, -1.0, 1.0)  # deeper into the vessel's circle
    pick, _ = select_candidate([ashore, clear], np.zeros(6), np.zeros(2), cert,
                               length_m=1.255, r_comfort=0.16, prefer_starboard=False)
    assert pick.kind is Fallback.TURN_PORT
    # both keep the coast: the largest closest approach, as before
    near = _row(Fallback.BRAKING, -0.2, 0.5)
    pick, _ = select_candidate([near, clear], np.zeros(6), np.zeros(2), cert,
                               length_m=1.255, r_comfort=0.16, prefer_starboard=False)
    assert pick.kind is Fallback.BRAKING
    # both cut into the coast: the one that cuts in least
    deep = _row(Fallback.TURN_STARBOARD, 2.0, -0.9)
    pick, _ = select_candidate([deep, ashore], np.zeros(6), np.zeros(2), cert,
                               length_m=1.255, r_comfort=0.16, prefer_starboard=False)
    assert pick is ashore


def test_the_last_calls_manoeuvre_is_kept_while_it_is_nearly_as_good():
    cert = _cert()
    port = _row(Fallback.TURN_PORT, -0.30, 1.0, "full ahead, 1/3 horizon")
    stb = _row(Fallback.TURN_STARBOARD, -0.35, 1.0, "full ahead, 1/3 horizon")
    rows = [port, stb]
    kw = {"length_m": 1.255, "r_comfort": 0.16, "prefer_starboard": False}
    assert select_candidate(rows, np.zeros(6), np.zeros(2), cert, **kw)[0].kind is \
        Fallback.TURN_PORT
    pick, _ = select_candidate(rows, np.zeros(6), np.zeros(2), cert, **kw,
                               previous=("turn_starboard", "full ahead, 1/3 horizon"))
    assert pick.kind is Fallback.TURN_STARBOARD and "last call kept" in pick.detail
    # not when it falls more than 10 % of d_safe behind
    far = stb._replace(closest=-0.30 - 0.2 * D_SAFE)
    pick, _ = select_candidate([port, far], np.zeros(6), np.zeros(2), cert, **kw,
                               previous=("turn_starboard", "full ahead, 1/3 horizon"))
    assert pick.kind is Fallback.TURN_PORT
    # nor when it cuts into the coast where the best does not
    ashore = _row(Fallback.TURN_STARBOARD, -0.30, -0.1, "full ahead, 1/3 horizon")
    pick, _ = select_candidate([port, ashore], np.zeros(6), np.zeros(2), cert, **kw,
                               previous=("turn_starboard", "full ahead, 1/3 horizon"))
    assert pick.kind is Fallback.TURN_PORT
