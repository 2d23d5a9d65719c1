"""``--json`` prints only JSON on stdout even when a native library printf()s on fd 1
(acados/HPIPM print "QP solver returned error status 3" from C, past sys.stdout)."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

from ruamel.yaml import YAML

from .conftest import BASE

NATIVE = "QP solver returned error status 3"

# a child process whose twin prints from C on fd 1 at every tick, as acados does, and in
# the middle of a buffered line (no newline) so that only a C-level flush moves it
_PATCH = textwrap.dedent(f"""
    import ctypes, sys
    libc = ctypes.CDLL(None)
    from asvtwin.twin import runtime
    _step = runtime.Twin.step
    def step(self, *a, **k):
        libc.printf(b"{NATIVE}\\n")
        libc.printf(b"partial native line ")
        print("a stray Python print")
        return _step(self, *a, **k)
    runtime.Twin.step = step
    from asvtwin.cli import main
    sys.exit(main(sys.argv[1:]))
""")


def _child(args: list[str], tmp_path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", _PATCH, *args], check=False, capture_output=True,
                          text=True, timeout=300, cwd=tmp_path)


def _scenario(tmp_path) -> str:
    scen = json.loads(json.dumps(BASE))
    # the native print is injected, so no safety filter is needed (its build is slow)
    scen["rates"] = {"sim_hz": 2.0, "tracker_hz": 1.0, "observer_hz": 2.0,
                     "controller_hz": 2.0, "filter_hz": 0.5, "snapshot_hz": 0.5}
    path = tmp_path / "scenario.yaml"
    with open(path, "w") as f:
        YAML().dump(scen, f)
    return str(path)


def test_run_json_stdout_is_only_json(tmp_path) -> None:
    path = _scenario(tmp_path)
    p = _child(["run", "--headless", "--scenario", path, "--duration", "4", "--json",
                "--no-record", "--out", str(tmp_path / "out")], tmp_path)
    assert p.returncode in (0, 1), p.stderr[-2000:]
    summary = json.loads(p.stdout)  # nothing but the JSON object
    assert summary["scenario"] == "twin_test" and summary["ticks"] == 8
    assert NATIVE in p.stderr and "a stray Python print" in p.stderr  # moved, not lost
    assert json.loads((tmp_path / "out" / "summary.json").read_text()) == summary


def test_scenario_run_json_stdout_is_only_json(tmp_path) -> None:
    path = _scenario(tmp_path)
    p = _child(["scenario", "run", path, "--json", "--duration", "4", "--no-record"],
               tmp_path)
    assert p.returncode in (0, 1), p.stderr[-2000:]
    summary = json.loads(p.stdout)
    assert summary["scenario"] == "twin_test"
    assert NATIVE in p.stderr


def test_context_manager_restores_stdout_and_moves_only_the_block() -> None:
    """Native and Python prints inside the block go to stderr, the yielded stream and
    everything after the block to stdout (a light child: no twin)."""
    code = textwrap.dedent(f"""
        import ctypes
        from asvtwin.cli.run import native_stdout_to_stderr
        libc = ctypes.CDLL(None)
        print("before", flush=True)
        with native_stdout_to_stderr() as out:
            libc.printf(b"{NATIVE}\\n")
            libc.printf(b"unterminated")
            print("python inside")
            print('{{"ok": 1}}', file=out)
        libc.printf(b"native after\\n")
        print("after")
    """)
    p = subprocess.run([sys.executable, "-c", code], check=False, capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 0, p.stderr
    assert p.stdout.splitlines()[0:2] == ["before", '{"ok": 1}']
    assert "after" in p.stdout and "native after" in p.stdout
    assert NATIVE not in p.stdout and "unterminated" not in p.stdout
    assert NATIVE in p.stderr and "unterminated" in p.stderr and "python inside" in p.stderr
    with_off = subprocess.run([sys.executable, "-c", code.replace(
        "native_stdout_to_stderr()", "native_stdout_to_stderr(False)")],
        check=False, capture_output=True, text=True, timeout=120)
    assert NATIVE in with_off.stdout  # the control: the native print does reach stdout
