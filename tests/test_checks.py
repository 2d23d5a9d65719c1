"""asvtwin.checks: the shared validators, their messages and their error classes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from asvtwin.checks import (
    check_all_finite,
    check_finite,
    check_positive,
    check_range,
    check_rows,
    check_vector,
)
from asvtwin.errors import ConfigError, ParameterError, StateError


def test_scalars_pass_through_as_floats():
    assert check_finite(np.float32(1.5), "a") == 1.5
    assert check_positive(0, "a", allow_zero=True) == 0.0
    assert check_range(1.0, "f", 0.0, 1.0, lo_open=True) == 1.0


@pytest.mark.parametrize("call,message", [
    (lambda: check_finite(math.nan, "mass", where="ship.toml"),
     "ship.toml: mass must be finite, actually: nan"),
    (lambda: check_positive(-1, "dt_s"), "dt_s must be > 0, actually: -1"),
    (lambda: check_positive(math.inf, "dt_s"), "dt_s must be > 0, actually: inf"),
    (lambda: check_positive(-0.1, "sigma", allow_zero=True), "sigma must be >= 0"),
    (lambda: check_range(0.0, "f", 0.0, 1.0, lo_open=True), "f must be in (0, 1], actually: 0.0"),
    (lambda: check_range(90, "switch", 0, 90, hi_open=True, unit="deg"),
     "switch must be in [0, 90) [deg], actually: 90"),
    (lambda: check_range(math.nan, "f", 0.0, 1.0), "f must be in [0, 1], actually: nan"),
])
def test_messages_say_expected_and_actual(call, message):
    with pytest.raises(ParameterError) as e:
        call()
    assert message in str(e.value)
    assert isinstance(e.value, ValueError)  # the fitting built-in too


def test_the_caller_chooses_the_error_class():
    with pytest.raises(ConfigError, match="environment: T_s must be > 0"):
        check_positive(0.0, "T_s", where="environment", error=ConfigError)


def test_arrays():
    a = check_rows([1, 2, 3], 3, "input")
    assert a.shape == (1, 3) and a.dtype == np.float64
    with pytest.raises(StateError, match=r"input must have shape \(3,\) or \(n, 3\)"):
        check_rows(np.zeros((2, 4)), 3, "input")
    with pytest.raises(StateError, match="state of vessel 1 has non-finite v: inf"):
        check_rows([[0, 0, 0], [0, np.inf, 0]], 3, "state", ("u", "v", "r"))
    with pytest.raises(StateError, match="target of track 0 has non-finite 2"):
        check_rows([[0, 0, np.nan]], 3, "target", row="track")
    assert check_vector([1.0, 2.0], 2, "x").shape == (2,)
    with pytest.raises(StateError, match="x has non-finite b: nan"):
        check_vector([1.0, np.nan], 2, "x", ("a", "b"))
    with pytest.raises(StateError, match=r"entry \(1, 0\) is nan"):
        check_all_finite([[1.0, 2.0], [np.nan, 0.0]], "radii")


def test_the_vessel_model_uses_the_shared_check():
    from asvtwin.vessel.model import validate_array

    with pytest.raises(StateError, match="state of vessel 0 has non-finite psi"):
        validate_array([0, 0, np.nan, 0, 0, 0], 6, "state", ("x", "y", "psi", "u", "v", "r"))
