"""Say so when a first run compiles: "compiling kernels, first run only", with progress.

The numerical kernels are compiled by numba on first use and cached on disk beside the
sources (or in ``NUMBA_CACHE_DIR``); a first run on a fresh checkout spends 30-70 s
there, later runs load them in well under a second. :func:`compile_notice` listens for
numba's ``numba:compile`` event, which fires only on a cache miss, so nothing is printed
when the cache is warm. On a terminal the line counts the kernels and the seconds as they
go; elsewhere (a log, CI) one line at the start and one at the end.

Importing numba costs most of a second, so the listener is installed only once numba is
imported by the command itself (an import hook waits for ``numba.core.event``).

Other first-run builds (the acados solver's C code) announce themselves through the logger
``asvtwin.build`` (:data:`BUILD_LOGGER`): library code logs one INFO record before a long
build, ``logging.getLogger("asvtwin.build").info("compiling the acados solver, first run
only")``, and the notice prints it and keeps the seconds counting, whatever ``-v`` says.
"""

from __future__ import annotations

import importlib.abc
import importlib.util
import logging
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import IO, Any

__all__ = ["BUILD_LOGGER", "CompileProgress", "compile_notice"]

#: Logger through which library code announces a long first-run build.
BUILD_LOGGER = "asvtwin.build"


class CompileProgress:
    """Counts numba compilations and reports them on ``stream`` (stderr by default)."""

    def __init__(self, stream: IO[str] | None = None, *, interval_s: float = 0.5) -> None:
        self.stream = stream if stream is not None else sys.stderr
        self.interval_s = interval_s
        self.compiled = 0
        self.builds: list[str] = []
        self.current = ""
        self.t0: float | None = None
        self._depth = 0
        self._stop = threading.Event()
        self._ticker: threading.Thread | None = None
        self._tty = bool(getattr(self.stream, "isatty", lambda: False)())

    # numba.core.event.Listener protocol (duck-typed: no numba import here)
    def notify(self, event: Any) -> None:
        if event.is_start:
            self._start(event)
        else:
            self._depth = max(0, self._depth - 1)
            self.compiled += 1

    def build(self, message: str) -> None:
        """A library build announced on :data:`BUILD_LOGGER`: say it, keep counting."""
        self._begin()
        self._write(f"asvtwin: {message}\n")
        self.builds.append(message)
        self.current = message

    def _start(self, event: Any) -> None:
        self._depth += 1
        dispatcher = (event.data or {}).get("dispatcher")
        self.current = getattr(getattr(dispatcher, "py_func", None), "__name__", "")
        self._begin()

    def _begin(self) -> None:
        if self.t0 is None:
            self.t0 = time.monotonic()
            self._write("asvtwin: compiling kernels, first run only (they are cached; "
                        "this takes 30-70 s once)\n")
            if self._tty:
                self._ticker = threading.Thread(target=self._tick, daemon=True)
                self._ticker.start()

    def _tick(self) -> None:
        spinner = "|/-\\"
        i = 0
        while not self._stop.wait(self.interval_s):
            i += 1
            self._write(f"\r  {spinner[i % 4]} {self.compiled} kernels compiled, "
                        f"{self.elapsed_s:.0f} s{f' (now: {self.current})' if self.current else ''}"
                        "\x1b[K")

    @property
    def elapsed_s(self) -> float:
        return 0.0 if self.t0 is None else time.monotonic() - self.t0

    def close(self) -> None:
        """Stop the ticker and print the summary line (only if anything compiled)."""
        self._stop.set()
        if self._ticker is not None:
            self._ticker.join()
            self._write("\r\x1b[K")
        if self.t0 is not None:
            n = self.compiled
            what = f"{n} kernel{'' if n == 1 else 's'}"
            if self.builds:
                what += f" and {len(self.builds)} solver build{'' if len(self.builds) == 1 else 's'}"
            self._write(f"asvtwin: compiled {what} in {self.elapsed_s:.0f} s; later runs load "
                        "them from the cache\n")

    def _write(self, text: str) -> None:
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):
            pass


class _Listener:
    """Adapter to numba's Listener ABC, built once numba is imported."""

    @staticmethod
    def make(progress: CompileProgress) -> Any:
        from numba.core import event

        class Listener(event.Listener):  # type: ignore[misc]
            def on_start(self, ev: Any) -> None:
                progress.notify(ev)

            def on_end(self, ev: Any) -> None:
                progress.notify(ev)

        return Listener()


class _WhenImported(importlib.abc.MetaPathFinder):
    """Run a callback right after ``numba.core.event`` has been imported."""

    def __init__(self, callback: Any) -> None:
        self.callback = callback

    def find_spec(self, name: str, path: Any, target: Any = None) -> Any:
        if name != "numba.core.event":
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(name)
        if spec is None or spec.loader is None:
            return spec
        loader = spec.loader
        original = loader.exec_module

        def exec_module(module: Any) -> None:
            original(module)
            self.callback()

        loader.exec_module = exec_module  # type: ignore[method-assign]
        return spec


@contextmanager
def compile_notice(stream: IO[str] | None = None) -> Iterator[CompileProgress]:
    """Report numba compilations inside the block (nothing if the cache is warm)."""
    progress = CompileProgress(stream)
    installed: list[Any] = []

    def install() -> None:
        from numba.core import event

        listener = _Listener.make(progress)
        event.register("numba:compile", listener)
        installed.append(listener)

    class _BuildHandler(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            progress.build(record.getMessage())

    build_logger = logging.getLogger(BUILD_LOGGER)
    handler = _BuildHandler(logging.INFO)
    build_logger.addHandler(handler)
    old_level = build_logger.level
    build_logger.setLevel(logging.INFO)
    hook = None
    if "numba.core.event" in sys.modules:
        install()
    else:
        hook = _WhenImported(install)
        sys.meta_path.insert(0, hook)
    try:
        yield progress
    finally:
        build_logger.removeHandler(handler)
        build_logger.setLevel(old_level)
        if hook is not None and hook in sys.meta_path:
            sys.meta_path.remove(hook)
        if installed:
            from numba.core import event

            event.unregister("numba:compile", installed[0])
        progress.close()
