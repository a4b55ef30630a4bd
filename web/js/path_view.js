// The tool path in plan view (X-Y) and side view (X-Z), in stock coordinates, coloured by the
// resultant force, with the stock outline. Clicking near the path picks that time.
import { h, lowerBound } from './dom.js';

const STOPS = [[49, 54, 149], [69, 117, 180], [116, 173, 209], [254, 224, 144], [244, 109, 67], [165, 0, 38]];
const BINS = 24;

export function forceColour(fraction) {
  const f = Math.min(1, Math.max(0, fraction)) * (STOPS.length - 1);
  const i = Math.min(STOPS.length - 2, Math.floor(f));
  const t = f - i;
  const c = STOPS[i].map((v, k) => Math.round(v + t * (STOPS[i + 1][k] - v)));
  return `rgb(${c[0]},${c[1]},${c[2]})`;
}

// Motion window answer -> {t, x, y, z} in stock coordinates; buckets of a decimated answer
// are taken at their midpoints (a few thousand buckets are finer than the screen).
export function pathPoints(w, offset = [0, 0, 0]) {
  const n = w.t_s.length;
  const t = new Float64Array(n);
  const p = { x: new Float32Array(n), y: new Float32Array(n), z: new Float32Array(n) };
  const axes = [['x', 'x_mm', 0], ['y', 'y_mm', 1], ['z', 'z_mm', 2]];
  for (let i = 0; i < n; i++) {
    t[i] = w.decimated ? (w.t_s[i] + w.t_end_s[i]) / 2 : w.t_s[i];
    for (const [a, key, k] of axes) {
      const v = w.decimated ? (w[key].min[i] + w[key].max[i]) / 2 : w[key][i];
      p[a][i] = v + offset[k];
    }
  }
  return { t, ...p };
}

class View {
  constructor(title, hAxis, vAxis) {
    this.hAxis = hAxis;
    this.vAxis = vAxis;
    this.canvas = h('canvas', { role: 'img', 'aria-label': `${title}: tool path coloured by force; the block table lists the same data` });
    this.el = h('figure', { class: 'path-view' }, h('figcaption', {}, title), this.canvas);
  }

  layout(bounds, cssWidth, cssHeight) {
    const px = devicePixelRatio || 1;
    this.canvas.width = Math.round(cssWidth * px);
    this.canvas.height = Math.round(cssHeight * px);
    this.canvas.style.width = `${cssWidth}px`;
    this.canvas.style.height = `${cssHeight}px`;
    const pad = 16;
    const [h0, h1] = bounds[this.hAxis];
    const [v0, v1] = bounds[this.vAxis];
    const s = Math.min((cssWidth - 2 * pad) / Math.max(h1 - h0, 1e-6), (cssHeight - 2 * pad) / Math.max(v1 - v0, 1e-6));
    const ox = (cssWidth - s * (h1 - h0)) / 2;
    const oy = (cssHeight - s * (v1 - v0)) / 2;
    this.toScreen = (a, b) => [ox + s * (a - h0), cssHeight - oy - s * (b - v0)];
    this.px = px;
  }
}

export class PathView {
  // stock: {min: [x,y,z], max: [x,y,z]} or null; onPick(t).
  constructor(container, { points, forceAt, forceMax, stock, onPick }) {
    this.p = points;
    this.stock = stock;
    this.onPick = onPick;
    this.forceMax = forceMax || 1;
    this.force = Float32Array.from(points.t, (t) => forceAt(t));
    this.views = [new View('Plan view (X-Y)', 'x', 'y'), new View('Side view (X-Z)', 'x', 'z')];
    this.selected = null;   // {t0, t1}
    this.marker = null;
    const legend = h('div', { class: 'colour-legend' }, h('span', {}, '0 N'),
      h('span', { class: 'ramp', style: `background: linear-gradient(to right, ${STOPS.map((c) => `rgb(${c})`).join(',')})` }),
      h('span', {}, `${Math.round(this.forceMax)} N resultant`));
    this.el = h('div', { class: 'path-views' }, this.views.map((v) => v.el), legend);
    container.append(this.el);
    for (const v of this.views) v.canvas.addEventListener('click', (e) => this.click(v, e));
    this.resizeObserver = new ResizeObserver(() => this.draw());
    this.resizeObserver.observe(this.el);
  }

  destroy() {
    this.resizeObserver.disconnect();
  }

  bounds() {
    const b = {};
    for (const a of ['x', 'y', 'z']) {
      let lo = Infinity;
      let hi = -Infinity;
      for (const v of this.p[a]) {
        if (v < lo) lo = v;
        if (v > hi) hi = v;
      }
      const k = { x: 0, y: 1, z: 2 }[a];
      if (this.stock) {
        lo = Math.min(lo, this.stock.min[k]);
        hi = Math.max(hi, this.stock.max[k]);
      }
      b[a] = [lo, hi];
    }
    return b;
  }

  select(block, t) {
    this.selected = block ? { t0: block.t_start_s, t1: block.t_end_s } : null;
    this.marker = t ?? null;
    this.draw();
  }

  draw() {
    const width = Math.max(200, Math.floor(this.views[0].el.clientWidth));
    const b = this.bounds();
    for (const v of this.views) {
      v.layout(b, width, 280);
      this.drawView(v);
    }
  }

  drawView(v) {
    const ctx = v.canvas.getContext('2d');
    const { px } = v;
    ctx.setTransform(px, 0, 0, px, 0, 0);
    ctx.clearRect(0, 0, v.canvas.width, v.canvas.height);
    const H = this.p[v.hAxis];
    const V = this.p[v.vAxis];
    const n = this.p.t.length;
    if (this.stock) {
      const k = { x: 0, y: 1, z: 2 };
      const [x0, y0] = v.toScreen(this.stock.min[k[v.hAxis]], this.stock.min[k[v.vAxis]]);
      const [x1, y1] = v.toScreen(this.stock.max[k[v.hAxis]], this.stock.max[k[v.vAxis]]);
      ctx.fillStyle = 'rgba(148, 163, 184, 0.15)';
      ctx.fillRect(x0, y1, x1 - x0, y0 - y1);
      ctx.strokeStyle = '#64748b';
      ctx.setLineDash([5, 3]);
      ctx.strokeRect(x0, y1, x1 - x0, y0 - y1);
      ctx.setLineDash([]);
    }
    // One path per colour bin: a few dozen strokes instead of one per segment.
    const bins = Array.from({ length: BINS + 1 }, () => new Path2D());
    for (let i = 1; i < n; i++) {
      const f = Math.max(this.force[i - 1], this.force[i]);
      const bin = f <= 0 ? BINS : Math.min(BINS - 1, Math.floor((f / this.forceMax) * BINS));
      const [ax, ay] = v.toScreen(H[i - 1], V[i - 1]);
      const [bx, by] = v.toScreen(H[i], V[i]);
      bins[bin].moveTo(ax, ay);
      bins[bin].lineTo(bx, by);
    }
    ctx.lineCap = 'round';
    ctx.strokeStyle = 'rgba(100, 116, 139, 0.45)';
    ctx.lineWidth = 1;
    ctx.stroke(bins[BINS]);
    ctx.lineWidth = 2.5;
    for (let k = 0; k < BINS; k++) {
      ctx.strokeStyle = forceColour((k + 0.5) / BINS);
      ctx.stroke(bins[k]);
    }
    if (this.selected) {
      ctx.strokeStyle = 'rgba(37, 99, 235, 0.55)';
      ctx.lineWidth = 6;
      ctx.beginPath();
      let started = false;
      for (let i = 0; i < n; i++) {
        if (this.p.t[i] < this.selected.t0 || this.p.t[i] > this.selected.t1) continue;
        const [x, y] = v.toScreen(H[i], V[i]);
        if (started) ctx.lineTo(x, y);
        else ctx.moveTo(x, y);
        started = true;
      }
      ctx.stroke();
    }
    if (this.marker != null) {
      const i = Math.min(n - 1, lowerBound(this.p.t, this.marker));
      const [x, y] = v.toScreen(H[i], V[i]);
      ctx.fillStyle = '#2563eb';
      ctx.strokeStyle = '#fff';
      ctx.lineWidth = 2;
      ctx.beginPath();
      ctx.arc(x, y, 6, 0, 2 * Math.PI);
      ctx.fill();
      ctx.stroke();
    }
  }

  click(v, e) {
    const rect = v.canvas.getBoundingClientRect();
    const mx = e.clientX - rect.left;
    const my = e.clientY - rect.top;
    const H = this.p[v.hAxis];
    const V = this.p[v.vAxis];
    let best = -1;
    let bestD = 12 * 12;
    for (let i = 0; i < this.p.t.length; i++) {
      const [x, y] = v.toScreen(H[i], V[i]);
      const d = (x - mx) ** 2 + (y - my) ** 2;
      if (d < bestD) {
        bestD = d;
        best = i;
      }
    }
    if (best >= 0) this.onPick?.(this.p.t[best]);
  }
}
