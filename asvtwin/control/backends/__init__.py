"""Solver backends of the safety filter behind one interface (:class:`Backend`).

``casadi-ipopt`` (always available), ``casadi-fatrop`` (same wheel) and ``acados``
(SQP-RTI, the optional ``acados`` extra). :func:`make_backend` builds one per problem and
process and keeps it: a filter never rebuilds its solver in a loop.
"""

from __future__ import annotations

import logging
import threading

from asvtwin.control.backends.base import Backend, RawSolution
from asvtwin.control.backends.ocp import OcpSpec, cache_dir
from asvtwin.errors import ConfigError

__all__ = [
    "BACKENDS",
    "Backend",
    "OcpSpec",
    "RawSolution",
    "available_backends",
    "backend_lock",
    "cache_dir",
    "claim_backend",
    "make_backend",
]

log = logging.getLogger(__name__)

#: Backend names, fastest first (the order "auto" tries).
BACKENDS = ("acados", "casadi-ipopt", "casadi-fatrop")

_BUILT: dict[tuple[str, str], Backend] = {}
_LOCKS: dict[int, threading.Lock] = {}
_LOCKS_GUARD = threading.Lock()
_OWNERS: dict[int, object] = {}


def backend_lock(backend: object) -> threading.Lock:
    """The lock that serialises calls into ``backend``: filters with the same problem share
    one compiled solver per process, and two twins solving at once from two threads must
    not enter it together (acados' solver memory is not thread-safe)."""
    with _LOCKS_GUARD:
        return _LOCKS.setdefault(id(backend), threading.Lock())


def claim_backend(backend: object, owner: object) -> bool:
    """Record ``owner`` as the last user of the shared ``backend`` (call under its
    :func:`backend_lock`); True when another owner (or none) used it last.

    acados carries its multipliers and the QP's warm start from one solve to the next, so
    a filter that takes over the shared solver resets it first: its answers must not
    depend on what other filters solved before it in the process."""
    key = id(backend)
    if _OWNERS.get(key) is owner:
        return False
    _OWNERS[key] = owner
    return True


def available_backends() -> list[str]:
    """Names of the backends that can be built in this environment, fastest first."""
    from asvtwin.control.backends.acados_backend import acados_available

    names = ["casadi-ipopt", "casadi-fatrop"]
    return (["acados"] if acados_available() else []) + names


def make_backend(name: str, spec: OcpSpec, **options: object) -> Backend:
    """The backend ``name`` for ``spec``, built once per process (``"auto"``: fastest)."""
    if name == "auto":
        name = available_backends()[0]
    if name not in BACKENDS:
        raise ConfigError(f"backend must be 'auto' or one of {list(BACKENDS)}, "
                          f"actually: {name!r}")
    key = (name, spec.key() + repr(sorted(options.items())))
    if key in _BUILT:
        return _BUILT[key]
    backend: Backend
    if name == "acados":
        from asvtwin.control.backends.acados_backend import AcadosBackend

        backend = AcadosBackend(spec, **options)  # type: ignore[arg-type]
    else:
        from asvtwin.control.backends.casadi_backend import CasadiBackend

        backend = CasadiBackend(spec, solver=name.split("-", 1)[1],
                                **options)  # type: ignore[arg-type]
    _BUILT[key] = backend
    log.info("built safety filter backend %s (N=%d, %d circles, %d segments)", name,
             spec.N, spec.n_circles, spec.n_segments)
    return backend
