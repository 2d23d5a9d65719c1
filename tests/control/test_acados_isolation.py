"""The acados backend's libraries do not leak their symbols into the process.

With the libraries preloaded ``RTLD_GLOBAL`` a torch linear layer run after one filter call
crashed the interpreter (segmentation fault): BLASFEO/HPIPM symbols shadowed those torch
resolves at run time. The check runs in a fresh interpreter, so a crash fails this test
instead of the test session.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from asvtwin.control import available_backends

SCRIPT = textwrap.dedent("""
    from asvtwin.control import PsfConfig, SafetyFilter
    from asvtwin.vessel import cybership2
    psf = SafetyFilter(cybership2(), config=PsfConfig(backend="acados"))
    r = psf.filter([0, 0, 0, 0.3, 0, 0], [2.0, 0, 0], None, t_s=0.0)
    import torch
    layer = torch.nn.Linear(186, 128)
    with torch.no_grad():
        y = layer(torch.ones(64, 186))
    print("ok", r.fallback, y.shape[0])
""")


def test_torch_runs_after_the_acados_filter_in_one_process():
    if not any(b.startswith("acados") for b in available_backends()):
        pytest.skip("acados extra not installed")
    pytest.importorskip("torch")
    proc = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True,
                          timeout=600, check=False)
    assert proc.returncode == 0, f"exit {proc.returncode}\n{proc.stderr[-2000:]}"
    assert proc.stdout.split()[-1] == "64"
