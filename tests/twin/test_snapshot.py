"""The snapshot contract: encodes to JSON that its own JSON Schema accepts, NaN is null."""

from __future__ import annotations

import jsonschema
import numpy as np
import pytest

from asvtwin.twin.snapshot import (
    AisTargets,
    ComponentHealth,
    FilterState,
    Snapshot,
    Tracks,
    decode,
    empty_snapshot,
    encode,
    json_schema,
    ro,
)


def _full() -> Snapshot:
    n, h = 3, 5
    return empty_snapshot(
        seq=7, t_s=12.5,
        ais=AisTargets(mmsi=ro([257000001, 257000002, 257000003], np.int64),
                       names=("A", "B", ""), position_m=ro(np.ones((n, 2))),
                       lat_deg=ro([63.4] * n), lon_deg=ro([10.4] * n),
                       sog_m_s=ro([1.0, np.nan, 2.0]), cog_rad=ro([0.1, np.nan, 0.2]),
                       heading_rad=ro([np.nan] * n), age_s=ro([1.0, 2.0, 3.0]),
                       stale=ro([False, False, True], np.bool_), length_m=ro([10.0, np.nan, 5.0]),
                       beam_m=ro([3.0, np.nan, 2.0])),
        tracks=Tracks(ids=ro([1, 2, 3], np.int64), mmsi=ro([-1, 257000001, -1], np.int64),
                      status=("confirmed",) * n, source=("lidar", "fused", "ais"),
                      mean=ro(np.zeros((n, 4))), cov=ro(np.tile(np.eye(4), (n, 1, 1))),
                      pred_times_s=ro(np.arange(h, dtype=float)),
                      pred_mean=ro(np.zeros((n, h, 2))), pred_radius_m=ro(np.ones((n, h))),
                      cpa_m=ro([np.nan, 3.0, 4.0]), tcpa_s=ro([np.nan, 10.0, -1.0])),
        filter=FilterState(u_L=ro([1.0, 0, 0]), u_0=ro([0.5, 0, 0]), intervened=True,
                           fallback="braking", explanation="vessel on the starboard bow",
                           plan=ro(np.zeros((4, 2))), plan_margin_m=ro([1.0, 0.5, -0.1, 2.0]),
                           critical_stages=ro([2], np.int64)),
        health=(ComponentHealth(name="lidar", period_s=0.1, calls=10),),
        events=("track 2 dangerous",), counters={"ais_lines": 4},
    )


@pytest.mark.parametrize("snap", [empty_snapshot(), _full()], ids=["empty", "full"])
def test_encoded_snapshot_validates_against_its_schema(snap: Snapshot) -> None:
    msg = decode(encode(snap))
    jsonschema.validate(msg, json_schema())
    assert msg["schema"] == "asvtwin.snapshot/1"


def test_not_available_is_null_on_the_wire() -> None:
    msg = decode(encode(_full()))
    assert msg["ais"]["sog_m_s"] == [1.0, None, 2.0]
    assert msg["ais"]["heading_rad"] == [None, None, None]
    assert msg["tracks"]["cov"][0] == np.eye(4).tolist()
    assert msg["filter"]["critical_stages"] == [2]


def test_schema_rejects_a_wrong_type() -> None:
    msg = decode(encode(_full()))
    msg["filter"]["fallback"] = 3
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(msg, json_schema())


def test_arrays_are_read_only() -> None:
    s = _full()
    with pytest.raises(ValueError):
        s.tracks.mean[0, 0] = 1.0
