"""The one exception family of asvtwin.

Every error the package raises on purpose derives from :class:`AsvTwinError` and from the
built-in exception that fits, so callers can catch either (``except ValueError`` keeps
working). Messages say what was expected and what was found.
"""

from __future__ import annotations

__all__ = [
    "AsvTwinError",
    "ConfigError",
    "MissingExtraError",
    "ParameterError",
    "ScenarioError",
    "SceneError",
    "SolverError",
    "SourceError",
    "StateError",
]


class AsvTwinError(Exception):
    """Base class of every error raised by asvtwin on purpose."""


class ParameterError(AsvTwinError, ValueError):
    """A model parameter is out of its allowed range (mass matrix, damping, limits...)."""


class StateError(AsvTwinError, ValueError):
    """A state, input or disturbance array is malformed or holds NaN/inf."""


class SceneError(AsvTwinError, ValueError):
    """A scene file is malformed: names the file, the field and the allowed range."""


class ScenarioError(AsvTwinError, ValueError):
    """A scenario is malformed: names the file, the line, the field and the allowed range."""


class ConfigError(AsvTwinError, ValueError):
    """A configuration file or value is invalid."""


class SourceError(AsvTwinError, RuntimeError):
    """A data source (AIS, weather) cannot be opened or read."""


class SolverError(AsvTwinError, RuntimeError):
    """An optimisation backend is unavailable or misconfigured (not a failed solve)."""


class MissingExtraError(AsvTwinError, ImportError):
    """An optional dependency is missing; the message names the extra to install."""

    def __init__(self, package: str, extra: str) -> None:
        super().__init__(
            f"{package!r} is not installed; install it with: pip install 'asvtwin[{extra}]'"
        )
        self.package = package
        self.extra = extra
