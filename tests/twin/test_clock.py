"""The clock: pacing against a fake time source, pause and single step across threads."""

from __future__ import annotations

import threading

import pytest

from asvtwin.errors import ConfigError
from asvtwin.twin.clock import Clock, parse_speed


class FakeTime:
    def __init__(self) -> None:
        self.t = 100.0
        self.slept: list[float] = []

    def now(self) -> float:
        return self.t

    def sleep(self, s: float) -> None:
        self.slept.append(s)
        self.t += s


@pytest.mark.parametrize(("text", "value"), [("max", "max"), ("MAX", "max"), ("10", 10.0),
                                             ("x50", 50.0), ("2.5x", 2.5), (1, 1.0),
                                             (float("inf"), "max")])
def test_parse_speed(text, value):
    assert parse_speed(text) == value


@pytest.mark.parametrize("bad", ["fast-ish", "0", "-1", "nan", 0.0, 2e6])
def test_parse_speed_rejects(bad):
    with pytest.raises(ConfigError, match="speed must be"):
        parse_speed(bad)


def test_realtime_waits_one_wall_second_per_simulated_second():
    ft = FakeTime()
    c = Clock(1.0, time_source=ft.now, sleep=ft.sleep, poll_s=10.0)
    for k in range(11):
        assert c.wait_for_tick(0.5 * k)
    assert ft.t == pytest.approx(105.0)  # 10 ticks of 0.5 s after the anchor
    assert c.state(5.0).mode == "realtime"


def test_scaled_speed_and_max():
    ft = FakeTime()
    c = Clock("x10", time_source=ft.now, sleep=ft.sleep, poll_s=10.0)
    for k in range(101):
        c.wait_for_tick(0.1 * k)
    assert ft.t - 100.0 == pytest.approx(1.0)  # 10 s simulated at x10
    c.set_speed("max")
    t_before = ft.t
    for k in range(101, 1000):
        c.wait_for_tick(0.1 * k)
    assert ft.t == t_before  # no waiting at all
    assert c.state().mode == "max"


def test_falling_behind_reanchors_instead_of_racing():
    ft = FakeTime()
    c = Clock(1.0, time_source=ft.now, sleep=ft.sleep, max_lag_s=1.0, poll_s=10.0)
    c.wait_for_tick(0.0)
    ft.t += 5.0  # a 5 s stall
    assert c.wait_for_tick(0.1)
    assert c.lag_resets == 1
    c.wait_for_tick(1.1)  # paced again from the new anchor: waits 1 s
    assert ft.t == pytest.approx(106.0)


def test_paused_clock_runs_exactly_the_steps_given_from_another_thread():
    c = Clock("max", paused=True, poll_s=0.01)
    assert not c.wait_for_tick(0.0, block=False)
    ran: list[int] = []

    def loop() -> None:
        k = 0
        while c.wait_for_tick(0.1 * k):
            ran.append(k)
            k += 1

    th = threading.Thread(target=loop)
    th.start()
    c.step(3)
    for _ in range(200):
        if len(ran) == 3:
            break
        threading.Event().wait(0.01)
    threading.Event().wait(0.05)
    assert ran == [0, 1, 2]  # paused again after three ticks
    assert c.state().mode == "step" and c.state().paused
    c.stop()
    th.join(2.0)
    assert not th.is_alive()
    with pytest.raises(ConfigError):
        c.step(0)
