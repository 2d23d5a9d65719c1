"""acados prints a line to the C stdout for every failed QP ("SQP_RTI: QP solver returned
error status 3 …"; compiled into libacados, print_level does not reach it): in the twin
among 50 vessels, thousands of lines an hour over `asvtwin run`'s terminal. The backend
silences fd 1 during its solves; the failure stays in every result's status."""

from __future__ import annotations

import ctypes
import os
import threading

import numpy as np
import pytest

from asvtwin.control import MovingObstacles, PsfConfig, SafetyFilter, available_backends
from asvtwin.vessel import cybership2_full_scale

pytestmark = pytest.mark.skipif("acados" not in available_backends(),
                                reason="the acados backend is not installed")


def _crowd(psf: SafetyFilter, seed: int, n: int = 6) -> None:
    """``n`` calls among twelve 300 m circles around the full-scale ship (seeded): QPs
    that HPIPM often cannot solve."""
    N, dt = psf.config.N, psf.config.dt_s
    x = np.array([0.0, 0.0, 0.0, 5.0, 0.0, 0.0])
    rng = np.random.default_rng(seed)
    tau = dt * np.arange(N + 1)
    for k in range(n):
        c = rng.uniform(-600, 600, (12, 1, 2)) + [300.0, 0.0]
        v = rng.uniform(-5, 5, (12, 1, 2))
        obs = MovingObstacles(positions=c + v * tau[None, :, None], radii=np.full(12, 300.0))
        res = psf.filter(x, psf.u_ub * np.array([0.6, 0.0, 0.0]), [obs], t_s=dt * k)
        assert np.all(np.isfinite(res.u0))


def test_what_acados_prints_during_a_solve_does_not_reach_stdout(capfd, monkeypatch):
    """acados' own line, printed from C in the middle of every solve (as libacados does on
    a failed QP), is silenced; the solve's answer is unchanged, and stdout works after."""
    psf = SafetyFilter(cybership2_full_scale(), config=PsfConfig(backend="acados"))
    io, libc = psf.backend._io, ctypes.CDLL(None)
    solve, calls = io.solve, []

    def noisy() -> int:
        calls.append(1)
        libc.printf(b"\nSQP_RTI: QP solver returned error status 3 QP iteration 1.\n")
        return solve()

    monkeypatch.setattr(io, "solve", noisy)  # the backend is shared: restored after
    _crowd(psf, seed=3)
    print("after the solves")
    out = capfd.readouterr().out
    assert calls  # the solver ran (and printed, from C, each time)
    assert "QP solver returned error" not in out
    assert "after the solves" in out


def test_the_redirect_is_shared_by_threads_and_restored():
    from asvtwin.control.backends.acados_backend import _c_stdout_silenced

    before = os.fstat(1)
    inside: list[tuple[int, int]] = []
    go = threading.Barrier(4)

    def worker():
        go.wait()
        for _ in range(200):
            with _c_stdout_silenced():
                st = os.fstat(1)
                inside.append((st.st_dev, st.st_ino))

    threads = [threading.Thread(target=worker) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    null = os.stat(os.devnull)
    assert set(inside) == {(null.st_dev, null.st_ino)}  # always /dev/null inside
    after = os.fstat(1)
    assert (after.st_dev, after.st_ino) == (before.st_dev, before.st_ino)  # and back after
