// The status panel by capability level (L0 physical ... L5 autonomous), after the
// digital-twin capability scale the paper uses: sources and report ages (L1), observer
// faults (L2), tracks and predictions (L3), the filter's interventions, fallbacks and
// solve time (L4), the controller and route (L5), and every component's health.
import { KN, deg } from './geo.js';

const esc = (s) => String(s ?? '').replace(/[&<>"]/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;' }[c]));
const num = (v, d = 1, unit = '') => (v == null || Number.isNaN(v) ? '–' : `${v.toFixed(d)}${unit}`);
const kv = (pairs) => `<div class="kv">${pairs.map(([k, v]) => `<span>${k}</span><span>${v}</span>`).join('')}</div>`;

export function renderStatus(el, s, conn) {
  const o = s.own, f = s.filter, ob = s.observer, w = s.weather, a = s.ais, tr = s.tracks;
  const ages = (a.age_s || []).filter((x) => x != null);
  const stale = (a.stale || []).filter(Boolean).length;
  const bySource = {};
  (tr.source || []).forEach((x) => { bySource[x] = (bySource[x] || 0) + 1; });
  const horizon = (tr.pred_times_s || []).length ? tr.pred_times_s[tr.pred_times_s.length - 1] : null;
  const dh = ob.d_hat || [0, 0, 0];
  const health = (s.health || []).map((h) => `<tr><td>${esc(h.name)}</td><td class="${h.status === 'ok' ? 'good' : h.status === 'failed' ? 'bad' : 'warn'}">${esc(h.status)}</td>`
    + `<td>${h.calls}</td><td>${h.errors}</td><td>${h.overruns}</td><td>${num(h.last_ms, 2)}</td><td>${num(h.mean_ms, 2)}</td></tr>`
    + (h.last_error ? `<tr><td colspan="7" class="bad">${esc(h.last_error)}</td></tr>` : '')).join('');
  el.innerHTML = `
    <h4>L0 physical — the world and the own ship</h4>${kv([
      ['scenario', esc(s.scenario)], ['time', `${num(s.t_s, 1)} s ${s.clock.wall_utc ? `(${esc(s.clock.wall_utc)})` : ''}`],
      ['clock', `${esc(s.clock.mode)} ×${num(s.clock.speed, 2)} ${s.clock.paused ? '<b class="warn">paused</b>' : ''}`],
      ['position', `${num(o.lat_deg, 5)}° N ${num(o.lon_deg, 5)}° E`],
      ['heading / COG', `${num(deg(o.state[2]), 1)}° / ${num(deg(o.cog_rad), 1)}°`], ['SOG', `${num(o.sog_m_s / KN, 1)} kn`],
      ['vessel', `${esc(o.vessel)} (${num(o.length_m, 1)} × ${num(o.beam_m, 1)} m)`]])}
    <h4>L1 descriptive — sources</h4>${kv([
      ['AIS targets', `${(a.mmsi || []).length} (${stale} stale${ages.length ? `, newest report ${num(Math.min(...ages), 0)} s, oldest ${num(Math.max(...ages), 0)} s` : ''})`],
      ['weather', `${esc(w.source) || '–'} · wind ${num(w.wind_speed_m_s, 1)} m/s from ${num(deg(w.wind_from_rad), 0)}° · age ${num(w.age_s, 0)} s`],
      ['LiDAR', `${s.lidar.n_rays} rays, ${(s.lidar.points || []).length} returns, range ${num(s.lidar.range_m, 0)} m, scan t ${num(s.lidar.t_s, 1)} s`],
      ['link', `${conn.connected ? '<span class="good">connected</span>' : '<span class="bad">disconnected</span>'} · ${num(conn.rateHz, 1)} Hz · ${conn.bytes} B/msg · seq ${s.seq}`]])}
    <h4>L2 diagnostic — observer</h4>${kv([
      ['d̂ (body)', `X ${num(dh[0] / 1e3, 1)} kN, Y ${num(dh[1] / 1e3, 1)} kN, N ${num(dh[2] / 1e3, 1)} kNm`],
      ['fault', ob.fault ? `<span class="bad">${esc(ob.fault_kind)} on ${esc(ob.fault_channel)} (${num(100 * ob.fault_confidence, 0)} %)</span>` : '<span class="good">none</span>'],
      ['estimate', ob.valid ? 'valid' : '<span class="warn">held (no measurement)</span>']])}
    <h4>L3 predictive — tracks</h4>${kv([
      ['tracks', `${(tr.ids || []).length} · ${Object.entries(bySource).map(([k, v]) => `${v} ${k}`).join(', ') || '–'}`],
      ['ellipses', `${(s.ellipses.ok || []).filter(Boolean).length} fitted`], ['prediction', horizon == null ? '–' : `${num(horizon, 0)} s ahead, 2σ cones`]])}
    <h4>L4 prescriptive — safety filter</h4>${kv([
      ['filter', f.enabled ? (f.intervened ? '<span class="warn">intervening</span>' : '<span class="good">passing u<sub>L</sub></span>') : '<span class="bad">off</span>'],
      ['certified', f.certified ? 'yes' : '<span class="bad">no</span>'], ['fallback', f.fallback === 'none' ? 'none' : `<span class="bad">${esc(f.fallback)}</span>`],
      ['counts', `${f.interventions} interventions, ${f.fallbacks} fallbacks / ${f.calls} calls`], ['solve', `${num(f.solve_ms, 2)} ms (${esc(f.status)})`],
      ['why', esc(f.explanation) || '–']])}
    <h4>L5 autonomous — controller</h4>${kv([
      ['controller', esc(o.controller)], ['route', `waypoint ${o.waypoint_index + 1} of ${(o.route || []).length}, CTE ${num(o.cte_m, 1)} m`],
      ['goal', o.goal_reached ? '<span class="good">reached</span>' : 'under way']])}
    <h4>Component health</h4><table><tr><th>component</th><th>status</th><th>calls</th><th>err</th><th>overrun</th><th>last ms</th><th>mean ms</th></tr>${health}</table>`;
}
