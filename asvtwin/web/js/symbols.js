// Chart symbols drawn on a canvas (no sprite or glyph server): IEC 62288-style AIS targets
// as triangles pointing along the heading, radar/LiDAR-only tracks as circles, lost targets
// crossed out, and name labels, all packed into one canvas that the chart's WebGL layer
// (chartlayer.js) uses as its texture. Labels are drawn once per name, on first use.
const SIZE = 32;           // symbol canvas [px]; drawn at SIZE / ICON_RATIO on the chart
const ICON_RATIO = 1.4;
const ATLAS = 1024;        // the atlas canvas is ATLAS x ATLAS px
const LABEL_H = 16;
const FONT = '12px "DejaVu Sans", sans-serif';

function triangle(ctx, stroke, fill) {
  ctx.beginPath();
  ctx.moveTo(SIZE / 2, 3); ctx.lineTo(SIZE / 2 + 8, SIZE - 5); ctx.lineTo(SIZE / 2 - 8, SIZE - 5);
  ctx.closePath();
  if (fill) { ctx.fillStyle = fill; ctx.fill(); }
  ctx.lineWidth = 2.2; ctx.strokeStyle = stroke; ctx.stroke();
}

function circle(ctx, stroke) {
  ctx.beginPath(); ctx.arc(SIZE / 2, SIZE / 2, 8, 0, 2 * Math.PI);
  ctx.lineWidth = 2.2; ctx.strokeStyle = stroke; ctx.stroke();
}

function cross(ctx, stroke) {
  ctx.beginPath();
  ctx.moveTo(6, 6); ctx.lineTo(SIZE - 6, SIZE - 6); ctx.moveTo(SIZE - 6, 6); ctx.lineTo(6, SIZE - 6);
  ctx.lineWidth = 2; ctx.strokeStyle = stroke; ctx.stroke();
}

const ICONS = {
  'ais': (c) => triangle(c, '#1c1c1c', 'rgba(255,255,255,0.6)'),
  'ais-danger': (c) => triangle(c, '#e0141e', 'rgba(255,80,80,0.5)'),
  'ais-lost': (c) => { triangle(c, '#777', null); cross(c, '#777'); },
  'radar': (c) => circle(c, '#1c1c1c'),
  'radar-danger': (c) => circle(c, '#e0141e'),
  'radar-lost': (c) => { circle(c, '#777'); cross(c, '#777'); },
};

// Images by name ('ais', ..., or 'name:<text>' for a label), packed in shelves; `version`
// changes whenever the canvas does (the layer then uploads it again).
export class SymbolAtlas {
  constructor() {
    this.canvas = document.createElement('canvas');
    this.canvas.width = ATLAS; this.canvas.height = ATLAS;
    this.ctx = this.canvas.getContext('2d', { willReadFrequently: false });
    this.version = 0;
    this._clear();
  }

  _clear() {
    this.ctx.clearRect(0, 0, ATLAS, ATLAS);
    this.images = new Map();
    this.x = 0; this.y = 0; this.shelf = 0;
    for (const [name, draw] of Object.entries(ICONS)) {
      this._place(name, SIZE, SIZE, (ctx) => draw(ctx), SIZE / ICON_RATIO);
    }
    this.version += 1;
  }

  // drop the labels when the atlas is three quarters full (call between two snapshots)
  trim() { if (this.y > 0.75 * ATLAS) this._clear(); }

  _place(name, w, h, draw, shown = null) {
    if (this.x + w > ATLAS) { this.x = 0; this.y += this.shelf + 1; this.shelf = 0; }
    if (this.y + h > ATLAS) throw new Error('symbol atlas full');
    const { ctx } = this;
    ctx.save(); ctx.translate(this.x, this.y); draw(ctx); ctx.restore();
    const k = shown ? shown / w : 1;
    const img = { w: w * k, h: h * k, uv: [this.x / ATLAS, this.y / ATLAS, (this.x + w) / ATLAS, (this.y + h) / ATLAS] };
    this.images.set(name, img);
    this.x += w + 1; this.shelf = Math.max(this.shelf, h);
    this.version += 1;
    return img;
  }

  get(name) {
    const img = this.images.get(name);
    if (img) return img;
    if (!name.startsWith('name:')) throw new Error(`no chart symbol ${name}`);
    const text = name.slice(5);
    this.ctx.font = FONT;
    const w = Math.min(ATLAS, Math.ceil(this.ctx.measureText(text).width) + 6);
    return this._place(name, w, LABEL_H, (ctx) => {
      ctx.font = FONT;
      ctx.lineWidth = 3; ctx.strokeStyle = 'rgba(255,255,255,0.85)';
      ctx.strokeText(text, 3, 12);
      ctx.fillStyle = '#111'; ctx.fillText(text, 3, 12);
    });
  }
}
