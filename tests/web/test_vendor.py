"""The vendored JavaScript matches its manifest (offline): every file's sha256, the pinned
versions, the licences; and the page loads nothing from outside the package."""

from __future__ import annotations

import importlib.util
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
WEB = ROOT / "asvtwin" / "web"


def _tool():
    spec = importlib.util.spec_from_file_location("vendor_js", ROOT / "tools" / "vendor_js.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def test_vendored_files_match_the_manifest():
    tool = _tool()
    assert tool.check() == []
    manifest = json.loads((WEB / "vendor" / "manifest.json").read_text())
    by_name = {p["name"]: p for p in manifest["packages"]}
    assert by_name["maplibre-gl"]["licence"] == "BSD-3-Clause"
    assert by_name["three"]["licence"] == "MIT"
    for p in manifest["packages"]:
        assert p["integrity"].startswith("sha512-")
        assert (WEB / "vendor" / p["name"] / p["licence_file"]).stat().st_size > 500


def test_a_changed_file_is_caught(tmp_path, monkeypatch):
    tool = _tool()
    fake = tmp_path / "vendor"
    for src in (WEB / "vendor").rglob("*"):
        if src.is_file():
            dst = fake / src.relative_to(WEB / "vendor")
            dst.parent.mkdir(parents=True, exist_ok=True)
            dst.write_bytes(src.read_bytes())
    (fake / "three" / "three.module.js").write_text("// tampered\n")
    monkeypatch.setattr(tool, "VENDOR", fake)
    monkeypatch.setattr(tool, "MANIFEST", fake / "manifest.json")
    problems = tool.check()
    assert len(problems) == 1 and "three.module.js" in problems[0]


def test_the_page_references_only_its_own_files():
    text = "\n".join(p.read_text() for p in [WEB / "index.html", *sorted((WEB / "js").glob("*.js")),
                                             WEB / "css" / "viewer.css"])
    assert not re.search(r"https?://(?!127\.0\.0\.1)", text), "an absolute URL in the viewer"
    assert "cdn" not in text.lower()
