"""The AIS static reports (type 5 and 24: length and beam) reach the twin's tracker.

Until 2026-12-02 the twin decoded them into its AIS registry but never handed them to the
tracker, so a tied track never knew its hull's size, and a long hull's ends started
tracks of their own (tests/tracking/test_long_hulls.py)."""

from __future__ import annotations

from asvtwin.twin import Twin
from tests.twin.conftest import scenario


def test_static_reports_size_the_tracks_of_transmitting_vessels():
    twin = Twin(scenario(duration_s=400.0))
    dims = {}
    while twin.t_s < 400.0 and len(dims) < 2:
        twin.step()
        dims = dict(twin.perception.tracker.dimensions)
    # ALPHA (class A, type 5) and BRAVO (class B, type 24 part B) as the scenario sizes them
    assert dims.get(257000001) == (80.0, 14.0), (twin.t_s, dims)
    assert dims.get(257000002) == (20.0, 5.0), (twin.t_s, dims)
    assert 257000003 not in dims  # CHARLIE sends no AIS
