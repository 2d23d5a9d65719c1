"""The scheduler: rates, failure isolation, overrun back-off only when paced."""

from __future__ import annotations

import pytest

from asvtwin.twin.clock import Clock
from asvtwin.twin.scheduler import Scheduler


class Wall:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def test_components_run_at_their_own_rates():
    s = Scheduler(Clock("max"))
    s.add("lidar", 0.1)
    s.add("filter", 0.5)
    s.add("every", 0.0)
    calls = {"lidar": 0, "filter": 0, "every": 0}
    for k in range(200):  # 10 s at 20 Hz
        t = 0.05 * k
        for name, count in list(calls.items()):
            if s.due(name, t):
                s.call(name, t, calls.__setitem__, name, count + 1)
    assert calls == {"lidar": 100, "filter": 20, "every": 200}


def test_a_raising_component_is_isolated_counted_and_finally_disabled():
    s = Scheduler(Clock("max"), fail_after=5)
    s.add("bad", 0.0)

    def boom(x: int) -> int:
        raise ValueError(f"bad input {x}")

    outs = [s.call("bad", float(k), boom, k, fallback=-1) for k in range(4)]
    assert outs == [(False, -1)] * 4
    h = s.health()[0]
    assert (h.errors, h.calls, h.status) == (4, 4, "degraded")
    assert "ValueError: bad input 3" in h.last_error
    assert s.due("bad", 10.0)
    s.call("bad", 4.0, boom, 4)
    assert not s.due("bad", 10.0)  # five in a row: disabled
    assert s.health()[0].status == "failed"
    assert "bad failed and disabled: 5 error(s)" in s.degradations()[0]
    # a success resets the run of errors
    s.add("flaky", 0.0)
    for k in range(10):
        s.call("flaky", float(k), boom if k % 2 else int, k)
    assert s.stats("flaky").errors == 5 and not s.stats("flaky").failed


@pytest.mark.parametrize(("speed", "stretched"), [(1.0, True), ("max", False)])
def test_overruns_stretch_the_period_only_in_a_paced_run(speed, stretched):
    wall = Wall()
    s = Scheduler(Clock(speed, time_source=wall), backoff_after=3)
    s.add("slow", 0.1, budget_ms=50.0)

    def slow() -> None:
        wall.t += 0.2  # 200 ms of wall time

    t = 0.0
    for _ in range(3):
        assert s.due("slow", t)
        s.call("slow", t, slow)
        t += 0.1
    st = s.stats("slow")
    assert st.overruns == (3 if stretched else 0)
    assert st.stretch == (2 if stretched else 1)
    assert st.mean_ms == pytest.approx(200.0)
    if stretched:
        assert not s.due("slow", t)  # next call 0.2 s after the last
        assert s.due("slow", t + 0.1)
        assert "period stretched to 0.2 s" in s.health()[0].last_error
