"""Debian's Chromium for the browser tests and the viewer benchmark, with the faster of the
two software WebGL implementations the machine has.

Headless Chromium on a machine without a GPU draws WebGL with SwiftShader (its own CPU
rasteriser, through ANGLE's Vulkan back end). When Mesa's llvmpipe is installed (Debian's
``libgl1-mesa-dri`` and ``libegl-mesa0``), ANGLE's OpenGL-on-EGL back end can use it
instead: still software WebGL, but llvmpipe compiles shaders with LLVM and rasterises in
several threads, and fills pixels several times faster than SwiftShader (see
docs/viewer.md for the measurements). The page is still composited in software
(``--disable-gpu-compositing``): compositing through llvmpipe as well cost more per frame
than reading the WebGL canvas back.

``ASVTWIN_SOFTWARE_GL=swiftshader`` (or ``llvmpipe``) forces one (the benchmark's A/B).
When llvmpipe is asked for but the browser does not give it (no WebGL context, or another
renderer), :func:`launch` falls back to SwiftShader; the renderer actually used is
returned, read from WebGL's ``UNMASKED_RENDERER_WEBGL``.
"""

from __future__ import annotations

import glob
import os
import shutil

CHROMIUM = shutil.which("chromium")

# ANGLE on OpenGL ES through Mesa's EGL (llvmpipe, the only driver without a GPU); the GPU
# blocklist refuses llvmpipe otherwise and WebGL falls back to SwiftShader
LLVMPIPE_ARGS = ["--use-angle=gl-egl", "--ignore-gpu-blocklist", "--disable-gpu-compositing"]

RENDERER_JS = """() => {
  const gl = document.createElement('canvas').getContext('webgl');
  if (!gl) return null;
  const ext = gl.getExtension('WEBGL_debug_renderer_info');
  return ext ? gl.getParameter(ext.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
}"""


def mesa_llvmpipe_installed() -> bool:
    """Mesa's software OpenGL driver and its EGL are on the machine (any multiarch dir)."""
    return bool(glob.glob("/usr/lib/*/dri/swrast_dri.so")) and bool(
        glob.glob("/usr/lib/*/libEGL_mesa.so.0"))


def wanted_gl() -> str:
    """``llvmpipe`` or ``swiftshader``: ``ASVTWIN_SOFTWARE_GL`` if set, else llvmpipe when
    Mesa provides it."""
    forced = os.environ.get("ASVTWIN_SOFTWARE_GL", "").strip().lower()
    if forced not in ("", "llvmpipe", "swiftshader"):
        raise ValueError(f"ASVTWIN_SOFTWARE_GL={forced!r}: use 'llvmpipe' or 'swiftshader'")
    if forced:
        return forced
    return "llvmpipe" if mesa_llvmpipe_installed() else "swiftshader"


def webgl_renderer(browser) -> str | None:
    """The WebGL renderer string of ``browser`` (a Playwright Browser), from a blank page."""
    page = browser.new_page()
    try:
        page.goto("about:blank")
        return page.evaluate(RENDERER_JS)
    finally:
        page.close()


def launch(pw, gl: str | None = None, **kwargs):
    """Launch Debian's Chromium (never a downloaded browser) with the software WebGL ``gl``
    (default :func:`wanted_gl`). Returns ``(browser, renderer)``; falls back to SwiftShader
    when llvmpipe was wanted and the browser's WebGL is not llvmpipe."""
    if CHROMIUM is None:
        raise RuntimeError("Debian's chromium is not installed (apt-get install chromium)")
    gl = gl or wanted_gl()
    if gl == "llvmpipe":
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=LLVMPIPE_ARGS, **kwargs)
        renderer = webgl_renderer(browser)
        if renderer and "llvmpipe" in renderer:
            return browser, renderer
        browser.close()
    browser = pw.chromium.launch(executable_path=CHROMIUM, **kwargs)
    return browser, webgl_renderer(browser)
