// The target table: range, bearing, SOG, COG, CPA, TCPA, source and report age, sortable
// by any column. A target is dangerous when CPA <= the CPA limit and 0 <= TCPA <= the TCPA
// limit (the user sets both) while the own ship is under way; it flashes red until
// acknowledged, and alarms again if it leaves the limits and comes back.
import { NM, KN, deg } from './geo.js';

const fmt = (v, d = 1) => (v == null || Number.isNaN(v) ? '–' : v.toFixed(d));

export class TargetTable {
  constructor(tbody, headRow, { onAck } = {}) {
    this.tbody = tbody;
    this.sortKey = 'tcpa';
    this.asc = true;
    this.acked = new Set();
    this.stats = { rows: 0, dangerous: 0, unacked: 0, updates: 0 };
    headRow.querySelectorAll('th[data-k]').forEach((th) => th.addEventListener('click', () => {
      const k = th.dataset.k;
      this.asc = this.sortKey === k ? !this.asc : true;
      this.sortKey = k;
      headRow.querySelectorAll('th').forEach((x) => x.classList.remove('sorted', 'asc'));
      th.classList.add('sorted'); if (this.asc) th.classList.add('asc');
      this.render(this.last || []);
    }));
    tbody.addEventListener('click', (e) => {
      const key = e.target?.dataset?.ack;
      if (key) { this.acked.add(key); this.render(this.last || []); onAck && onAck(key); }
    });
  }

  ackAll() { (this.last || []).forEach((t) => t.danger && this.acked.add(t.key)); this.render(this.last || []); }

  render(targets) {
    this.last = targets;
    for (const k of [...this.acked]) if (!targets.some((t) => t.key === k && t.danger)) this.acked.delete(k);
    const key = this.sortKey, sign = this.asc ? 1 : -1;
    const val = (t) => (key === 'label' || key === 'source' ? t[key] : t[key] ?? Infinity);
    const rows = [...targets].sort((a, b) => {
      const x = val(a), y = val(b);
      return (x < y ? -1 : x > y ? 1 : 0) * sign;
    });
    const html = rows.map((t) => {
      const cls = [t.danger ? 'danger' : '', t.danger && this.acked.has(t.key) ? 'acked' : '', t.lost ? 'lost' : ''].join(' ');
      const ack = t.danger && !this.acked.has(t.key) ? `<button data-ack="${t.key}">ACK</button>` : '';
      return `<tr class="${cls}" data-key="${t.key}"><td>${t.label}</td><td>${fmt(t.range / NM, 2)}</td><td>${fmt(t.bearing, 0)}</td>`
        + `<td>${fmt(t.sog / KN, 1)}</td><td>${t.cogRad == null ? '–' : fmt(deg(t.cogRad), 0)}</td>`
        + `<td>${t.cpa == null ? '–' : fmt(t.cpa / NM, 2)}</td><td>${t.tcpa == null ? '–' : fmt(t.tcpa / 60, 1)}</td>`
        + `<td>${t.source}</td><td>${fmt(t.age, 0)}</td><td>${ack}</td></tr>`;
    }).join('');
    this.tbody.innerHTML = html;
    // unacknowledged dangerous targets flash: the table toggles on every render (2 Hz)
    this.blink = !this.blink;
    this.tbody.parentElement.classList.toggle('blink', this.blink);
    const dangerous = targets.filter((t) => t.danger);
    Object.assign(this.stats, {
      rows: rows.length, dangerous: dangerous.length,
      unacked: dangerous.filter((t) => !this.acked.has(t.key)).length, updates: this.stats.updates + 1,
    });
  }
}
