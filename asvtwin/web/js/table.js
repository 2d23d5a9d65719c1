// The target table: range, bearing, SOG, COG, CPA, TCPA, source and report age, sortable
// by any column. A target is dangerous when CPA <= the CPA limit and 0 <= TCPA <= the TCPA
// limit (the user sets both) while the own ship is under way; it flashes red until
// acknowledged, and alarms again if it leaves the limits and comes back.
import { NM, KN, deg } from './geo.js';

const OVERSCAN = 20;   // rows drawn above and below the visible ones
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
      this.render(this.last || [], false);
    }));
    tbody.addEventListener('click', (e) => {
      const key = e.target?.dataset?.ack;
      if (key) { this.acked.add(key); this.render(this.last || [], false); onAck && onAck(key); }
    });
  }

  ackAll() { (this.last || []).forEach((t) => t.danger && this.acked.add(t.key)); this.render(this.last || [], false); }

  // Virtualised rows: the DOM holds only the rows in view plus OVERSCAN above and below
  // (a spacer row stands for the rest), so a render at 2 Hz lays out and paints a few dozen
  // rows, not every target (200 rows relaid out and repainted cost tens of milliseconds of
  // the browser's main thread). Rows in the window are kept between renders: only the cells
  // whose text changed are written and rows are moved only when the order changed.
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

  _pad() {
    const tr = document.createElement('tr'), td = document.createElement('td');
    tr.className = 'pad'; td.colSpan = 10; tr.appendChild(td);
    return { tr, td, h: -1 };
  }

  // The rows [first, last) of the sorted list that the scroller shows, with OVERSCAN more
  // on each side; the row height is measured once from a drawn row.
  _window(n) {
    const sc = this.scroller;
    if (!sc || !this.rowH) return [0, Math.min(n, 2 * OVERSCAN)];
    const first = Math.max(0, Math.floor(sc.scrollTop / this.rowH) - OVERSCAN);
    const last = Math.min(n, Math.ceil((sc.scrollTop + sc.clientHeight) / this.rowH) + OVERSCAN);
    return [Math.min(first, Math.max(0, last - 1)), last];
  }

  // `tick`: a timed render (dangerous rows flash once per tick), not a scroll or a click
  render(targets, tick = true) {
    this.last = targets;
    this.rows = this.rows || new Map();
    if (!this.padTop) { this.padTop = this._pad(); this.padBottom = this._pad(); }
    if (!this.scroller) {
      this.scroller = this.tbody.closest('.table-scroll');
      let asked = false;
      this.scroller?.addEventListener('scroll', () => {
        if (asked) return;
        asked = true;
        requestAnimationFrame(() => { asked = false; this.render(this.last || [], false); });
      }, { passive: true });
    }
    for (const k of [...this.acked]) if (!targets.some((t) => t.key === k && t.danger)) this.acked.delete(k);
    const key = this.sortKey, sign = this.asc ? 1 : -1;
    const val = (t) => (key === 'label' || key === 'source' ? t[key] : t[key] ?? Infinity);
    const rows = [...targets].sort((a, b) => {
      const x = val(a), y = val(b);
      return (x < y ? -1 : x > y ? 1 : 0) * sign;
    });
    // unacknowledged dangerous targets flash: their rows toggle on every render (2 Hz)
    if (tick) this.blink = !this.blink;
    const [first, last] = this._window(rows.length);
    const seen = new Set();
    let writes = 0;
    const order = rows.slice(first, last).map((t) => {
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
    // the spacers keep the scroll height of the whole list
    const rowH = this.rowH || 0;
    for (const [pad, h] of [[this.padTop, first * rowH], [this.padBottom, (rows.length - last) * rowH]]) {
      if (pad.h !== h) { pad.td.style.height = `${h}px`; pad.tr.hidden = h === 0; pad.h = h; }
    }
    order.unshift(this.padTop.tr); order.push(this.padBottom.tr);
    const kids = this.tbody.children;
    let same = kids.length === order.length;
    for (let i = 0; same && i < order.length; i++) same = kids[i] === order[i];
    if (!same) this.tbody.replaceChildren(...order);
    if (!this.rowH && order.length > 2) {
      // measured once (a forced layout); rows have a fixed height (CSS)
      this.rowH = order[1].getBoundingClientRect().height || 0;
      if (this.rowH && last < rows.length) { this.render(targets, false); return; }
    }
    this.stats.cellWrites = writes;
    this.stats.reordered = !same;
    this.stats.domRows = last - first;
    this.stats.first = first;
    const dangerous = targets.filter((t) => t.danger);
    Object.assign(this.stats, {
      rows: rows.length, dangerous: dangerous.length,
      unacked: dangerous.filter((t) => !this.acked.has(t.key)).length, updates: this.stats.updates + 1,
    });
  }
}
