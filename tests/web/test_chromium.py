"""The headless browser's software WebGL (tests/web/chromium.py): llvmpipe when Mesa has
it, SwiftShader otherwise or when asked, and both draw the same pixels."""

from __future__ import annotations

import pytest

from tests.web.chromium import CHROMIUM, launch, mesa_llvmpipe_installed, wanted_gl

playwright = pytest.importorskip("playwright.sync_api")

# a WebGL page: clear to one colour, fill the lower-left triangle with another, read back
# a pixel of each half
DRAW = """() => {
  const c = document.createElement('canvas'); c.width = 64; c.height = 64;
  const gl = c.getContext('webgl', {antialias: false});
  const sh = (type, src) => { const s = gl.createShader(type); gl.shaderSource(s, src); gl.compileShader(s); return s; };
  const p = gl.createProgram();
  gl.attachShader(p, sh(gl.VERTEX_SHADER, 'attribute vec2 a; void main() { gl_Position = vec4(a, 0.0, 1.0); }'));
  gl.attachShader(p, sh(gl.FRAGMENT_SHADER, 'precision mediump float; void main() { gl_FragColor = vec4(0.2, 0.6, 1.0, 1.0); }'));
  gl.linkProgram(p); gl.useProgram(p);
  gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 1, -1, -1, 1]), gl.STATIC_DRAW);
  gl.enableVertexAttribArray(0); gl.vertexAttribPointer(0, 2, gl.FLOAT, false, 0, 0);
  gl.clearColor(1.0, 0.5, 0.0, 1.0); gl.clear(gl.COLOR_BUFFER_BIT);
  gl.drawArrays(gl.TRIANGLES, 0, 3);
  const px = (x, y) => { const b = new Uint8Array(4); gl.readPixels(x, y, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, b); return Array.from(b); };
  return {inside: px(8, 8), outside: px(56, 56)};
}"""


def drawn(gl: str) -> tuple[str, dict]:
    with playwright.sync_playwright() as pw:
        browser, renderer = launch(pw, gl)
        try:
            page = browser.new_page()
            page.goto("about:blank")
            return renderer, page.evaluate(DRAW)
        finally:
            browser.close()


def test_a_bad_choice_is_refused(monkeypatch):
    monkeypatch.setenv("ASVTWIN_SOFTWARE_GL", "vulkan")
    with pytest.raises(ValueError, match="vulkan"):
        wanted_gl()
    monkeypatch.setenv("ASVTWIN_SOFTWARE_GL", "SwiftShader")
    assert wanted_gl() == "swiftshader"
    monkeypatch.delenv("ASVTWIN_SOFTWARE_GL")
    assert wanted_gl() == ("llvmpipe" if mesa_llvmpipe_installed() else "swiftshader")


@pytest.mark.skipif(CHROMIUM is None, reason="Debian's chromium is not installed")
def test_both_software_webgl_draw_the_same_pixels():
    renderer, px = drawn("swiftshader")
    assert "SwiftShader" in renderer
    assert px == {"inside": [51, 153, 255, 255], "outside": [255, 128, 0, 255]}
    if not mesa_llvmpipe_installed():
        pytest.skip("Mesa's llvmpipe is not installed (libgl1-mesa-dri, libegl-mesa0)")
    renderer, px_llvm = drawn("llvmpipe")
    assert "llvmpipe" in renderer  # not silently SwiftShader again
    assert px_llvm == px
