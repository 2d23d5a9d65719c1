"""Shared test configuration.

``ASVTWIN_FULL=1`` runs the long versions of the studies marked ``slow``; by default
they run their short, real version (each test reads :func:`full_run`).
"""

from __future__ import annotations

import os

import matplotlib
import pytest

matplotlib.use("Agg")


def full_run() -> bool:
    """True when the long versions of the slow studies are asked for."""
    return os.environ.get("ASVTWIN_FULL", "") not in ("", "0")


@pytest.fixture
def rng():
    import numpy as np

    return np.random.default_rng(12345)
