// "What if…": asks the server (POST /api/whatif) what happens next under each
// alternative, from the snapshot it is showing, and shows the answer: each alternative's
// Monte Carlo futures as faint ghost tracks on the chart in the alternative's colour (red
// where a future collided), and a panel with the collision and grounding probabilities
// (95 % Clopper-Pearson intervals), the closest approach and the recommendation in words.
import { GHOST_COLOURS } from './chart.js';

const $ = (id) => document.getElementById(id);
const esc = (s) => String(s ?? '').replace(/[&<>"]/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;' }[c]));
const pct = (p) => (p == null ? '–' : `${(100 * p).toFixed(1)} %`);
const m = (v) => (v == null || !Number.isFinite(v) ? '–' : `${v.toFixed(0)} m`);

export function answerHtml(ans) {
  const rows = ans.alternatives.map((a, k) => `<tr data-alt="${esc(a.label)}">
      <td><span class="sw" style="background:${GHOST_COLOURS[k % GHOST_COLOURS.length]}"></span>${esc(a.label)}</td>
      <td title="95 % interval ${pct(a.p_collision_ci[0])} – ${pct(a.p_collision_ci[1])}">${a.collisions}/${a.rollouts} · ≤ ${pct(a.p_collision_ci[1])}</td>
      <td title="95 % interval ${pct(a.p_grounding_ci[0])} – ${pct(a.p_grounding_ci[1])}">${a.groundings}/${a.rollouts}</td>
      <td title="5 % / 50 % / 95 % over the futures">${m(a.min_distance_m[1])}</td></tr>`).join('');
  const r = ans.recommendation;
  return `<div class="rec ${r.acceptable ? '' : 'bad'}"><b>${esc(r.label)}</b>${r.rule ? ` (COLREG rule ${r.rule})` : ''}: ${esc(r.reason)}</div>
    <table><tr><th>alternative</th><th>collisions · upper 95 %</th><th>groundings</th><th>closest (median)</th></tr>${rows}</table>
    <div class="note">${ans.rollouts} futures each, ${ans.horizon_s.toFixed(0)} s ahead from t = ${ans.t_s.toFixed(1)} s, seed ${ans.seed}; ghosts: ${(ans.ghosts || []).length} futures, positions every ${ans.ghost_t_s.length > 1 ? (ans.ghost_t_s[1] - ans.ghost_t_s[0]).toFixed(0) : '–'} s</div>`;
}

// Wire the panel: `post(path, body)` sends JSON and resolves with {status, body};
// `chart.setGhosts(answer | null)` draws or clears the ghosts; `state` is exposed to tests.
export function setupWhatIf(chart, post, state) {
  const panel = $('whatif-panel'), out = $('whatif-answer');
  const close = () => { panel.hidden = true; chart.setGhosts(null); $('legend-ghosts').hidden = true; state.answer = null; };
  $('btn-whatif').addEventListener('click', () => { if (panel.hidden) panel.hidden = false; else close(); });
  $('btn-whatif-close').addEventListener('click', close);
  $('btn-whatif-ask').addEventListener('click', async () => {
    const alternatives = [...document.querySelectorAll('.wi-alt')].filter((c) => c.checked).map((c) => c.value);
    const body = { alternatives, rollouts: Number($('wi-rollouts').value), horizon_s: Number($('wi-horizon').value), ghosts: 10 };
    state.pending = true;
    $('btn-whatif-ask').disabled = true;
    out.textContent = `rolling out ${body.rollouts} futures × ${alternatives.length} alternatives…`;
    const t0 = performance.now();
    try {
      const r = await post('/api/whatif', body);
      if (r.status !== 200) { out.innerHTML = `<div class="rec bad">refused (HTTP ${r.status}): ${esc(r.body.error)}</div>`; state.error = r.body.error; return; }
      state.answer = r.body;
      state.seconds = (performance.now() - t0) / 1000;
      out.innerHTML = answerHtml(r.body);
      chart.setGhosts(r.body);
      $('legend-ghosts').hidden = false;
    } catch (err) {
      out.innerHTML = `<div class="rec bad">failed: ${esc(err)}</div>`;
      state.error = String(err);
    } finally {
      state.pending = false;
      state.asked = (state.asked || 0) + 1;
      $('btn-whatif-ask').disabled = false;
    }
  });
}
