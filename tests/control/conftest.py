"""Shared fixtures of the safety-filter tests: one filter per backend per session."""

from __future__ import annotations

import os

import pytest

from asvtwin.control import PsfConfig, SafetyFilter, available_backends
from asvtwin.vessel import cybership2

FULL = os.environ.get("ASVTWIN_FULL") == "1"


@pytest.fixture(scope="session")
def params():
    return cybership2()


@pytest.fixture(scope="session")
def default_backend() -> str:
    """The fastest installed backend (ASVTWIN_PSF_BACKEND overrides, e.g. casadi-ipopt)."""
    return os.environ.get("ASVTWIN_PSF_BACKEND") or available_backends()[0]


@pytest.fixture(scope="session")
def psf(params, default_backend):
    """The benchmark setting: N = 50 stages of 0.5 s, the fastest installed backend."""
    return SafetyFilter(params, config=PsfConfig(backend=default_backend))


@pytest.fixture(scope="session")
def psf_ipopt(params):
    return SafetyFilter(params, config=PsfConfig(backend="casadi-ipopt"))
