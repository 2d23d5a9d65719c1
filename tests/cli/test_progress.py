"""First runs compile kernels: "compiling kernels, first run only" is said once, and
nothing is said when the cache is warm."""

from __future__ import annotations

import io
import os
import subprocess
import sys
import textwrap

import numba
import pytest

from asvtwin.cli.progress import compile_notice
from tests.conftest import full_run


def test_a_compilation_is_announced_once_with_a_summary():
    stream = io.StringIO()
    with compile_notice(stream) as progress:
        @numba.njit(cache=False)
        def f(x):
            return x + 1

        @numba.njit(cache=False)
        def g(x):
            return f(x) * 2

        assert g(1) == 4
    text = stream.getvalue()
    assert text.count("compiling kernels, first run only") == 1
    assert progress.compiled >= 2  # g and its callee f
    assert f"compiled {progress.compiled} kernels in" in text


def test_nothing_is_said_when_nothing_compiles():
    @numba.njit(cache=False)
    def h(x):
        return x - 1

    h(1)  # compiled outside: inside the block it is warm
    stream = io.StringIO()
    with compile_notice(stream) as progress:
        assert h(2) == 1
    assert stream.getvalue() == "" and progress.compiled == 0


def test_the_listener_waits_for_numba_to_be_imported():
    # a fresh interpreter: numba is imported only inside the block, through the hook
    code = textwrap.dedent("""
        import sys
        from asvtwin.cli.progress import compile_notice
        assert "numba" not in sys.modules
        with compile_notice(sys.stdout):
            import numba
            assert numba.njit(lambda x: x + 1)(1) == 2
    """)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr
    assert "compiling kernels, first run only" in proc.stdout
    assert "compiled 1 kernel in" in proc.stdout


def test_a_library_build_announced_on_the_build_logger_is_shown():
    import logging

    from asvtwin.cli.progress import BUILD_LOGGER

    stream = io.StringIO()
    with compile_notice(stream) as progress:
        logging.getLogger(BUILD_LOGGER).info("compiling the acados solver, first run only")
    text = stream.getvalue()
    assert text.splitlines()[0].startswith("asvtwin: compiling kernels, first run only")
    assert "asvtwin: compiling the acados solver, first run only" in text
    assert progress.builds and "compiled 0 kernels and 1 solver build in" in text
    # outside the block the logger is quiet again (default WARNING level)
    assert logging.getLogger(BUILD_LOGGER).level == logging.NOTSET


@pytest.mark.slow
@pytest.mark.skipif(not full_run(), reason="compiles the vessel kernels from an empty "
                    "cache (~10 s CPU); set ASVTWIN_FULL=1")
def test_first_run_from_an_empty_cache_says_so(tmp_path):
    """The README's first-run promise, end to end: an empty numba cache, the make-run
    command, the notice on stderr; the second run is silent."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    argv = [sys.executable, "-m", "asvtwin", "sim", "--vessel", "cybership2", "--manoeuvre",
            "thrust_step", "--no-plot", "--out", str(tmp_path / "out")]
    first = subprocess.run(argv, capture_output=True, text=True, env=env, timeout=600,
                           check=False)
    assert first.returncode == 0, first.stderr
    assert first.stderr.startswith("asvtwin: compiling kernels, first run only")
    assert "later runs load them from the cache" in first.stderr
    second = subprocess.run(argv, capture_output=True, text=True, env=env, timeout=600,
                            check=False)
    assert second.returncode == 0 and second.stderr == ""
