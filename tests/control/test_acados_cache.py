"""A generated acados solver is cached per acados installation.

A cached solver's ``acados_ocp.json`` records the library path of the installation that
built it, and loading it opens ``libacados.so`` from there. The cache folder was named
by the problem, the options and the acados version only, so a second environment (a
clean clone's ``.venv``, another virtualenv) reused the first one's build, and once that
environment was deleted every filter failed to build ("libacados.so: cannot open shared
object file"; seen 2026-12-07). The builds run in fresh interpreters with their own
cache folder.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from asvtwin.control import available_backends
from asvtwin.control.backends.acados_backend import solver_cache_key

SCRIPT = ("from asvtwin.control import PsfConfig, SafetyFilter\n"
          "from asvtwin.vessel import cybership2\n"
          "SafetyFilter(cybership2(), config=PsfConfig(backend='acados'))\n"
          "print('built')\n")


def test_the_cache_key_names_the_installation(tmp_path):
    opts, S = {"nlp_solver_type": "SQP_RTI"}, np.array([2.0, 1.0, 1.5])
    a = solver_cache_key(opts, "0.2", "/opt/one/acados", S)
    assert a == solver_cache_key(opts, "0.2", "/opt/one/acados", S)
    assert a != solver_cache_key(opts, "0.2", "/opt/two/acados", S)
    assert a != solver_cache_key(opts, "0.3", "/opt/one/acados", S)
    # a link to the same installation is the same installation
    real = tmp_path / "install"
    real.mkdir()
    (tmp_path / "link").symlink_to(real)
    assert (solver_cache_key(opts, "0.2", str(real), S)
            == solver_cache_key(opts, "0.2", str(tmp_path / "link"), S))


@pytest.mark.skipif("acados" not in available_backends(), reason="needs the acados extra")
def test_a_solver_built_by_a_deleted_installation_is_not_reused(tmp_path):
    import acados  # type: ignore[import-not-found]

    other = tmp_path / "other_install"
    shutil.copytree(acados.DIR, other, symlinks=True)
    cache = tmp_path / "cache"

    def build(source: str) -> None:
        env = {**os.environ, "ASVTWIN_CACHE": str(cache), "ACADOS_SOURCE_DIR": source}
        r = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True,
                           check=False, text=True, timeout=900)
        assert r.returncode == 0 and "built" in r.stdout, r.stderr[-3000:]

    build(str(other))  # another environment builds first ...
    shutil.rmtree(other)  # ... and is deleted
    build(acados.DIR)  # this one must build its own
    recorded = {os.path.realpath(json.loads(f.read_text())["acados_lib_path"])
                for f in cache.glob("acados_*/acados_ocp.json")}
    assert os.path.realpath(os.path.join(acados.DIR, "lib")) in recorded
    assert os.path.realpath(str(other / "lib")) in recorded
