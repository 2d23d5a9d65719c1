// Everything on the chart that moves, drawn by one MapLibre custom layer (WebGL2) instead of
// GeoJSON sources: a snapshot fills a few typed arrays on the main thread and uploads them
// as four buffers; nothing is sent to MapLibre's worker, nothing is re-tiled, and a frame
// is five draw calls whatever the number of targets.
//
// Why: with a GeoJSON source, each snapshot of 200 targets (~2,000 features) was cloned to
// MapLibre's worker, cut into tiles, turned into buckets and sent back, and every frame drew
// each layer once per tile; with software WebGL that was a large share of the browser's CPU
// per frame (docs/viewer.md). Here geometry stays in (Web) Mercator coordinates relative to
// the scene's origin (float32 is then exact to well under a millimetre), the matrix is
// offset to that origin in float64, and line widths, circle radii, symbols and labels are
// expanded to pixels in the vertex shaders, so panning, zooming and turning the chart need
// no rebuild.
//
// Programs: `fill` (triangles, premultiplied RGBA per vertex), `line` (one instance per
// segment: a screen-space quad of the segment's width, dashes by distance along the line in
// units of the width, as MapLibre's line-dasharray), `circle` (one instance per point: fill
// and stroke ring), `sprite` (one instance per symbol or label: a quad textured from a
// canvas atlas; symbols turn with the chart's bearing, labels stay upright).

const DASHES = { solid: [1, 0], long: [4, 2], cog: [4, 3], short: [2, 2], cpa: [3, 2] };
const DASH_IDS = Object.fromEntries(Object.keys(DASHES).map((k, i) => [k, i]));

// CSS colour ('#rrggbb' or 'rgba(r,g,b,a)') -> premultiplied RGBA bytes, cached
const COLOURS = new Map();
export function rgba(css) {
  let c = COLOURS.get(css);
  if (c) return c;
  let r, g, b, a = 1;
  if (css[0] === '#') {
    const n = parseInt(css.slice(1), 16);
    [r, g, b] = [(n >> 16) & 255, (n >> 8) & 255, n & 255];
  } else {
    const m = css.match(/rgba?\(([^)]*)\)/);
    if (!m) throw new Error(`colour ${css}: use #rrggbb or rgba(r,g,b,a)`);
    [r, g, b, a = 1] = m[1].split(',').map(Number);
  }
  c = [Math.round(r * a), Math.round(g * a), Math.round(b * a), Math.round(255 * a)];
  COLOURS.set(css, c);
  return c;
}

// Web Mercator [0, 1] x [0, 1] of lon/lat [deg] (MapLibre's MercatorCoordinate)
function mercator(lon, lat) {
  const y = Math.log(Math.tan(Math.PI / 4 + (lat * Math.PI) / 360));
  return [(lon + 180) / 360, 0.5 - y / (2 * Math.PI)];
}

// A growable interleaved buffer: float32 attributes and RGBA bytes sharing one ArrayBuffer.
class Interleaved {
  constructor(floats, bytes) {
    this.stride = 4 * floats + bytes;   // bytes per item
    this.floats = floats;
    this.n = 0;
    this._alloc(256);
  }

  _alloc(cap) {
    const buf = new ArrayBuffer(cap * this.stride);
    if (this.u8) new Uint8Array(buf).set(this.u8.subarray(0, this.n * this.stride));
    this.cap = cap;
    this.f32 = new Float32Array(buf);
    this.u8 = new Uint8Array(buf);
  }

  // the float offset and byte offset of a new item
  push() {
    if (this.n === this.cap) this._alloc(this.cap * 2);
    const i = this.n++;
    return i * this.stride;
  }

  bytes() { return this.u8.subarray(0, this.n * this.stride); }
}

const VS_PRELUDE = `#version 300 es
precision highp float;
uniform mat4 u_matrix;      // relative Mercator -> clip
uniform vec2 u_viewport;    // drawing buffer [px]
uniform float u_world;      // pixels per Mercator unit
uniform float u_bearing;    // the chart's bearing [rad]
vec2 toPx(vec4 clip) { return clip.xy / clip.w * 0.5 * u_viewport; }
vec4 offsetPx(vec4 clip, vec2 px) { return clip + vec4(px * 2.0 / u_viewport * clip.w, 0.0, 0.0); }
`;

const PROGRAMS = {
  fill: {
    vs: `${VS_PRELUDE}
in vec2 a_pos; in vec4 a_color; out vec4 v_color;
void main() { v_color = a_color; gl_Position = u_matrix * vec4(a_pos, 0.0, 1.0); }`,
    fs: `#version 300 es
precision mediump float; in vec4 v_color; out vec4 o;
void main() { o = v_color; }`,
  },
  line: {
    vs: `${VS_PRELUDE}
in vec2 a_corner;                 // (t along the segment 0..1, side -1..1), per vertex
in vec2 a_a; in vec2 a_b; in vec4 a_color; in vec3 a_wdd;   // width px, distance at a, dash id
uniform vec2 u_dash[${Object.keys(DASHES).length}];
out vec4 v_color; out float v_dist; out vec2 v_dash;
void main() {
  vec4 ca = u_matrix * vec4(a_a, 0.0, 1.0), cb = u_matrix * vec4(a_b, 0.0, 1.0);
  vec2 d = toPx(cb) - toPx(ca);
  float len = length(d);
  vec2 dir = len > 1e-6 ? d / len : vec2(1.0, 0.0);
  float w = a_wdd.x;
  // square caps of half the width: consecutive segments overlap at their joints
  float t = a_corner.x;
  vec2 px = vec2(-dir.y, dir.x) * a_corner.y * 0.5 * max(w, 1.0) + dir * (t * 2.0 - 1.0) * 0.5 * w;
  gl_Position = offsetPx(mix(ca, cb, t), px);
  v_color = a_color;
  v_dist = (a_wdd.y + t * length(a_b - a_a)) * u_world / max(w, 1.0) + (t * 2.0 - 1.0) * 0.5;
  v_dash = u_dash[int(a_wdd.z + 0.5)];
}`,
    fs: `#version 300 es
precision mediump float; in vec4 v_color; in float v_dist; in vec2 v_dash; out vec4 o;
void main() {
  if (v_dash.y > 0.0 && mod(v_dist, v_dash.x + v_dash.y) > v_dash.x) discard;
  o = v_color;
}`,
  },
  circle: {
    vs: `${VS_PRELUDE}
in vec2 a_corner; in vec2 a_pos; in vec2 a_rs; in vec4 a_fill; in vec4 a_stroke;   // radius, stroke px
out vec2 v_xy; out vec2 v_rs; out vec4 v_fill; out vec4 v_stroke;
void main() {
  float ext = a_rs.x + a_rs.y + 1.0;
  v_xy = a_corner * ext; v_rs = a_rs; v_fill = a_fill; v_stroke = a_stroke;
  gl_Position = offsetPx(u_matrix * vec4(a_pos, 0.0, 1.0), v_xy);
}`,
    fs: `#version 300 es
precision mediump float; in vec2 v_xy; in vec2 v_rs; in vec4 v_fill; in vec4 v_stroke; out vec4 o;
void main() {
  float d = length(v_xy);
  if (d > v_rs.x + v_rs.y) discard;
  o = d > v_rs.x ? v_stroke : v_fill;
  if (o.a == 0.0) discard;
}`,
  },
  sprite: {
    vs: `${VS_PRELUDE}
in vec2 a_corner;                                   // -1..1
in vec2 a_pos; in vec4 a_offsize; in vec4 a_uv; in vec2 a_rot;   // (x, y, w/2, h/2) px; uv rect; (angle, turns with the map)
out vec2 v_uv;
void main() {
  float th = a_rot.y > 0.5 ? a_rot.x - u_bearing : 0.0;   // clockwise on screen
  vec2 q = a_corner * a_offsize.zw;
  vec2 r = vec2(q.x * cos(th) + q.y * sin(th), -q.x * sin(th) + q.y * cos(th));
  v_uv = mix(a_uv.xy, a_uv.zw, a_corner * vec2(0.5, -0.5) + 0.5);
  gl_Position = offsetPx(u_matrix * vec4(a_pos, 0.0, 1.0), a_offsize.xy + r);
}`,
    fs: `#version 300 es
precision mediump float; uniform sampler2D u_tex; in vec2 v_uv; out vec4 o;
void main() { o = texture(u_tex, v_uv); if (o.a < 0.02) discard; }`,
  },
};

// per-instance attributes: [name, size, type] (type 'f' float32, 'b' normalized bytes)
const LAYOUT = {
  fill: [['a_pos', 2, 'f'], ['a_color', 4, 'b']],
  line: [['a_a', 2, 'f'], ['a_b', 2, 'f'], ['a_wdd', 3, 'f'], ['a_color', 4, 'b']],
  circle: [['a_pos', 2, 'f'], ['a_rs', 2, 'f'], ['a_fill', 4, 'b'], ['a_stroke', 4, 'b']],
  sprite: [['a_pos', 2, 'f'], ['a_offsize', 4, 'f'], ['a_uv', 4, 'f'], ['a_rot', 2, 'f']],
};
const CORNERS = {   // per-vertex corners of the instanced quads (two triangles)
  line: [0, -1, 1, -1, 1, 1, 0, -1, 1, 1, 0, 1],
  quad: [-1, -1, 1, -1, 1, 1, -1, -1, 1, 1, -1, 1],
};

export class ChartLayer {
  // frame: the scene's LocalFrame (NED <-> lon/lat); atlas: a SymbolAtlas (symbols.js)
  constructor(frame, atlas, id = 'dyn') {
    this.id = id;
    this.type = 'custom';
    this.renderingMode = '2d';
    this.frame = frame;
    this.atlas = atlas;
    this.origin = mercator(frame.lon0, frame.lat0);
    this.bufs = {};
    for (const [k, attrs] of Object.entries(LAYOUT)) {
      const floats = attrs.filter((a) => a[2] === 'f').reduce((s, a) => s + a[1], 0);
      const bytes = attrs.filter((a) => a[2] === 'b').reduce((s, a) => s + a[1], 0);
      this.bufs[k] = new Interleaved(floats, bytes);
    }
    this.tags = [];         // lines with a tag (what-if ghosts): {tag, color}, for tests
    this.stats = { draws: 0, uploads: 0, fillVertices: 0, lines: 0, circles: 0, sprites: 0 };
    this.dirty = false;
  }

  // ---- building a snapshot's geometry (NED metres in, relative Mercator out) ----
  begin() {
    for (const b of Object.values(this.bufs)) b.n = 0;
    this.tags = [];
  }

  m(p) {
    const [lon, lat] = this.frame.toLonLat(p[0], p[1]);
    const [x, y] = mercator(lon, lat);
    return [x - this.origin[0], y - this.origin[1]];
  }

  // triangles: NED points, every three one triangle
  fill(tris, css) {
    const c = rgba(css), b = this.bufs.fill;
    for (const p of tris) {
      const o = b.push(), q = this.m(p);
      b.f32[o / 4] = q[0]; b.f32[o / 4 + 1] = q[1];
      b.u8.set(c, o + 8);
    }
  }

  line(pts, css, width, dash = 'solid', tag = null) {
    if (pts.length < 2) return;
    const c = rgba(css), b = this.bufs.line, di = DASH_IDS[dash] ?? 0;
    let prev = this.m(pts[0]), dist = 0;
    for (let i = 1; i < pts.length; i++) {
      const q = this.m(pts[i]), o = b.push() / 4;
      const f = b.f32;
      f[o] = prev[0]; f[o + 1] = prev[1]; f[o + 2] = q[0]; f[o + 3] = q[1];
      f[o + 4] = width; f[o + 5] = dist; f[o + 6] = di;
      b.u8.set(c, 4 * o + 28);
      dist += Math.hypot(q[0] - prev[0], q[1] - prev[1]);
      prev = q;
    }
    if (tag !== null) this.tags.push({ tag, color: css });
  }

  circle(p, r, fill, stroke, sw) {
    const b = this.bufs.circle, o = b.push(), q = this.m(p);
    b.f32[o / 4] = q[0]; b.f32[o / 4 + 1] = q[1]; b.f32[o / 4 + 2] = r; b.f32[o / 4 + 3] = sw;
    b.u8.set(rgba(fill), o + 16); b.u8.set(rgba(stroke), o + 20);
  }

  // an atlas image at p: offset [px, screen right/up] of the image's centre, turned by
  // `rot` [rad, clockwise from north] with the chart when `withMap`, else upright
  sprite(p, name, { dx = 0, dy = 0, rot = 0, withMap = true } = {}) {
    const img = this.atlas.get(name);
    const b = this.bufs.sprite, o = b.push() / 4, q = this.m(p), f = b.f32;
    f[o] = q[0]; f[o + 1] = q[1];
    f[o + 2] = dx; f[o + 3] = dy; f[o + 4] = img.w / 2; f[o + 5] = img.h / 2;
    f[o + 6] = img.uv[0]; f[o + 7] = img.uv[1]; f[o + 8] = img.uv[2]; f[o + 9] = img.uv[3];
    f[o + 10] = rot; f[o + 11] = withMap ? 1 : 0;
    return img;
  }

  end() {
    this.dirty = true;
    const B = this.bufs;
    Object.assign(this.stats, { fillVertices: B.fill.n, lines: B.line.n, circles: B.circle.n, sprites: B.sprite.n });
    if (this.map) this.map.triggerRepaint();
  }

  // ---- MapLibre's CustomLayerInterface ----
  onAdd(map, gl) {
    this.map = map;
    if (this.gl === gl) { this.dirty = true; return; }   // re-added after a rebuild of the style
    if (!(gl instanceof WebGL2RenderingContext)) throw new Error('the chart needs WebGL2');
    this.gl = gl;
    this.progs = {};
    for (const [k, src] of Object.entries(PROGRAMS)) {
      const p = gl.createProgram();
      for (const [type, text] of [[gl.VERTEX_SHADER, src.vs], [gl.FRAGMENT_SHADER, src.fs]]) {
        const s = gl.createShader(type);
        gl.shaderSource(s, text); gl.compileShader(s);
        if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(`${k} shader: ${gl.getShaderInfoLog(s)}`);
        gl.attachShader(p, s);
      }
      gl.linkProgram(p);
      if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(`${k} program: ${gl.getProgramInfoLog(p)}`);
      const u = {};
      for (const name of ['u_matrix', 'u_viewport', 'u_world', 'u_bearing', 'u_dash', 'u_tex']) u[name] = gl.getUniformLocation(p, name);
      const vao = gl.createVertexArray(), buf = gl.createBuffer();
      gl.bindVertexArray(vao);
      const instanced = k !== 'fill';
      if (instanced) {
        const cb = gl.createBuffer();
        gl.bindBuffer(gl.ARRAY_BUFFER, cb);
        gl.bufferData(gl.ARRAY_BUFFER, new Float32Array(k === 'line' ? CORNERS.line : CORNERS.quad), gl.STATIC_DRAW);
        const loc = gl.getAttribLocation(p, 'a_corner');
        gl.enableVertexAttribArray(loc);
        gl.vertexAttribPointer(loc, 2, gl.FLOAT, false, 0, 0);
      }
      gl.bindBuffer(gl.ARRAY_BUFFER, buf);
      const stride = this.bufs[k].stride;
      let fo = 0, bo = 4 * this.bufs[k].floats;
      for (const [name, size, type] of LAYOUT[k]) {
        const loc = gl.getAttribLocation(p, name);
        if (loc < 0) throw new Error(`${k}: attribute ${name} unused`);
        gl.enableVertexAttribArray(loc);
        if (type === 'f') { gl.vertexAttribPointer(loc, size, gl.FLOAT, false, stride, fo); fo += 4 * size; }
        else { gl.vertexAttribPointer(loc, size, gl.UNSIGNED_BYTE, true, stride, bo); bo += size; }
        if (instanced) gl.vertexAttribDivisor(loc, 1);
      }
      gl.bindVertexArray(null);
      this.progs[k] = { p, u, vao, buf };
    }
    this.tex = gl.createTexture();
    this.atlasVersion = -1;
    this.dirty = true;
  }

  onRemove() { this.map = null; }

  _upload(gl) {
    for (const [k, pr] of Object.entries(this.progs)) {
      gl.bindBuffer(gl.ARRAY_BUFFER, pr.buf);
      gl.bufferData(gl.ARRAY_BUFFER, this.bufs[k].bytes(), gl.DYNAMIC_DRAW);
    }
    if (this.atlas.version !== this.atlasVersion) {
      gl.bindTexture(gl.TEXTURE_2D, this.tex);
      gl.pixelStorei(gl.UNPACK_PREMULTIPLY_ALPHA_WEBGL, true);
      gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA, gl.RGBA, gl.UNSIGNED_BYTE, this.atlas.canvas);
      gl.pixelStorei(gl.UNPACK_PREMULTIPLY_ALPHA_WEBGL, false);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
      this.atlasVersion = this.atlas.version;
    }
    this.dirty = false;
    this.stats.uploads += 1;
  }

  render(gl, args) {
    if (this.dirty) this._upload(gl);
    // MapLibre's view-projection takes world pixels (Mercator x world size); moved to the
    // scene's origin and scaled to Mercator units in float64, then handed over as float32
    const M = args.modelViewProjectionMatrix, [tx, ty] = this.origin;
    const W = 512 * 2 ** this.map.getZoom();
    const m = new Float32Array(16);
    for (let r = 0; r < 4; r++) {
      m[r] = M[r] * W; m[4 + r] = M[4 + r] * W; m[8 + r] = M[8 + r];
      m[12 + r] = (M[r] * tx + M[4 + r] * ty) * W + M[12 + r];
    }
    const world = W * (this.map.getPixelRatio?.() || 1);
    const vp = [gl.drawingBufferWidth, gl.drawingBufferHeight];
    const bearing = (this.map.getBearing() * Math.PI) / 180;
    gl.disable(gl.DEPTH_TEST); gl.disable(gl.STENCIL_TEST); gl.disable(gl.CULL_FACE);
    gl.enable(gl.BLEND); gl.blendFunc(gl.ONE, gl.ONE_MINUS_SRC_ALPHA);
    const draw = (k, mode, count, instances) => {
      if (!instances) return;
      const pr = this.progs[k];
      gl.useProgram(pr.p);
      gl.uniformMatrix4fv(pr.u.u_matrix, false, m);
      gl.uniform2fv(pr.u.u_viewport, vp);
      gl.uniform1f(pr.u.u_world, world);
      gl.uniform1f(pr.u.u_bearing, bearing);
      if (pr.u.u_dash) gl.uniform2fv(pr.u.u_dash, Object.values(DASHES).flat());
      if (pr.u.u_tex) { gl.activeTexture(gl.TEXTURE0); gl.bindTexture(gl.TEXTURE_2D, this.tex); gl.uniform1i(pr.u.u_tex, 0); }
      gl.bindVertexArray(pr.vao);
      if (k === 'fill') gl.drawArrays(mode, 0, count);
      else gl.drawArraysInstanced(mode, 0, count, instances);
      this.stats.draws += 1;
    };
    const B = this.bufs;
    draw('fill', gl.TRIANGLES, B.fill.n, B.fill.n);
    draw('line', gl.TRIANGLES, 6, B.line.n);
    draw('circle', gl.TRIANGLES, 6, B.circle.n);
    draw('sprite', gl.TRIANGLES, 6, B.sprite.n);
    gl.bindVertexArray(null);
  }
}
