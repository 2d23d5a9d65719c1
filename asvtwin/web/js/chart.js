// The ECDIS-style chart: MapLibre GL JS with a style made only of inline GeoJSON (no tile,
// glyph or sprite server). Everything the snapshot holds in scene NED metres is converted
// to lon/lat with the scene's exact LocalFrame port (geo.js).
//
// Drawing cost. The land is a GeoJSON source tiled once (at most ZOOM_DEPTH zoom levels
// below the view: 1-4 overzoomed tiles cover the chart instead of 6-12; re-made when the
// user zooms past that), drawn by two layers. Everything that moves (targets and their
// vectors and names, cones, ellipses, LiDAR points, the plan, arrows, ghosts) is drawn by
// one WebGL custom layer (chartlayer.js) from typed arrays filled per snapshot: no GeoJSON,
// no worker re-tiling, five draw calls per frame. Software rasterising pays per pixel
// shaded, so the water is no layer but the CSS colour behind a transparent canvas.
// Declutter: names are shown for the LABELS nearest targets and every dangerous one (an
// ECDIS shows target labels selectively; all 200 names over each other help nobody).
import * as maplibregl from 'maplibre-gl';
import { SymbolAtlas } from './symbols.js';
import { ChartLayer } from './chartlayer.js';
import { deg } from './geo.js';

const VECTOR_S = 360;          // COG/SOG vectors: 6 minutes ahead
const ZOOM_DEPTH = 3;          // sources tiled at most this many zoom levels below the view
const LABELS = 20;             // names shown: the nearest targets, and all dangerous ones
const LABEL_MINZOOM = 11.5;    // no names when zoomed out further
// what-if ghosts: one colour per alternative (in the order of the answer)
export const GHOST_COLOURS = ['#1f5fd0', '#d4691e', '#8e3bb5', '#0f8f8f', '#b8860b', '#c2185b', '#5d4037', '#455a64'];
const PALETTES = {
  day: { water: '#d4eaee', land: '#d8c89a', coast: '#6b5a2e', own: '#0b0b0b', route: '#d4691e' },
  dusk: { water: '#6d8a96', land: '#8a7f5e', coast: '#3d321a', own: '#f0f0f0', route: '#f0a050' },
  night: { water: '#0b1620', land: '#2a2416', coast: '#5a4a20', own: '#b07a30', route: '#8a5020' },
};

const fc = (features) => ({ type: 'FeatureCollection', features });
const feat = (geometry, properties = {}) => ({ type: 'Feature', geometry, properties });
const line = (coords, p) => feat({ type: 'LineString', coordinates: coords }, p);

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
  // triangles: a strip between the two sides, a fan around each end
  const tris = [];
  for (let i = 0; i + 1 < n; i++) tris.push(left[i], right[i], left[i + 1], left[i + 1], right[i], right[i + 1]);
  const fan = (c, arc) => { for (let k = 0; k + 1 < arc.length; k++) tris.push(c, arc[k], arc[k + 1]); };
  fan(pl, [left[n - 1], ...cap, right[n - 1]]);
  fan(p0, [right[0], ...back, left[0]]);
  const ring = [...left, ...cap, ...right.reverse(), ...back];
  ring.push(ring[0]);
  return { ring, tris };
}

// a convex polygon's triangles (a fan from its first point)
function fanTris(ring) {
  const tris = [];
  for (let k = 1; k + 1 < ring.length; k++) tris.push(ring[0], ring[k], ring[k + 1]);
  return tris;
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

// The vendored MapLibre draws the style's sky in every frame, a default sky when the style
// has none: one pass over the whole canvas with the sky's fragment shader. The chart is
// never pitched (maxPitch 0), so the sky is never in view and the pass draws nothing
// visible, yet with software WebGL it was most of an empty frame's rasterising (llvmpipe:
// ~50 of ~80 ms of CPU per frame of a blank map, load ~10; measured in docs/viewer.md).
// MapLibre has no option to turn it off, so its draw function is replaced with a no-op
// (an internal of the pinned version: when it is not there, nothing is changed).
function skipSky(map) {
  const p = map.painter;
  if (!p || !p.drawFunctions || typeof p.drawFunctions.sky !== 'function') return false;
  p.drawFunctions = { ...p.drawFunctions, sky: () => {} };
  return true;
}

export class Chart {
  constructor(el, scene, frame, { onClick } = {}) {
    this.frame = frame;
    this.scene = scene;
    this.stats = { updates: 0, targets: 0, cones: 0, planStages: 0, criticalStages: 0, lidarPoints: 0, ellipses: 0, ghosts: 0, labels: 0, loaded: false, idle: 0, renders: 0, sourceMaxzoom: null };
    this.orientation = 'north';
    this.follow = true;
    this.palette = 'day';
    this.draft = [];
    this.ghosts = [];
    this.last = null;
    this.layer = new ChartLayer(frame, new SymbolAtlas());
    this.stats.layer = this.layer.stats;
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
    this.stats.skySkipped = skipSky(this.map);
    this.map.addControl(new maplibregl.ScaleControl({ unit: 'nautical' }), 'top-right');
    this.ready = new Promise((resolve) => this.map.on('load', () => { this._setup(); resolve(); }));
    this.map.on('idle', () => { this.stats.idle += 1; });
    this.map.on('render', () => { this.stats.renders += 1; });
    this.map.on('zoomend', () => this._retile());
    this.map.on('click', (e) => onClick && onClick(frame.toNed(e.lngLat.lng, e.lngLat.lat)));
  }

  _ll(points) { return points.map((p) => this.frame.toLonLat(p[0], p[1])); }

  _wantMaxzoom() { return Math.max(0, Math.floor(this.map.getZoom()) - ZOOM_DEPTH); }

  // The layers, bottom to top: land, coast, everything that moves (the WebGL layer), the
  // route being edited.
  _layers() {
    const P = PALETTES[this.palette] || PALETTES.day;
    return [
      { id: 'land', type: 'fill', source: 'land', paint: { 'fill-color': P.land } },
      { id: 'coast', type: 'line', source: 'land', paint: { 'line-color': P.coast, 'line-width': 1 } },
      this.layer,
      { id: 'draft', type: 'line', source: 'draft', paint: { 'line-color': '#d4691e', 'line-width': 3 } },
    ];
  }

  // (Re)make the GeoJSON sources tiled at `maxzoom` and the layers.
  _build(maxzoom) {
    const m = this.map;
    for (const l of this._layers()) if (m.getLayer(l.id)) m.removeLayer(l.id);
    for (const id of ['land', 'draft']) if (m.getSource(id)) m.removeSource(id);
    const src = (id, data) => m.addSource(id, { type: 'geojson', data, tolerance: 0.2, maxzoom, buffer: 64 });
    src('land', this.scene.land);
    src('draft', fc(this.draft.length > 1 ? [line(this._ll(this.draft))] : []));
    for (const l of this._layers()) m.addLayer(l);
    this.stats.sourceMaxzoom = maxzoom;
  }

  _retile() {
    if (!this.stats.loaded) return;
    const want = this._wantMaxzoom();
    if (want !== this.stats.sourceMaxzoom) this._build(want);
    if (this.last) this.update(...this.last);   // the names depend on the zoom
  }

  _setup() {
    this.map.getContainer().style.background = PALETTES[this.palette].water;
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
    const ghosts = [];
    const labels = (answer?.alternatives || []).map((a) => a.label);
    for (const g of answer?.ghosts || []) {
      const k = Math.max(0, labels.indexOf(g.alternative));
      const pos = g.positions_m || [];
      if (pos.length > 1) {
        ghosts.push({ pos, alt: g.alternative, color: g.collision ? 'rgba(224,20,30,0.6)' : hexA(GHOST_COLOURS[k % GHOST_COLOURS.length], 0.55) });
      }
    }
    this.ghosts = ghosts;
    this.stats.ghosts = ghosts.length;
    this.stats.ghostAlternatives = labels.length;
    if (this.last) this.update(...this.last);
  }

  // The ghost lines the chart's layer holds now: [alternative, colour] each.
  drawnGhosts() { return this.layer.tags.map((t) => [t.tag, t.color]); }

  // One snapshot (plus the targets main.js derived from it) onto the chart.
  update(s, targets) {
    this.last = [s, targets];
    if (!this.stats.loaded) return;
    const m = this.map, G = this.layer, own = s.own, p = [own.state[0], own.state[1]], psi = own.state[2];
    const L = own.length_m || 10, B = own.beam_m || 3;
    const sog = own.sog_m_s || 0, cog = own.cog_rad ?? psi;
    const P = PALETTES[this.palette] || PALETTES.day;
    G.atlas.trim();
    G.begin();
    const ln = (pts, color, width, dash = 'solid', tag = null) => G.line(pts, color, width, dash, tag);

    // fills: prediction cones ("green broadening path"), the own ship's hull to scale
    const tr = s.tracks, hull = placed(hullOutline(L, B), p, psi), rings = [];
    (tr.ids || []).forEach((id, i) => {
      const c = cone(tr.pred_mean[i] || [], tr.pred_radius_m[i] || []);
      if (c) { G.fill(c.tris, 'rgba(40,170,60,0.22)'); rings.push(c.ring); }
    });
    G.fill(fanTris(hull), 'rgba(255,255,255,0.4)');
    // lines, bottom to top: cone outlines, hull, centrelines
    for (const r of rings) ln(r, 'rgba(20,120,40,0.7)', 1);
    ln(hull, P.own, 1);
    (tr.ids || []).forEach((id, i) => { const mm = tr.pred_mean[i] || []; if (mm.length > 1) ln(mm, '#1f8a35', 1); });
    // route and past track
    const route = own.route || [];
    if (route.length) ln([p, ...route.slice(own.waypoint_index || 0)], P.route, 2, 'long');
    if ((own.past_track || []).length > 1) ln([...own.past_track, p], '#555555', 1.5);
    // what-if ghosts over the route, under the plan and the targets
    for (const g of this.ghosts) ln(g.pos, g.color, 2.5, 'solid', g.alt);
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
        ln([plan[i], plan[i + 1]], critical ? '#e0141e' : '#1a9a2a', 5);
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
    // targets: vectors, CPA lines of dangerous ones
    const v0 = [sog * Math.cos(cog), sog * Math.sin(cog)];
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
    // circles: the own ship's position mark, waypoints, LiDAR returns (coast grey, vessels magenta)
    G.circle(p, 7, 'rgba(0,0,0,0)', P.own, 2);
    route.forEach((wp) => G.circle(wp, 4, 'rgba(0,0,0,0)', P.route, 2));
    const pts = s.lidar.points || [], coast = s.lidar.coast || [];
    pts.forEach((q, i) => G.circle(q, 1.6, coast[i] ? '#6a6a6a' : '#c01cc0', 'rgba(0,0,0,0)', 0));
    // symbols along the heading, then the names of the nearest and the dangerous targets
    for (const t of targets) {
      const kind = t.source === 'lidar' ? 'radar' : 'ais';
      G.sprite(t.pos, t.lost ? `${kind}-lost` : t.danger ? `${kind}-danger` : kind, { rot: t.heading ?? t.cogRad ?? 0 });
    }
    let nLabels = 0;
    if (m.getZoom() >= LABEL_MINZOOM) {
      const near = targets.filter((t) => !t.danger).sort((a, b) => a.range - b.range).slice(0, LABELS);
      for (const t of [...near, ...targets.filter((x) => x.danger)]) {
        const img = G.atlas.get(`name:${t.label}`);
        G.sprite(t.pos, `name:${t.label}`, { dx: 12 + img.w / 2, withMap: false });
        nLabels += 1;
      }
    }
    G.end();

    // orientation: north-up, course-up or head-up, following the own ship
    const bearing = this.orientation === 'course' ? deg(cog) : this.orientation === 'head' ? deg(psi) : 0;
    if (this.follow) m.jumpTo({ center: this.frame.toLonLat(p[0], p[1]), bearing });
    else if (m.getBearing() !== bearing) m.jumpTo({ bearing });

    Object.assign(this.stats, {
      updates: this.stats.updates + 1, targets: targets.length, cones: rings.length, planStages: nPlan, criticalStages: nCrit,
      lidarPoints: pts.length, ellipses: nEll, bearing, labels: nLabels,
    });
  }
}

// '#rrggbb' with an alpha -> 'rgba(r,g,b,a)'
function hexA(hex, a) {
  const n = parseInt(hex.slice(1), 16);
  return `rgba(${(n >> 16) & 255},${(n >> 8) & 255},${n & 255},${a})`;
}
