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

  // One row per target, kept between renders: only the cells whose text changed are
  // written and rows are moved only when the order changed, so a render at 2 Hz costs a
  // little style and layout, not a rebuilt table.
  _row(t) {
    let r = this.rows.get(t.key);
    if (!r) {
      const tr = document.createElement('tr');
      tr.dataset.key = t.key;
      const cells = [];
      for (let i = 0; i < 10; i++) cells.push(tr.appendChild(document.createElement('td')));
      r = { tr, cells, texts: new Array(10).fill(null), cls: null, ack: null };
      this.rows.set(t.key, r);
    }
    return r;
  }

  render(targets) {
    this.last = targets;
    this.rows = this.rows || new Map();
    for (const k of [...this.acked]) if (!targets.some((t) => t.key === k && t.danger)) this.acked.delete(k);
    const key = this.sortKey, sign = this.asc ? 1 : -1;
    const val = (t) => (key === 'label' || key === 'source' ? t[key] : t[key] ?? Infinity);
    const rows = [...targets].sort((a, b) => {
      const x = val(a), y = val(b);
      return (x < y ? -1 : x > y ? 1 : 0) * sign;
    });
    // unacknowledged dangerous targets flash: their rows toggle on every render (2 Hz)
    this.blink = !this.blink;
    const seen = new Set();
    let writes = 0;
    const order = rows.map((t) => {
      const r = this._row(t);
      seen.add(t.key);
      const texts = [t.label, fmt(t.range / NM, 2), fmt(t.bearing, 0), fmt(t.sog / KN, 1),
        t.cogRad == null ? '–' : fmt(deg(t.cogRad), 0), t.cpa == null ? '–' : fmt(t.cpa / NM, 2),
        t.tcpa == null ? '–' : fmt(t.tcpa / 60, 1), t.source, fmt(t.age, 0)];
      for (let i = 0; i < 9; i++) if (r.texts[i] !== texts[i]) { r.cells[i].textContent = texts[i]; r.texts[i] = texts[i]; writes += 1; }
      const acked = this.acked.has(t.key);
      const cls = [t.danger ? 'danger' : '', t.danger && acked ? 'acked' : '', t.danger && !acked && this.blink ? 'blink' : '', t.lost ? 'lost' : ''].join(' ').trim();
      if (r.cls !== cls) { r.tr.className = cls; r.cls = cls; }
      const ack = t.danger && !acked;
      if (r.ack !== ack) {
        r.cells[9].replaceChildren();
        if (ack) { const bt = document.createElement('button'); bt.dataset.ack = t.key; bt.textContent = 'ACK'; r.cells[9].appendChild(bt); }
        r.ack = ack;
      }
      return r.tr;
    });
    for (const [k, r] of this.rows) if (!seen.has(k)) { r.tr.remove(); this.rows.delete(k); }
    const kids = this.tbody.children;
    let same = kids.length === order.length;
    for (let i = 0; same && i < order.length; i++) same = kids[i] === order[i];
    if (!same) this.tbody.replaceChildren(...order);
    this.stats.cellWrites = writes;
    this.stats.reordered = !same;
    const dangerous = targets.filter((t) => t.danger);
    Object.assign(this.stats, {
      rows: rows.length, dangerous: dangerous.length,
      unacked: dangerous.filter((t) => !this.acked.has(t.key)).length, updates: this.stats.updates + 1,
    });
  }
}
