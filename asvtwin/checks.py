"""Shared array type and input checks: one home for what many modules validate.

Every check raises an :class:`~asvtwin.errors.AsvTwinError` subclass (``error=``, chosen by
the caller: :class:`~asvtwin.errors.ParameterError` for model parameters,
:class:`~asvtwin.errors.ConfigError` for settings, :class:`~asvtwin.errors.StateError` for
states and inputs) whose message says where (``where``: a file, a config section), what
(``name``), the allowed range and the actual value, in the form "expected …, actually: …".
Each returns the checked value, so a check reads as an assignment.

>>> check_positive(2.5, "dt_s")
2.5
>>> check_range(1.5, "surge_fraction", 0.0, 1.0, lo_open=True)
Traceback (most recent call last):
...
asvtwin.errors.ParameterError: surge_fraction must be in (0, 1], actually: 1.5
>>> check_rows([[0, 0, 0, 1, 0, float("nan")]], 6, "state", ("x", "y", "psi", "u", "v", "r"))
Traceback (most recent call last):
...
asvtwin.errors.StateError: state of vessel 0 has non-finite r: nan
"""

from __future__ import annotations

import math
from typing import TypeAlias

import numpy as np
from numpy.typing import ArrayLike, NDArray

from asvtwin.errors import AsvTwinError, ParameterError, StateError

__all__ = [
    "F8",
    "check_all_finite",
    "check_finite",
    "check_positive",
    "check_range",
    "check_rows",
    "check_vector",
]

#: A float64 array: the package's one alias for ``NDArray[np.float64]``.
F8: TypeAlias = NDArray[np.float64]


def _prefix(where: str) -> str:
    return f"{where}: " if where else ""


def check_finite(value: float, name: str, *, where: str = "",
                 error: type[AsvTwinError] = ParameterError) -> float:
    """``value`` as a float; refused if NaN or infinite."""
    v = float(value)
    if not math.isfinite(v):
        raise error(f"{_prefix(where)}{name} must be finite, actually: {value}")
    return v


def check_positive(value: float, name: str, *, allow_zero: bool = False, where: str = "",
                   error: type[AsvTwinError] = ParameterError) -> float:
    """``value`` as a float; refused unless finite and > 0 (≥ 0 with ``allow_zero``)."""
    v = float(value)
    ok = v >= 0.0 if allow_zero else v > 0.0
    if not (math.isfinite(v) and ok):
        raise error(f"{_prefix(where)}{name} must be {'>=' if allow_zero else '>'} 0, "
                    f"actually: {value}")
    return v


def check_range(value: float, name: str, lo: float, hi: float, *, lo_open: bool = False,
                hi_open: bool = False, unit: str = "", where: str = "",
                error: type[AsvTwinError] = ParameterError) -> float:
    """``value`` as a float; refused unless finite and inside [lo, hi] (open ends with
    ``lo_open``/``hi_open``)."""
    v = float(value)
    inside = (v > lo if lo_open else v >= lo) and (v < hi if hi_open else v <= hi)
    if not (math.isfinite(v) and inside):
        span = f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
        raise error(f"{_prefix(where)}{name} must be in {span}{f' [{unit}]' if unit else ''}"
                    f", actually: {value}")
    return v


def check_all_finite(a: ArrayLike, what: str, *,
                     error: type[AsvTwinError] = StateError) -> F8:
    """``a`` as a float array; refused naming the first non-finite entry's index."""
    arr = np.asarray(a, dtype=np.float64)
    bad = ~np.isfinite(arr)
    if bad.any():
        idx = tuple(int(i) for i in np.argwhere(bad)[0])
        raise error(f"{what} must be finite, actually entry {idx} is {arr[idx]}")
    return arr


def check_vector(a: ArrayLike, n: int, what: str, fields: tuple[str, ...] | None = None, *,
                 error: type[AsvTwinError] = StateError) -> F8:
    """``a`` as a float (n,) array; refused naming the expected shape or the field of the
    first non-finite entry."""
    arr = np.asarray(a, dtype=np.float64)
    if arr.shape != (n,):
        raise error(f"{what} must have shape ({n},), actually: {arr.shape}")
    bad = ~np.isfinite(arr)
    if bad.any():
        j = int(np.argmax(bad))
        raise error(f"{what} has non-finite {fields[j] if fields else j}: {arr[j]}")
    return arr


def check_rows(a: ArrayLike, width: int, what: str, fields: tuple[str, ...] | None = None,
               *, row: str = "vessel", error: type[AsvTwinError] = StateError) -> F8:
    """``a`` as a float (n, width) array (a (width,) row becomes (1, width)); refused
    naming the expected shape, or the row index and field of the first NaN/inf."""
    arr = np.asarray(a, dtype=np.float64)
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != width:
        raise error(f"{what} must have shape ({width},) or (n, {width}), actually: "
                    f"{np.shape(a)}")
    bad = ~np.isfinite(arr)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        name = fields[j] if fields else str(j)
        raise error(f"{what} of {row} {i} has non-finite {name}: {arr[i, j]}")
    return arr
