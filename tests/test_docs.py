"""Executable documentation: docstring examples and examples/*.py run in the suite."""

from __future__ import annotations

import doctest
import importlib
import pkgutil
import re
import runpy
from pathlib import Path

import pytest

import asvtwin
from asvtwin.errors import MissingExtraError

ROOT = Path(__file__).resolve().parents[1]


def _modules():
    for info in pkgutil.walk_packages(asvtwin.__path__, "asvtwin."):
        if not info.name.endswith("__main__"):
            yield info.name


@pytest.mark.parametrize("name", sorted(_modules()))
def test_docstring_examples(name):
    try:
        mod = importlib.import_module(name)
    except MissingExtraError as exc:  # an optional extra is not installed
        pytest.skip(str(exc))
    result = doctest.testmod(mod, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0


@pytest.mark.parametrize("path", sorted((ROOT / "examples").glob("*.py")), ids=lambda p: p.name)
def test_examples_run(path, capsys):
    runpy.run_path(str(path), run_name="__main__")
    assert capsys.readouterr().out.strip()


# ------------------------------------------------------------ code blocks of the docs
_FENCE = re.compile(r"^```python[ \t]*\n(.*?)^```[ \t]*$", re.DOTALL | re.MULTILINE)


def _pages() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def python_blocks(text: str) -> list[tuple[int, str]]:
    """The ```python blocks of a Markdown page with their first line numbers."""
    return [(text.count("\n", 0, m.start(1)) + 1, m.group(1)) for m in _FENCE.finditer(text)]


def test_python_blocks_are_found():
    page = "intro\n```python\nx = 1\n```\n```text\nnot code\n```\n```python\nx += 1\n```\n"
    assert python_blocks(page) == [(3, "x = 1\n"), (9, "x += 1\n")]


@pytest.mark.parametrize("page", _pages(), ids=lambda p: p.name)
def test_markdown_python_blocks_run(page, tmp_path, monkeypatch, capsys):
    """Every ```python block of README.md and docs/*.md runs, in page order, in one
    namespace per page (later blocks may use names from earlier ones), in a scratch
    directory. Blocks that are not meant to run are fenced as ```text or ```sh."""
    blocks = python_blocks(page.read_text(encoding="utf-8"))
    if not blocks:
        pytest.skip(f"{page.name} has no python blocks")
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": f"docs_{page.stem}"}
    for line, code in blocks:
        try:
            exec(compile(code, f"{page.name}:{line}", "exec"), namespace)  # noqa: S102
        except MissingExtraError as exc:
            pytest.skip(f"{page.name}:{line}: {exc}")
