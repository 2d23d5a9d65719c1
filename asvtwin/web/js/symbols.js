// Chart symbols drawn on a canvas (no sprite server): IEC 62288-style AIS targets as
// triangles pointing along the heading, radar/LiDAR-only tracks as circles, lost targets
// crossed out, and name labels as images (MapLibre would need a glyph server for text).
const SIZE = 32;

function canvas(w, h) {
  const c = document.createElement('canvas');
  c.width = w; c.height = h;
  return [c, c.getContext('2d')];
}

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

export function addSymbols(map) {
  const defs = {
    'ais': (c) => triangle(c, '#1c1c1c', 'rgba(255,255,255,0.6)'),
    'ais-danger': (c) => triangle(c, '#e0141e', 'rgba(255,80,80,0.5)'),
    'ais-lost': (c) => { triangle(c, '#777', null); cross(c, '#777'); },
    'radar': (c) => circle(c, '#1c1c1c'),
    'radar-danger': (c) => circle(c, '#e0141e'),
    'radar-lost': (c) => { circle(c, '#777'); cross(c, '#777'); },
  };
  for (const [name, draw] of Object.entries(defs)) {
    const [cv, ctx] = canvas(SIZE, SIZE);
    draw(ctx);
    map.addImage(name, ctx.getImageData(0, 0, SIZE, SIZE), { pixelRatio: 1.4 });
  }
  // name labels on demand: layers ask for "name:<text>" and get it drawn here
  map.setMissingStyleImageResolver(async (id) => {
    if (!id.startsWith('name:') || map.hasImage(id)) return;
    const text = id.slice(5);
    const [, probe] = canvas(1, 1);
    probe.font = '12px "DejaVu Sans", sans-serif';
    const w = Math.ceil(probe.measureText(text).width) + 6;
    const [, ctx] = canvas(w, 16);
    ctx.font = '12px "DejaVu Sans", sans-serif';
    ctx.lineWidth = 3; ctx.strokeStyle = 'rgba(255,255,255,0.85)';
    ctx.strokeText(text, 3, 12);
    ctx.fillStyle = '#111'; ctx.fillText(text, 3, 12);
    map.addImage(id, ctx.getImageData(0, 0, w, 16));
  });
}
