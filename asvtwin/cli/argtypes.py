"""Argument types shared by the sub-commands: numbers checked at parse time.

Each is an ``argparse`` ``type=`` callable. A bad value becomes argparse's usual one-line
``usage`` + ``error: argument --x: ...`` message and exit code 2, instead of a traceback
deep inside a simulation.

>>> positive_float("2.5")
2.5
>>> fraction("1")
1.0
>>> fraction("3")
Traceback (most recent call last):
...
argparse.ArgumentTypeError: expected a fraction in (0, 1], actually: 3
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

__all__ = [
    "CONTROLLERS",
    "PSF_BACKENDS",
    "fraction",
    "non_negative_float",
    "out_dir",
    "positive_float",
    "positive_int",
]

#: ``choices`` of every ``--psf-backend``/``--backend`` option: "auto" and the names of
#: :data:`asvtwin.control.BACKENDS` (not imported here: the control package takes seconds
#: to import, and ``--help`` must stay fast; a test keeps the two equal).
PSF_BACKENDS = ("auto", "acados", "casadi-ipopt", "casadi-fatrop")

#: ``choices`` of every ``--controller`` option: :data:`asvtwin.scenarios.CONTROLLERS`
#: (not imported here for the same reason; a test keeps the two equal).
CONTROLLERS = ("manual", "los", "los_psf", "rl", "rl_psf")


def _number(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, actually: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, actually: {text}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0."""
    value = _number(text)
    if value <= 0.0:
        raise argparse.ArgumentTypeError(f"expected a number > 0, actually: {text}")
    return value


def non_negative_float(text: str) -> float:
    """A finite number ≥ 0."""
    value = _number(text)
    if value < 0.0:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, actually: {text}")
    return value


def fraction(text: str) -> float:
    """A fraction of a largest value, in (0, 1]."""
    value = _number(text)
    if not 0.0 < value <= 1.0:
        raise argparse.ArgumentTypeError(f"expected a fraction in (0, 1], actually: {text}")
    return value


def positive_int(text: str) -> int:
    """An integer ≥ 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, actually: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, actually: {text}")
    return value


def out_dir(command: str) -> Path:
    """The default output folder of a sub-command: ``out/<command>`` (one convention for
    every command that writes files)."""
    return Path("out") / command
