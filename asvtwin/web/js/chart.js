// The ECDIS-style chart: MapLibre GL JS with a style made only of inline GeoJSON (no tile,
// glyph or sprite server). Everything the snapshot holds in scene NED metres is converted
// to lon/lat with the scene's exact LocalFrame port (geo.js).
import * as maplibregl from 'maplibre-gl';
import { addSymbols } from './symbols.js';
import { deg } from './geo.js';

const VECTOR_S = 360;          // COG/SOG vectors: 6 minutes ahead
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
    this.stats = { updates: 0, targets: 0, cones: 0, planStages: 0, criticalStages: 0, lidarPoints: 0, ellipses: 0, loaded: false, idle: 0 };
    this.orientation = 'north';
    this.follow = true;
    this.palette = 'day';
    this.draft = [];
    const o = scene.origin;
    this.map = new maplibregl.Map({
      container: el,
      style: { version: 8, sources: {}, layers: [{ id: 'water', type: 'background', paint: { 'background-color': PALETTES.day.water } }] },
      center: [o.lon_deg, o.lat_deg], zoom: 13, attributionControl: false, fadeDuration: 0,
      maxPitch: 0, renderWorldCopies: false,
    });
    this.map.addControl(new maplibregl.ScaleControl({ unit: 'nautical' }), 'top-right');
    this.ready = new Promise((resolve) => this.map.on('load', () => { this._setup(); resolve(); }));
    this.map.on('idle', () => { this.stats.idle += 1; });
    this.map.on('click', (e) => onClick && onClick(frame.toNed(e.lngLat.lng, e.lngLat.lat)));
  }

  _ll(points) { return points.map((p) => this.frame.toLonLat(p[0], p[1])); }

  _setup() {
    const m = this.map, P = PALETTES.day;
    addSymbols(m);
    const src = (id, data = EMPTY) => m.addSource(id, { type: 'geojson', data, tolerance: 0.2 });
    src('land', this.scene.land);
    // every moving part lives in one GeoJSON source (one setData, one re-tiling per update);
    // each feature's `kind` selects its layer
    src('dyn');
    src('draft');
    const add = (layer) => {
      if (layer.source === 'dyn' || !['land', 'draft'].includes(layer.source)) {
        const kind = ['==', ['get', 'kind'], layer.source];
        layer.filter = layer.filter ? ['all', kind, layer.filter] : kind;
        layer.source = 'dyn';
      }
      m.addLayer(layer);
    };
    add({ id: 'land', type: 'fill', source: 'land', paint: { 'fill-color': P.land } });
    add({ id: 'coast', type: 'line', source: 'land', paint: { 'line-color': P.coast, 'line-width': 1 } });
    add({ id: 'route', type: 'line', source: 'route', filter: ['==', ['geometry-type'], 'LineString'], paint: { 'line-color': P.route, 'line-width': 2, 'line-dasharray': [4, 2] } });
    add({ id: 'route-wp', type: 'circle', source: 'route', filter: ['==', ['geometry-type'], 'Point'], paint: { 'circle-radius': 4, 'circle-color': 'rgba(0,0,0,0)', 'circle-stroke-color': P.route, 'circle-stroke-width': 2 } });
    add({ id: 'track', type: 'line', source: 'track', paint: { 'line-color': '#555', 'line-width': 1.5 } });
    add({ id: 'cones', type: 'fill', source: 'cones', paint: { 'fill-color': 'rgba(40,170,60,0.22)', 'fill-outline-color': 'rgba(20,120,40,0.7)' } });
    add({ id: 'preds', type: 'line', source: 'preds', paint: { 'line-color': '#1f8a35', 'line-width': 1 } });
    add({ id: 'ellipses', type: 'line', source: 'ellipses', paint: { 'line-color': '#008b9a', 'line-width': 1.5 } });
    add({ id: 'lidar', type: 'circle', source: 'lidar', paint: { 'circle-radius': 1.6, 'circle-color': ['case', ['get', 'coast'], '#6a6a6a', '#c01cc0'] } });
    add({ id: 'plan', type: 'line', source: 'plan', layout: { 'line-cap': 'round' }, paint: { 'line-color': ['case', ['get', 'critical'], '#e0141e', '#1a9a2a'], 'line-width': 5 } });
    add({ id: 'arrows', type: 'line', source: 'arrows', paint: { 'line-color': ['get', 'color'], 'line-width': 2, 'line-dasharray': ['case', ['get', 'ghost'], ['literal', [2, 2]], ['literal', [1, 0]]] } });
    add({ id: 'cpa', type: 'line', source: 'cpa', paint: { 'line-color': '#e0141e', 'line-width': 1.5, 'line-dasharray': [3, 2] } });
    add({ id: 'vectors', type: 'line', source: 'vectors', paint: { 'line-color': ['case', ['get', 'danger'], '#e0141e', '#1c1c1c'], 'line-width': 1.2, 'line-dasharray': [4, 3] } });
    add({ id: 'targets', type: 'symbol', source: 'targets', layout: { 'icon-image': ['get', 'icon'], 'icon-rotate': ['get', 'rot'], 'icon-rotation-alignment': 'map', 'icon-allow-overlap': true, 'icon-ignore-placement': true } });
    add({ id: 'labels', type: 'symbol', source: 'targets', minzoom: 11.5, layout: { 'icon-image': ['concat', 'name:', ['get', 'name']], 'icon-anchor': 'left', 'icon-offset': [12, 0], 'icon-allow-overlap': true, 'icon-ignore-placement': true } });
    add({ id: 'own-hull', type: 'fill', source: 'own', filter: ['==', ['get', 'part'], 'hull'], paint: { 'fill-color': 'rgba(255,255,255,0.4)', 'fill-outline-color': P.own } });
    add({ id: 'own-lines', type: 'line', source: 'own', filter: ['==', ['geometry-type'], 'LineString'], paint: { 'line-color': P.own, 'line-width': 2, 'line-dasharray': ['case', ['==', ['get', 'part'], 'cog'], ['literal', [4, 3]], ['literal', [1, 0]]] } });
    add({ id: 'own-mark', type: 'circle', source: 'own', filter: ['==', ['geometry-type'], 'Point'], paint: { 'circle-radius': 7, 'circle-color': 'rgba(0,0,0,0)', 'circle-stroke-color': P.own, 'circle-stroke-width': 2 } });
    add({ id: 'draft', type: 'line', source: 'draft', paint: { 'line-color': '#d4691e', 'line-width': 3 } });
    this.stats.loaded = true;
    document.getElementById('attribution').textContent = `Land: ${this.scene.attribution} (${this.scene.licence.split(' ').slice(0, 4).join(' ')}…)`;
  }

  setPalette(name) {
    const P = PALETTES[name] || PALETTES.day;
    this.palette = name;
    const m = this.map;
    if (!this.stats.loaded) return;
    m.setPaintProperty('water', 'background-color', P.water);
    m.setPaintProperty('land', 'fill-color', P.land);
    m.setPaintProperty('coast', 'line-color', P.coast);
    for (const id of ['own-lines', 'own-mark']) m.setPaintProperty(id, id === 'own-mark' ? 'circle-stroke-color' : 'line-color', P.own);
  }

  setDraft(points) {
    this.draft = points;
    if (!this.stats.loaded) return;
    this.map.getSource('draft').setData(fc(points.length > 1 ? [line(this._ll(points))] : []));
  }

  // One snapshot (plus the targets main.js derived from it) onto the chart.
  update(s, targets) {
    if (!this.stats.loaded) return;
    const m = this.map, own = s.own, p = [own.state[0], own.state[1]], psi = own.state[2];
    const L = own.length_m || 10, B = own.beam_m || 3;
    const sog = own.sog_m_s || 0, cog = own.cog_rad ?? psi;
    const all = [];
    const set = (kind, feats) => { for (const f of feats) { f.properties.kind = kind; all.push(f); } };

    // own ship: hull to scale, heading line, COG/SOG vector, position mark
    const headLen = Math.max(3 * L, 200);
    set('own', [
      poly(this._ll(placed(hullOutline(L, B), p, psi)), { part: 'hull' }),
      line(this._ll([p, [p[0] + headLen * Math.cos(psi), p[1] + headLen * Math.sin(psi)]]), { part: 'heading' }),
      line(this._ll([p, [p[0] + sog * VECTOR_S * Math.cos(cog), p[1] + sog * VECTOR_S * Math.sin(cog)]]), { part: 'cog' }),
      feat({ type: 'Point', coordinates: this.frame.toLonLat(p[0], p[1]) }, { part: 'mark' }),
    ]);
    const route = own.route || [];
    set('route', [
      ...(route.length ? [line(this._ll([p, ...route.slice(own.waypoint_index || 0)]))] : []),
      ...route.map((w, i) => feat({ type: 'Point', coordinates: this.frame.toLonLat(w[0], w[1]) }, { i })),
    ]);
    set('track', (own.past_track || []).length > 1 ? [line(this._ll([...own.past_track, p]))] : []);

    // LiDAR returns and the ellipses fitted to them
    const pts = s.lidar.points || [], coast = s.lidar.coast || [];
    const cpts = [], vpts = [];
    pts.forEach((q, i) => (coast[i] ? cpts : vpts).push(this.frame.toLonLat(q[0], q[1])));
    set('lidar', [feat({ type: 'MultiPoint', coordinates: cpts }, { coast: true }), feat({ type: 'MultiPoint', coordinates: vpts }, { coast: false })]);
    const el = s.ellipses, ellFeats = [];
    (el.centre || []).forEach((c, i) => { if (el.ok[i]) ellFeats.push(line(this._ll(ellipseRing(c, el.semi_axes_m[i], el.angle_rad[i])))); });
    set('ellipses', ellFeats);

    // tracks: prediction cones ("green broadening path") and centrelines
    const tr = s.tracks, cones = [], preds = [];
    (tr.ids || []).forEach((id, i) => {
      const means = tr.pred_mean[i] || [], radii = tr.pred_radius_m[i] || [];
      const ring = cone(means, radii);
      if (ring) cones.push(poly(this._ll(ring), { id }));
      if (means.length > 1) preds.push(line(this._ll(means), { id }));
    });
    set('cones', cones); set('preds', preds);

    // the safety filter's plan: green, critical stages red
    const f = s.filter, plan = f.plan || [], crit = new Set(f.critical_stages || []);
    const planFeats = [];
    for (let i = 0; i + 1 < plan.length; i++) {
      const critical = crit.has(i + 1) || crit.has(i);
      planFeats.push(line(this._ll([plan[i], plan[i + 1]]), { critical, stage: i }));
    }
    set('plan', f.enabled ? planFeats : []);
    this.stats.planStages = f.enabled ? planFeats.length : 0;
    this.stats.criticalStages = f.enabled ? planFeats.filter((x) => x.properties.critical).length : 0;

    // arrows: the learner's proposal u_L (ghost) and the input let through u_0, the
    // disturbance estimate d-hat (body frame -> NED) and the wind (pointing downwind)
    const arrows = [];
    const uL = f.u_L || [0, 0, 0], u0 = f.u_0 || [0, 0, 0];
    const fmax = Math.max(Math.hypot(uL[0], uL[1]), Math.hypot(u0[0], u0[1]), 1e-9);
    const bodyDir = (v) => psi + Math.atan2(v[1], v[0]);
    if (Math.hypot(uL[0], uL[1]) > 0) arrows.push(line(this._ll(arrow(p, bodyDir(uL), 4 * L * Math.hypot(uL[0], uL[1]) / fmax)), { color: '#888888', ghost: true }));
    if (Math.hypot(u0[0], u0[1]) > 0) arrows.push(line(this._ll(arrow(p, bodyDir(u0), 4 * L * Math.hypot(u0[0], u0[1]) / fmax)), { color: '#1a9a2a', ghost: false }));
    const dh = s.observer.d_hat || [0, 0, 0];
    if (Math.hypot(dh[0], dh[1]) > 0) arrows.push(line(this._ll(arrow(p, bodyDir(dh), 2.5 * L)), { color: '#1f5fd0', ghost: false }));
    const w = s.weather;
    if (w.wind_speed_m_s > 0 && w.wind_from_rad != null) {
      const side = [p[0] + 2 * L * Math.cos(psi + Math.PI / 2), p[1] + 2 * L * Math.sin(psi + Math.PI / 2)];
      arrows.push(line(this._ll(arrow(side, w.wind_from_rad + Math.PI, 2.5 * L)), { color: '#444444', ghost: false }));
    }
    set('arrows', arrows);

    // targets: symbols along COG, vectors, names, CPA lines of dangerous ones
    const tf = [], vf = [], cf = [];
    const v0 = [sog * Math.cos(cog), sog * Math.sin(cog)];
    for (const t of targets) {
      const kind = t.source === 'lidar' ? 'radar' : 'ais';
      const icon = t.lost ? `${kind}-lost` : t.danger ? `${kind}-danger` : kind;
      const rot = deg(t.heading ?? t.cogRad ?? 0);
      tf.push(feat({ type: 'Point', coordinates: this.frame.toLonLat(t.pos[0], t.pos[1]) }, { icon, rot, name: t.label }));
      if (t.vel && !t.lost) vf.push(line(this._ll([t.pos, [t.pos[0] + t.vel[0] * VECTOR_S, t.pos[1] + t.vel[1] * VECTOR_S]]), { danger: t.danger }));
      if (t.danger && t.tcpa != null) {
        const a = [p[0] + v0[0] * t.tcpa, p[1] + v0[1] * t.tcpa];
        const b = [t.pos[0] + t.vel[0] * t.tcpa, t.pos[1] + t.vel[1] * t.tcpa];
        cf.push(line(this._ll([p, a, b, t.pos])));
      }
    }
    set('targets', tf); set('vectors', vf); set('cpa', cf);
    m.getSource('dyn').setData(fc(all));

    // orientation: north-up, course-up or head-up, following the own ship
    const bearing = this.orientation === 'course' ? deg(cog) : this.orientation === 'head' ? deg(psi) : 0;
    if (this.follow) m.jumpTo({ center: this.frame.toLonLat(p[0], p[1]), bearing });
    else if (m.getBearing() !== bearing) m.jumpTo({ bearing });

    Object.assign(this.stats, {
      updates: this.stats.updates + 1, targets: tf.length, cones: cones.length,
      lidarPoints: pts.length, ellipses: ellFeats.length, bearing,
    });
  }
}
