// The viewer: fetches the scene once, receives snapshots on /ws, draws the chart, the 3-D
// view, the target table and the status panel, and sends the controls over REST.
// State for tests and curious users: window.asvtwinViewer.
import { LocalFrame, rangeBearing, cpaTcpa, KN, NM } from './geo.js';
import { Chart } from './chart.js';
import { View3D } from './view3d.js';
import { TargetTable } from './table.js';
import { renderStatus } from './status.js';
import { setupWhatIf } from './whatif.js';

const $ = (id) => document.getElementById(id);
// text written only when it changed: an unchanged write still invalidates style and layout
const setText = (el, text) => { if (el.textContent !== text) el.textContent = text; };
const params = new URLSearchParams(location.search);
const token = params.get('token');
const rateHz = Math.min(60, Math.max(0.1, Number(params.get('rate_hz') || 10)));
const headers = { 'content-type': 'application/json', ...(token ? { 'x-asvtwin-token': token } : {}) };

const V = window.asvtwinViewer = {
  ready: false, snapshots: 0, lastSeq: null, bytes: 0, errors: [], events: [],
  controls: {}, lastControl: null, conn: { connected: false, rateHz, bytes: 0 }, info: null,
  // main-thread time spent per part [ms, summed since the page opened] (the benchmark reads it)
  ms: { parse: 0, derive: 0, chart: 0, view3d: 0, render3d: 0, table: 0, status: 0 },
};
// run f, adding its duration to V.ms[key]
const timed = (key, f) => { const t0 = performance.now(); const r = f(); V.ms[key] += performance.now() - t0; return r; };
window.addEventListener('error', (e) => V.errors.push(String(e.message)));
window.addEventListener('unhandledrejection', (e) => V.errors.push(String(e.reason)));

async function getJSON(path) {
  const r = await fetch(path, { headers });
  if (!r.ok) throw new Error(`${path}: HTTP ${r.status}`);
  return r.json();
}

function logEvent(text, t_s) {
  const li = document.createElement('li');
  li.textContent = t_s == null ? text : `${t_s.toFixed(1)} s  ${text}`;
  const list = $('event-list');
  list.prepend(li);
  while (list.children.length > 80) list.lastChild.remove();
  V.events.push(text);
}

async function control(action, body = {}) {
  V.lastControl = { action, pending: true };
  try {
    const r = await fetch(`/api/control/${action}`, { method: 'POST', headers, body: JSON.stringify(body) });
    const answer = await r.json();
    V.controls[action] = (V.controls[action] || 0) + 1;
    V.lastControl = { action, status: r.status, answer };
    if (!r.ok) logEvent(`${action} refused: ${answer.error}`);
    return answer;
  } catch (err) {
    V.lastControl = { action, error: String(err) };
    logEvent(`${action} failed: ${err}`);
    return null;
  }
}
V.control = control;

// ---- the targets every view shares: tracks, plus AIS targets not tied to a track ----
function deriveTargets(s, limits) {
  const own = s.own, p0 = [own.state[0], own.state[1]];
  const v0 = [own.sog_m_s * Math.cos(own.cog_rad), own.sog_m_s * Math.sin(own.cog_rad)];
  const underWay = own.sog_m_s > 0.5 * KN;   // no CPA alarms when stopped
  const a = s.ais, byMmsi = new Map();
  (a.mmsi || []).forEach((m, i) => byMmsi.set(m, i));
  const out = [], tr = s.tracks;
  const scanAge = s.lidar.t_s == null ? null : s.t_s - s.lidar.t_s;
  const add = (t) => {
    [t.range, t.bearing] = rangeBearing(p0, t.pos);
    t.danger = underWay && !t.lost && t.cpa != null && t.tcpa != null
      && t.cpa <= limits.cpaNm * NM && t.tcpa <= limits.tcpaMin * 60;
    out.push(t);
  };
  const used = new Set();
  (tr.ids || []).forEach((id, i) => {
    const m = tr.mmsi[i], ai = m >= 0 ? byMmsi.get(m) : undefined;
    if (ai !== undefined) used.add(m);
    const [x, y, vx, vy] = tr.mean[i];
    add({
      key: `t${id}`, label: ai !== undefined && a.names[ai] ? a.names[ai] : (m >= 0 ? `${m}` : `track ${id}`),
      pos: [x, y], vel: [vx, vy], sog: Math.hypot(vx, vy), cogRad: Math.atan2(vy, vx),
      heading: ai !== undefined ? (a.heading_rad[ai] ?? a.cog_rad[ai]) : Math.atan2(vy, vx),
      // lost: a track with AIS is lost when its AIS reports went stale (the registry's
      // judgement, by reporting interval); between two reports it coasts, as it should
      cpa: tr.cpa_m[i], tcpa: tr.tcpa_s[i], source: tr.source[i],
      lost: ai !== undefined ? !!a.stale[ai] : tr.status[i] === 'coasting',
      age: ai !== undefined ? a.age_s[ai] : scanAge, length: ai !== undefined ? a.length_m[ai] : null,
      beam: ai !== undefined ? a.beam_m[ai] : null, mmsi: m,
    });
  });
  (a.mmsi || []).forEach((m, i) => {
    if (used.has(m)) return;
    const pos = a.position_m[i], sog = a.sog_m_s[i] ?? 0, cog = a.cog_rad[i] ?? 0;
    const vel = [sog * Math.cos(cog), sog * Math.sin(cog)];
    const [cpa, tcpa] = cpaTcpa(p0, v0, pos, vel);
    add({
      key: `a${m}`, label: a.names[i] || `${m}`, pos, vel, sog, cogRad: a.cog_rad[i], heading: a.heading_rad[i] ?? a.cog_rad[i],
      cpa, tcpa, source: 'ais', lost: a.stale[i], age: a.age_s[i], length: a.length_m[i], beam: a.beam_m[i], mmsi: m,
    });
  });
  return out;
}

async function main() {
  const [info, scene] = await Promise.all([getJSON('/api/info'), getJSON('/api/scene')]);
  V.info = info;
  const frame = new LocalFrame(scene.origin.lat_deg, scene.origin.lon_deg);
  V.frame = frame;
  $('relief-note').textContent = scene.relief.note;
  const limits = { cpaNm: Number($('in-cpa').value), tcpaMin: Number($('in-tcpa').value) };
  $('in-cpa').addEventListener('change', (e) => { limits.cpaNm = Number(e.target.value); });
  $('in-tcpa').addEventListener('change', (e) => { limits.tcpaMin = Number(e.target.value); });

  let mode = null, draft = [];
  const setMode = (m) => {
    mode = mode === m ? null : m;
    $('btn-route').classList.toggle('active', mode === 'route');
    $('btn-inject').classList.toggle('active', mode === 'inject');
    $('chart-mode').style.display = mode ? 'block' : 'none';
    $('chart-mode').textContent = mode === 'route' ? 'click waypoints, then Send route' : mode === 'inject' ? 'click where the vessel starts' : '';
  };
  const chart = new Chart($('chart'), scene, frame, {
    onClick: (ned) => {
      if (mode === 'route') { draft.push(ned); chart.setDraft(draft); $('btn-route-send').disabled = false; }
      else if (mode === 'inject') {
        const n = (V.injected = (V.injected || 0) + 1);
        control('inject', { spec: { name: `INJECTED ${n}`, start: { north_m: ned[0], east_m: ned[1] },
          heading_deg: Number($('in-inj-hdg').value) % 360, speed_kn: Number($('in-inj-spd').value) } });
        setMode(null);
      }
    },
  });
  V.chart = chart.stats;
  V.map = chart.map;
  V.chartView = chart;
  const view = new View3D($('view3d'), scene);
  V.view3d = view.stats;
  V.view = view;
  const table = new TargetTable($('targets').querySelector('tbody'), $('targets').querySelector('thead tr'));
  V.table = table.stats;
  $('btn-ack-all').addEventListener('click', () => table.ackAll());
  V.whatif = {};
  setupWhatIf(chart, async (path, body) => {
    const r = await fetch(path, { method: 'POST', headers, body: JSON.stringify(body) });
    return { status: r.status, body: await r.json() };
  }, V.whatif);

  // controls
  let latest = null, fresh = false, requestFrame = () => {};
  // paused or not: the snapshot says so, but a twin may publish nothing while paused, so a
  // successful pause/resume counts until a newer snapshot arrives
  let pauseIntent = null;
  const isPaused = () => (pauseIntent && (!latest || latest.seq <= pauseIntent.seq)
    ? pauseIntent.paused : !!latest?.clock.paused);
  V.isPaused = isPaused;
  $('btn-pause').addEventListener('click', async () => {
    const action = isPaused() ? 'resume' : 'pause';
    const answer = await control(action);
    if (answer?.ok) pauseIntent = { paused: action === 'pause', seq: latest?.seq ?? -1 };
    $('btn-pause').textContent = isPaused() ? 'Resume' : 'Pause';
  });
  $('btn-step').addEventListener('click', () => control('step', { n_ticks: 1 }));
  $('sel-speed').addEventListener('change', (e) => control('speed', { factor: e.target.value === 'max' ? 'max' : Number(e.target.value) }));
  $('chk-filter').addEventListener('change', (e) => control('filter', { enabled: e.target.checked }));
  $('btn-wind').addEventListener('click', () => control('wind', { speed_m_s: Number($('in-wind-speed').value), from_deg: Number($('in-wind-from').value) % 360 }));
  $('btn-route').addEventListener('click', () => { draft = []; chart.setDraft(draft); setMode('route'); });
  $('btn-route-send').addEventListener('click', async () => {
    if (draft.length) await control('route', { waypoints_ned: draft });
    draft = []; chart.setDraft(draft); $('btn-route-send').disabled = true; setMode(null);
  });
  $('btn-inject').addEventListener('click', () => setMode('inject'));
  $('sel-orient').addEventListener('change', (e) => { chart.orientation = e.target.value; fresh = true; requestFrame(); });
  $('chk-follow').addEventListener('change', (e) => { chart.follow = e.target.checked; });
  $('sel-palette').addEventListener('change', (e) => {
    document.body.className = e.target.value; chart.setPalette(e.target.value);
  });
  const replay = info.kind === 'replay';
  let seeking = false;
  if (replay) {
    $('timeline').hidden = false;
    $('seek').max = String(info.duration_s);
    $('seek').addEventListener('input', () => { seeking = true; });
    $('seek').addEventListener('change', async (e) => { await control('seek', { t_s: Number(e.target.value) }); seeking = false; });
    $('btn-play').addEventListener('click', () => control(latest?.clock.paused || V.replayPaused ? 'resume' : 'pause').then((a) => { if (a) V.replayPaused = !V.replayPaused; $('btn-play').textContent = V.replayPaused ? 'Play' : 'Pause'; }));
    for (const id of ['chk-filter', 'btn-wind', 'btn-route', 'btn-inject']) $(id).disabled = true;
  }

  // the WebSocket, reconnecting with backoff
  let backoff = 500;
  const connect = () => {
    // ack=1: the server sends the next snapshot only after this page took the last one, so
    // a page slowed down by its machine gets fewer, fresh snapshots (never a backlog)
    const q = new URLSearchParams({ rate_hz: String(rateHz), format: 'json', ack: '1', ...(token ? { token } : {}) });
    const ws = new WebSocket(`${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/ws?${q}`);
    ws.binaryType = 'arraybuffer';
    const dec = new TextDecoder();
    ws.onopen = () => { V.conn.connected = true; backoff = 500; $('conn').className = 'conn on'; $('conn').textContent = 'live'; };
    ws.onclose = () => {
      V.conn.connected = false; $('conn').className = 'conn off'; $('conn').textContent = 'offline';
      setTimeout(connect, backoff); backoff = Math.min(10000, backoff * 2);
    };
    ws.onmessage = (ev) => {
      if (typeof ev.data === 'string') {
        const m = JSON.parse(ev.data);
        if (m.type === 'events') m.events.forEach((x) => logEvent(x, m.t_s));
        else if (m.type === 'error') logEvent(m.error);
        return;
      }
      V.conn.bytes = ev.data.byteLength;
      latest = timed('parse', () => JSON.parse(dec.decode(ev.data)));
      V.snapshots += 1; V.lastSeq = latest.seq; V.latest = latest;
      fresh = true;
      requestFrame();
      ws.send(JSON.stringify({ ack: latest.seq }));
    };
  };
  connect();

  // Drawing on demand: nothing runs per animation frame unless something changed. A
  // snapshot (or a control that changes the picture) asks for one frame; in it the chart
  // and the 3-D view take the newest snapshot. The table and the status panel change DOM
  // text, which costs style and layout, so they follow at most twice a second, on a timer.
  let targets = [], frameAsked = false, lastSlow = 0, slowTimer = null;
  const slow = () => {
    slowTimer = null;
    if (!latest) return;
    lastSlow = performance.now();
    timed('table', () => table.render(targets));
    setText($('target-count'), `(${targets.length}, ${table.stats.dangerous} dangerous)`);
    timed('status', () => renderStatus($('status'), latest, V.conn));
  };
  const drawFrame = () => {
    frameAsked = false;
    if (latest && fresh) {
      fresh = false;
      targets = timed('derive', () => deriveTargets(latest, limits));
      V.targets = targets.length;
      timed('chart', () => chart.update(latest, targets));
      timed('view3d', () => view.update(latest, targets));
      setText($('clock'), `t = ${latest.t_s.toFixed(1)} s${isPaused() ? ' (paused)' : ''}`);
      setText($('btn-pause'), isPaused() ? 'Resume' : 'Pause');
      if (replay && !seeking) { $('seek').value = String(latest.t_s); $('seek-label').textContent = `${latest.t_s.toFixed(1)} / ${info.duration_s.toFixed(1)} s`; }
      if (slowTimer === null) slowTimer = setTimeout(slow, Math.max(0, 500 - (performance.now() - lastSlow)));
    }
    timed('render3d', () => view.render());
  };
  requestFrame = () => { if (!frameAsked) { frameAsked = true; requestAnimationFrame(drawFrame); } };
  view.onDirty = requestFrame;
  await chart.ready;
  V.ready = true;
  requestFrame();
}

main().catch((err) => { V.errors.push(String(err)); logEvent(`viewer failed: ${err}`); });
