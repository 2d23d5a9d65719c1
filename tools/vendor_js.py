"""Vendor the viewer's JavaScript from the npm registry at pinned versions.

The browser viewer (``asvtwin/web``) must work with no network: no CDN, no bundler, and no
npm step on CI. This script fetches each pinned package's tarball with the ordinary npm
client (``npm pack NAME@VERSION``), checks the tarball against the registry's integrity
hash (``npm view NAME@VERSION dist.integrity``, Subresource-Integrity form ``sha512-...``),
and copies the few files the viewer loads plus the package's licence into
``asvtwin/web/vendor/NAME/``. A manifest ``asvtwin/web/vendor/manifest.json`` records, per
package, its name, version, licence, integrity and the sha256 of every copied file.

Usage::

    python tools/vendor_js.py           # fetch, verify and (re)write asvtwin/web/vendor/
    python tools/vendor_js.py --check   # offline: verify the vendored files against the manifest

Only ``--check`` runs in the test suite (no network); the vendored files are committed.
"""

from __future__ import annotations

import argparse
import base64
import hashlib
import json
import shutil
import subprocess
import sys
import tarfile
import tempfile
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
VENDOR = ROOT / "asvtwin" / "web" / "vendor"
MANIFEST = VENDOR / "manifest.json"


@dataclass(frozen=True)
class Pin:
    """One npm package at a pinned version and the files the viewer loads from it."""

    name: str
    version: str
    licence: str  # SPDX identifier, checked against the package.json
    files: tuple[str, ...]  # paths inside the tarball's ``package/`` folder
    licence_file: str


PINS = (
    Pin(
        "maplibre-gl",
        "6.17.0",
        "BSD-3-Clause",
        (
            "dist/maplibre-gl.mjs",
            "dist/maplibre-gl-worker.mjs",  # loaded by the main module from beside itself
            "dist/maplibre-gl-shared.mjs",
            "dist/maplibre-gl.css",
        ),
        "LICENSE.txt",
    ),
    Pin(
        "three",
        "0.187.0",
        "MIT",
        ("build/three.module.js", "build/three.core.js"),
        "LICENSE",
    ),
)


def sha256_file(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def sri_sha512(data: bytes) -> str:
    """The Subresource-Integrity string ``sha512-<base64>`` of ``data``."""
    return "sha512-" + base64.b64encode(hashlib.sha512(data).digest()).decode("ascii")


def _npm(*args: str, cwd: Path | None = None) -> str:
    npm = shutil.which("npm")
    if npm is None:
        raise SystemExit("vendor_js: `npm` is not on PATH (only needed to re-vendor; --check is offline)")
    out = subprocess.run([npm, *args], cwd=cwd, check=True, capture_output=True, text=True)
    return out.stdout


def _strip_source_map(data: bytes) -> bytes:
    """Drop the trailing ``//# sourceMappingURL=`` line: the maps are not vendored, and a
    browser with developer tools open would otherwise request a missing file."""
    lines = data.rstrip(b"\n").split(b"\n")
    if lines and lines[-1].startswith(b"//# sourceMappingURL="):
        lines = lines[:-1]
    return b"\n".join(lines) + b"\n"


def vendor(pin: Pin, work: Path) -> dict[str, object]:
    """Fetch, verify and copy one package; returns its manifest entry."""
    spec = f"{pin.name}@{pin.version}"
    expected = json.loads(_npm("view", spec, "dist.integrity", "--json"))
    packed = json.loads(_npm("pack", spec, "--json", "--pack-destination", str(work), cwd=work))
    tgz = work / packed[0]["filename"]
    actual = sri_sha512(tgz.read_bytes())
    if actual != expected:
        raise SystemExit(f"vendor_js: {spec}: integrity mismatch: registry {expected}, tarball {actual}")
    dest = VENDOR / pin.name
    if dest.exists():
        shutil.rmtree(dest)
    dest.mkdir(parents=True)
    files: dict[str, str] = {}
    with tarfile.open(tgz) as tar:
        meta = json.load(tar.extractfile("package/package.json"))  # type: ignore[arg-type]
        if meta.get("version") != pin.version or meta.get("license") != pin.licence:
            raise SystemExit(
                f"vendor_js: {spec}: package.json says version {meta.get('version')!r}, "
                f"licence {meta.get('license')!r}; expected {pin.version!r}, {pin.licence!r}"
            )
        for rel in (*pin.files, pin.licence_file):
            member = tar.extractfile(f"package/{rel}")
            if member is None:
                raise SystemExit(f"vendor_js: {spec}: no file {rel!r} in the tarball")
            data = member.read()
            if rel.endswith((".js", ".mjs")):
                data = _strip_source_map(data)
            out = dest / Path(rel).name
            out.write_bytes(data)
            files[out.name] = sha256_file(out)
    return {
        "name": pin.name,
        "version": pin.version,
        "licence": pin.licence,
        "licence_file": Path(pin.licence_file).name,
        "integrity": expected,
        "tarball": f"{pin.name}-{pin.version}.tgz",
        "files": files,
    }


def check() -> list[str]:
    """Problems found comparing ``asvtwin/web/vendor`` with its manifest (empty: all good)."""
    if not MANIFEST.exists():
        return [f"{MANIFEST} is missing: run tools/vendor_js.py"]
    manifest = json.loads(MANIFEST.read_text())
    problems: list[str] = []
    pinned = {(p.name, p.version) for p in PINS}
    listed = {(e["name"], e["version"]) for e in manifest["packages"]}
    if pinned != listed:
        problems.append(f"manifest lists {sorted(listed)}, the pins are {sorted(pinned)}")
    for entry in manifest["packages"]:
        for fname, digest in entry["files"].items():
            path = VENDOR / entry["name"] / fname
            if not path.exists():
                problems.append(f"{path} is missing")
            elif sha256_file(path) != digest:
                problems.append(f"{path}: sha256 differs from the manifest")
        if entry["licence_file"] not in entry["files"]:
            problems.append(f"{entry['name']}: licence file not vendored")
    return problems


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="verify offline against the manifest")
    args = ap.parse_args(argv)
    if args.check:
        problems = check()
        for p in problems:
            print(p, file=sys.stderr)
        print("vendored files match the manifest" if not problems else f"{len(problems)} problem(s)")
        return 1 if problems else 0
    VENDOR.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        entries = [vendor(pin, Path(tmp)) for pin in PINS]
    manifest = {
        "about": "JavaScript vendored from the npm registry by tools/vendor_js.py; "
        "integrity is the registry's hash of the tarball, files the sha256 of each copy.",
        "packages": entries,
    }
    MANIFEST.write_text(json.dumps(manifest, indent=2) + "\n")
    total = sum((VENDOR / e["name"] / f).stat().st_size for e in entries for f in e["files"])  # type: ignore[attr-defined]
    print(f"vendored {len(entries)} packages, {total / 1e6:.2f} MB, manifest {MANIFEST.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
