"""asvtwin: a digital twin of an autonomous surface vessel in the Trondheim Fjord.

Subpackages (imported on demand): ``geo``, ``vessel``, ``environment``, ``sources``,
``sensors``, ``tracking``, ``observer``, ``control``, ``rl``, ``twin``, ``server``.
"""

from importlib.metadata import PackageNotFoundError, version

from asvtwin.errors import AsvTwinError

try:
    __version__ = version("asvtwin")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+src"

__all__ = ["AsvTwinError", "__version__"]
