// Small time plots of numbers on a canvas: the last HISTORY values of one number, scaled to their own range.

const HISTORY = 120;

export class Series {
  constructor() { this.points = []; }
  add(t, v) {
    this.points.push([t, v]);
    if (this.points.length > HISTORY) this.points.shift();
  }
}

export function spark(width = 120, height = 24) {
  const canvas = document.createElement("canvas");
  canvas.className = "spark";
  canvas.width = width;
  canvas.height = height;
  return canvas;
}

export function draw(canvas, series) {
  const ctx = canvas.getContext("2d");
  const { width, height } = canvas;
  ctx.clearRect(0, 0, width, height);
  const pts = series.points;
  if (pts.length < 2) return;
  let lo = Infinity, hi = -Infinity;
  for (const [, v] of pts) { if (v < lo) lo = v; if (v > hi) hi = v; }
  if (hi === lo) { hi += 0.5; lo -= 0.5; }
  const t0 = pts[0][0], t1 = pts[pts.length - 1][0] || t0 + 1;
  ctx.strokeStyle = "#2b6cb0";
  ctx.lineWidth = 1.2;
  ctx.beginPath();
  pts.forEach(([t, v], i) => {
    const x = ((t - t0) / Math.max(t1 - t0, 1)) * (width - 2) + 1;
    const y = height - 2 - ((v - lo) / (hi - lo)) * (height - 4);
    if (i === 0) ctx.moveTo(x, y); else ctx.lineTo(x, y);
  });
  ctx.stroke();
}
