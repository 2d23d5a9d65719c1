// The ECDIS-style chart: MapLibre GL JS with a style made only of inline GeoJSON (no tile,
// glyph or sprite server). Everything the snapshot holds in scene NED metres is converted
// to lon/lat with the scene's exact LocalFrame port (geo.js).
//
// Drawing cost. With software WebGL (SwiftShader) every draw call fans out to the
// rasteriser's threads, so a frame costs about (draw calls) x (a thread round trip), and
// MapLibre issues one draw per layer per tile. The chart therefore keeps the draw calls
// few: every moving part is one GeoJSON source updated by one setData per snapshot, drawn
// by five layers whose colour, width and dashes come from each feature's properties
// (one fill, one line, one circle, two symbol layers); and each GeoJSON source is tiled
// at most ZOOM_DEPTH zoom levels below the view (overzoomed tiles: 1-4 cover the chart
// instead of 6-12), re-made when the user zooms past that. At ZOOM_DEPTH = 3 a tile
// coordinate (1/8192 of a tile) is 1/2 pixel on screen. Software rasterising also pays per
// pixel shaded, so the water is no layer but the CSS colour behind a transparent canvas.
import * as maplibregl from 'maplibre-gl';
import { addSymbols } from './symbols.js';
import { deg } from './geo.js';

const VECTOR_S = 360;          // COG/SOG vectors: 6 minutes ahead
const ZOOM_DEPTH = 3;          // sources tiled at most this many zoom levels below the view
// what-if ghosts: one colour per alternative (in the order of the answer)
export const GHOST_COLOURS = ['#1f5fd0', '#d4691e', '#8e3bb5', '#0f8f8f', '#b8860b', '#c2185b', '#5d4037', '#455a64'];
const EMPTY = { type: 'FeatureCollection', features: [] };
const PALETTES = {
  day: { water: '#d4eaee', land: '#d8c89a', coast: '#6b5a2e', own: '#0b0b0b', route: '#d4691e' },
  dusk: { water: '#6d8a96', land: '#8a7f5e', coast: '#3d321a', own: '#f0f0f0', route: '#f0a050' },
  night: { water: '#0b1620', land: '#2a2416', coast: '#5a4a20', own: '#b07a30', route: '#8a5020' },
};

const fc = (features) => ({ type: 'FeatureCollection', features });
const feat = (geometry, properties = {}) => ({ type: 'Feature', geometry, properties });
const line = (coords, p) => feat({ type: 'LineString', coordinates: coords }, p);
const poly = (ring, p) => feat({ type: 'Polygon', coordinates: [ring] }, p);

// A body-frame outline (x forward, y starboard) placed at p with heading psi, in NED.
function placed(outline, p, psi) {
  const c = Math.cos(psi), s = Math.sin(psi);
  return outline.map(([x, y]) => [p[0] + x * c - y * s, p[1] + x * s + y * c]);
}

function hullOutline(L, B) {
  return [[L / 2, 0], [L / 2 - B, B / 2], [-L / 2, B / 2], [-L / 2, -B / 2], [L / 2 - B, -B / 2], [L / 2, 0]];
}

// An arrow from p along NED direction angle `dir` [rad], `len` [m], with a head.
function arrow(p, dir, len) {
  const q = [p[0] + len * Math.cos(dir), p[1] + len * Math.sin(dir)];
  const h = 0.25 * len;
  const l = [q[0] - h * Math.cos(dir - 0.4), q[1] - h * Math.sin(dir - 0.4)];
  const r = [q[0] - h * Math.cos(dir + 0.4), q[1] - h * Math.sin(dir + 0.4)];
  return [p, q, l, q, r];
}

// The prediction cone of one track: the centreline offset left and right by the 2-sigma
// radius at each step, closed with an arc around the last step.
function cone(means, radii) {
  const n = means.length;
  if (n < 2) return null;
  let dn = means[n - 1][0] - means[0][0], de = means[n - 1][1] - means[0][1];
  const len = Math.hypot(dn, de);
  const a = len > 1e-6 ? Math.atan2(de, dn) : 0;
  const left = [], right = [];
  for (let i = 0; i < n; i++) {
    const r = radii[i] ?? 0;
    left.push([means[i][0] + r * Math.cos(a - Math.PI / 2), means[i][1] + r * Math.sin(a - Math.PI / 2)]);
    right.push([means[i][0] + r * Math.cos(a + Math.PI / 2), means[i][1] + r * Math.sin(a + Math.PI / 2)]);
  }
  const cap = [], rl = radii[n - 1] ?? 0, pl = means[n - 1];
  for (let k = 1; k < 8; k++) {
    const t = a - Math.PI / 2 + (k * Math.PI) / 8;
    cap.push([pl[0] + rl * Math.cos(t), pl[1] + rl * Math.sin(t)]);
  }
  const back = [], r0 = radii[0] ?? 0, p0 = means[0];
  for (let k = 1; k < 8; k++) {
    const t = a + Math.PI / 2 + (k * Math.PI) / 8;
    back.push([p0[0] + r0 * Math.cos(t), p0[1] + r0 * Math.sin(t)]);
  }
  const ring = [...left, ...cap, ...right.reverse(), ...back];
  ring.push(ring[0]);
  return ring;
}

function ellipseRing(c, ax, angle, k = 24) {
  const out = [];
  for (let i = 0; i <= k; i++) {
    const t = (2 * Math.PI * i) / k;
    const x = ax[0] * Math.cos(t), y = ax[1] * Math.sin(t);
    out.push([c[0] + x * Math.cos(angle) - y * Math.sin(angle), c[1] + x * Math.sin(angle) + y * Math.cos(angle)]);
  }
  return out;
}

export class Chart {
  constructor(el, scene, frame, { onClick } = {}) {
    this.frame = frame;
    this.scene = scene;
    this.stats = { updates: 0, targets: 0, cones: 0, planStages: 0, criticalStages: 0, lidarPoints: 0, ellipses: 0, ghosts: 0, loaded: false, idle: 0, renders: 0, sourceMaxzoom: null };
    this.orientation = 'north';
    this.follow = true;
    this.palette = 'day';
    this.draft = [];
    this.ghostFeats = [];
    this.last = null;
    const o = scene.origin;
    this.map = new maplibregl.Map({
      container: el,
      // no background layer: the water is the container's CSS colour showing through the
      // transparent canvas (a full-screen quad less for the software rasteriser per frame)
      style: { version: 8, sources: {}, layers: [] },
      center: [o.lon_deg, o.lat_deg], zoom: 13, attributionControl: false, fadeDuration: 0,
      maxPitch: 0, renderWorldCopies: false, pixelRatio: 1,
      canvasContextAttributes: { antialias: false, preserveDrawingBuffer: false },
    });
    this.map.addControl(new maplibregl.ScaleControl({ unit: 'nautical' }), 'top-right');
    this.ready = new Promise((resolve) => this.map.on('load', () => { this._setup(); resolve(); }));
    this.map.on('idle', () => { this.stats.idle += 1; });
    this.map.on('render', () => { this.stats.renders += 1; });
    this.map.on('zoomend', () => this._retile());
    this.map.on('click', (e) => onClick && onClick(frame.toNed(e.lngLat.lng, e.lngLat.lat)));
  }

  _ll(points) { return points.map((p) => this.frame.toLonLat(p[0], p[1])); }

  _wantMaxzoom() { return Math.max(0, Math.floor(this.map.getZoom()) - ZOOM_DEPTH); }

  // The layers, bottom to top. Everything that moves is in source `dyn`: its features carry
  // their own style (`fill`, `color`, `width`, `dash`, `r`, `stroke`), so one layer per
  // geometry kind draws them all.
  _layers() {
    const P = PALETTES[this.palette] || PALETTES.day;
    const dash = ['match', ['get', 'dash'], 'long', ['literal', [4, 2]], 'cog', ['literal', [4, 3]],
      'short', ['literal', [2, 2]], 'cpa', ['literal', [3, 2]], ['literal', [1, 0]]];
    return [
      { id: 'land', type: 'fill', source: 'land', paint: { 'fill-color': P.land } },
      { id: 'coast', type: 'line', source: 'land', paint: { 'line-color': P.coast, 'line-width': 1 } },
      { id: 'dyn-fill', type: 'fill', source: 'dyn', filter: ['==', ['get', 'k'], 'f'], paint: { 'fill-color': ['get', 'fill'] } },
      { id: 'dyn-line', type: 'line', source: 'dyn', filter: ['==', ['get', 'k'], 'l'], paint: { 'line-color': ['get', 'color'], 'line-width': ['get', 'width'], 'line-dasharray': dash } },
      { id: 'dyn-circle', type: 'circle', source: 'dyn', filter: ['==', ['get', 'k'], 'c'], paint: { 'circle-radius': ['get', 'r'], 'circle-color': ['get', 'fill'], 'circle-stroke-color': ['get', 'stroke'], 'circle-stroke-width': ['get', 'sw'] } },
      { id: 'targets', type: 'symbol', source: 'dyn', filter: ['==', ['get', 'k'], 's'], layout: { 'icon-image': ['get', 'icon'], 'icon-rotate': ['get', 'rot'], 'icon-rotation-alignment': 'map', 'icon-allow-overlap': true, 'icon-ignore-placement': true } },
      { id: 'labels', type: 'symbol', source: 'dyn', filter: ['==', ['get', 'k'], 's'], minzoom: 11.5, layout: { 'icon-image': ['concat', 'name:', ['get', 'name']], 'icon-anchor': 'left', 'icon-offset': [12, 0], 'icon-allow-overlap': true, 'icon-ignore-placement': true } },
      { id: 'draft', type: 'line', source: 'draft', paint: { 'line-color': '#d4691e', 'line-width': 3 } },
    ];
  }

  // (Re)make the GeoJSON sources tiled at `maxzoom` and their layers.
  _build(maxzoom) {
    const m = this.map;
    for (const l of this._layers()) if (m.getLayer(l.id)) m.removeLayer(l.id);
    for (const id of ['land', 'dyn', 'draft']) if (m.getSource(id)) m.removeSource(id);
    const src = (id, data) => m.addSource(id, { type: 'geojson', data, tolerance: 0.2, maxzoom, buffer: 64 });
    src('land', this.scene.land);
    src('dyn', this._dynData || EMPTY);
    src('draft', this.draft.length > 1 ? fc([line(this._ll(this.draft))]) : EMPTY);
    for (const l of this._layers()) m.addLayer(l);
    this.stats.sourceMaxzoom = maxzoom;
  }

  _retile() {
    if (!this.stats.loaded) return;
    const want = this._wantMaxzoom();
    if (want !== this.stats.sourceMaxzoom) this._build(want);
  }

  _setup() {
    this.map.getContainer().style.background = PALETTES[this.palette].water;
    addSymbols(this.map);
    this._build(this._wantMaxzoom());
    this.stats.loaded = true;
    document.getElementById('attribution').textContent = `Land: ${this.scene.attribution} (${this.scene.licence.split(' ').slice(0, 4).join(' ')}…)`;
  }

  setPalette(name) {
    this.palette = PALETTES[name] ? name : 'day';
    const P = PALETTES[this.palette], m = this.map;
    if (!this.stats.loaded) return;
    m.getContainer().style.background = P.water;
    m.setPaintProperty('land', 'fill-color', P.land);
    m.setPaintProperty('coast', 'line-color', P.coast);
    if (this.last) this.update(...this.last);
  }

  setDraft(points) {
    this.draft = points;
    if (!this.stats.loaded) return;
    this.map.getSource('draft').setData(fc(points.length > 1 ? [line(this._ll(points))] : []));
  }

  // What-if ghosts: each future of each alternative as a faint line in the alternative's
  // colour (red where that future collided); drawn from the next update on.
  setGhosts(answer) {
    const feats = [];
    const labels = (answer?.alternatives || []).map((a) => a.label);
    for (const g of answer?.ghosts || []) {
      const k = Math.max(0, labels.indexOf(g.alternative));
      const pos = g.positions_m || [];
      if (pos.length > 1) {
        feats.push(line(this._ll(pos), { k: 'l', color: g.collision ? 'rgba(224,20,30,0.6)' : hexA(GHOST_COLOURS[k % GHOST_COLOURS.length], 0.55), width: 2.5, dash: 'solid', alt: g.alternative }));
      }
    }
    this.ghostFeats = feats;
    this.stats.ghosts = feats.length;
    this.stats.ghostAlternatives = labels.length;
    if (this.last) this.update(...this.last);
  }

  // One snapshot (plus the targets main.js derived from it) onto the chart.
  update(s, targets) {
    this.last = [s, targets];
    if (!this.stats.loaded) return;
    const m = this.map, own = s.own, p = [own.state[0], own.state[1]], psi = own.state[2];
    const L = own.length_m || 10, B = own.beam_m || 3;
    const sog = own.sog_m_s || 0, cog = own.cog_rad ?? psi;
    const P = PALETTES[this.palette] || PALETTES.day;
    // features in drawing order within each layer: fills, then lines, then points
    const all = [];
    const ln = (pts, color, width, dash = 'solid', extra = {}) => all.push(line(this._ll(pts), { k: 'l', color, width, dash, ...extra }));
    const pt = (q, r, fill, stroke, sw) => all.push(feat({ type: 'Point', coordinates: this.frame.toLonLat(q[0], q[1]) }, { k: 'c', r, fill, stroke, sw }));
    const mpt = (qs, r, fill) => all.push(feat({ type: 'MultiPoint', coordinates: qs }, { k: 'c', r, fill, stroke: 'rgba(0,0,0,0)', sw: 0 }));

    // tracks: prediction cones ("green broadening path") and centrelines
    const tr = s.tracks;
    let nCones = 0;
    (tr.ids || []).forEach((id, i) => {
      const ring = cone(tr.pred_mean[i] || [], tr.pred_radius_m[i] || []);
      if (ring) { all.push(poly(this._ll(ring), { k: 'f', fill: 'rgba(40,170,60,0.22)' })); ln(ring, 'rgba(20,120,40,0.7)', 1); nCones += 1; }
    });
    // own ship: hull to scale (fill + outline)
    const hull = placed(hullOutline(L, B), p, psi);
    all.push(poly(this._ll(hull), { k: 'f', fill: 'rgba(255,255,255,0.4)' }));
    ln(hull, P.own, 1);
    (tr.ids || []).forEach((id, i) => { const mm = tr.pred_mean[i] || []; if (mm.length > 1) ln(mm, '#1f8a35', 1); });
    // route and past track
    const route = own.route || [];
    if (route.length) ln([p, ...route.slice(own.waypoint_index || 0)], P.route, 2, 'long');
    if ((own.past_track || []).length > 1) ln([...own.past_track, p], '#555555', 1.5);
    // what-if ghosts over the route, under the plan and the targets
    for (const g of this.ghostFeats) all.push(g);
    // fitted ellipses
    const el = s.ellipses;
    let nEll = 0;
    (el.centre || []).forEach((c, i) => { if (el.ok[i]) { ln(ellipseRing(c, el.semi_axes_m[i], el.angle_rad[i]), '#008b9a', 1.5); nEll += 1; } });
    // the safety filter's plan: green, critical stages red
    const f = s.filter, plan = f.plan || [], crit = new Set(f.critical_stages || []);
    let nPlan = 0, nCrit = 0;
    if (f.enabled) {
      for (let i = 0; i + 1 < plan.length; i++) {
        const critical = crit.has(i + 1) || crit.has(i);
        ln([plan[i], plan[i + 1]], critical ? '#e0141e' : '#1a9a2a', 5, 'solid', { critical });
        nPlan += 1; nCrit += critical ? 1 : 0;
      }
    }
    // arrows: the learner's proposal u_L (ghost) and the input let through u_0, the
    // disturbance estimate d-hat (body frame -> NED) and the wind (pointing downwind)
    const uL = f.u_L || [0, 0, 0], u0 = f.u_0 || [0, 0, 0];
    const fmax = Math.max(Math.hypot(uL[0], uL[1]), Math.hypot(u0[0], u0[1]), 1e-9);
    const bodyDir = (v) => psi + Math.atan2(v[1], v[0]);
    if (Math.hypot(uL[0], uL[1]) > 0) ln(arrow(p, bodyDir(uL), 4 * L * Math.hypot(uL[0], uL[1]) / fmax), '#888888', 2, 'short');
    if (Math.hypot(u0[0], u0[1]) > 0) ln(arrow(p, bodyDir(u0), 4 * L * Math.hypot(u0[0], u0[1]) / fmax), '#1a9a2a', 2);
    const dh = s.observer.d_hat || [0, 0, 0];
    if (Math.hypot(dh[0], dh[1]) > 0) ln(arrow(p, bodyDir(dh), 2.5 * L), '#1f5fd0', 2);
    const w = s.weather;
    if (w.wind_speed_m_s > 0 && w.wind_from_rad != null) {
      const side = [p[0] + 2 * L * Math.cos(psi + Math.PI / 2), p[1] + 2 * L * Math.sin(psi + Math.PI / 2)];
      ln(arrow(side, w.wind_from_rad + Math.PI, 2.5 * L), '#444444', 2);
    }
    // targets: vectors, CPA lines of dangerous ones, symbols along heading, names
    const v0 = [sog * Math.cos(cog), sog * Math.sin(cog)];
    let nT = 0;
    for (const t of targets) {
      if (t.vel && !t.lost) ln([t.pos, [t.pos[0] + t.vel[0] * VECTOR_S, t.pos[1] + t.vel[1] * VECTOR_S]], t.danger ? '#e0141e' : '#1c1c1c', 1.2, 'long');
      if (t.danger && t.tcpa != null) {
        const a = [p[0] + v0[0] * t.tcpa, p[1] + v0[1] * t.tcpa];
        const b = [t.pos[0] + t.vel[0] * t.tcpa, t.pos[1] + t.vel[1] * t.tcpa];
        ln([p, a, b, t.pos], '#e0141e', 1.5, 'cpa');
      }
    }
    // own ship: heading line, COG/SOG vector, position mark
    const headLen = Math.max(3 * L, 200);
    ln([p, [p[0] + headLen * Math.cos(psi), p[1] + headLen * Math.sin(psi)]], P.own, 2);
    ln([p, [p[0] + sog * VECTOR_S * Math.cos(cog), p[1] + sog * VECTOR_S * Math.sin(cog)]], P.own, 2, 'cog');
    pt(p, 7, 'rgba(0,0,0,0)', P.own, 2);
    route.forEach((wp) => pt(wp, 4, 'rgba(0,0,0,0)', P.route, 2));
    // LiDAR returns: coast grey, vessels magenta
    const pts = s.lidar.points || [], coast = s.lidar.coast || [];
    const cpts = [], vpts = [];
    pts.forEach((q, i) => (coast[i] ? cpts : vpts).push(this.frame.toLonLat(q[0], q[1])));
    if (cpts.length) mpt(cpts, 1.6, '#6a6a6a');
    if (vpts.length) mpt(vpts, 1.6, '#c01cc0');
    for (const t of targets) {
      const kind = t.source === 'lidar' ? 'radar' : 'ais';
      const icon = t.lost ? `${kind}-lost` : t.danger ? `${kind}-danger` : kind;
      all.push(feat({ type: 'Point', coordinates: this.frame.toLonLat(t.pos[0], t.pos[1]) }, { k: 's', icon, rot: deg(t.heading ?? t.cogRad ?? 0), name: t.label }));
      nT += 1;
    }
    this._dynData = fc(all);
    m.getSource('dyn').setData(this._dynData);

    // orientation: north-up, course-up or head-up, following the own ship
    const bearing = this.orientation === 'course' ? deg(cog) : this.orientation === 'head' ? deg(psi) : 0;
    if (this.follow) m.jumpTo({ center: this.frame.toLonLat(p[0], p[1]), bearing });
    else if (m.getBearing() !== bearing) m.jumpTo({ bearing });

    Object.assign(this.stats, {
      updates: this.stats.updates + 1, targets: nT, cones: nCones, planStages: nPlan, criticalStages: nCrit,
      lidarPoints: pts.length, ellipses: nEll, bearing, features: all.length,
    });
  }
}

// '#rrggbb' with an alpha -> 'rgba(r,g,b,a)'
function hexA(hex, a) {
  const n = parseInt(hex.slice(1), 16);
  return `rgba(${(n >> 16) & 255},${(n >> 8) & 255},${n & 255},${a})`;
}
