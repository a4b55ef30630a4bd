// The force plot: Fx, Fy, Fz and the resultant (torque and power on demand) over time, on uPlot.
//
// The whole run is held as a coarse overview (min/max envelope); the visible window is fetched
// again at about one bucket per pixel after each zoom or pan, so detail appears as you zoom while
// panning stays instant on the overview. Limit lines, flagged intervals and the selection are
// drawn in uPlot's hooks on the same canvas, so the PNG export shows them too.
//
// With an NC program, the resultant predicted from the commanded motion is one more series. The
// server puts it on the actual run's time axis block by block, but its samples fall at other
// times, so it has its own overview and its own finer windows fetched beside the actual ones;
// the two are joined on the union of their times.
//
// Each interaction records performance.measure('plot-frame') (input to drawn) and each window
// refinement 'plot-refine' (scale change to finer data drawn), for the browser tests.
import uPlot from '../vendor/uPlot.esm.js';
import { lowerBound } from './dom.js';

export const CHANNELS = [
  { key: 'fx_N', label: 'Fx', unit: 'N', scale: 'N', stroke: '#d62728' },
  { key: 'fy_N', label: 'Fy', unit: 'N', scale: 'N', stroke: '#2ca02c' },
  { key: 'fz_N', label: 'Fz', unit: 'N', scale: 'N', stroke: '#1f77b4' },
  { key: 'f_N', label: 'F (resultant)', unit: 'N', scale: 'N', stroke: '#111', width: 1.6 },
  { key: 'torque_Nm', label: 'Torque', unit: 'N·m', scale: 'Nm', stroke: '#8c2d9c', dash: [6, 3], optional: true },
  { key: 'power_kW', label: 'Power', unit: 'kW', scale: 'kW', stroke: '#e67e00', dash: [2, 3], optional: true },
];

// See-through, so the actual resultant stays visible where the two coincide.
export const COMMANDED = { key: 'f_N', label: 'F commanded (program)', unit: 'N', scale: 'N', stroke: 'rgba(23, 190, 207, 0.7)', width: 1.4 };
const ACTUAL_LABEL = 'F actual (dry run)';

const OVERVIEW_POINTS = 2000;   // buckets for the whole run: more than a laptop plot has pixels
const MAX_WINDOW_POINTS = 4000;
const REFINE_DELAY_MS = 120;

// A window answer as plot columns [x, ...keys]. Decimated buckets become two points (min at the
// bucket's start, max at its end) so the line sweeps the whole envelope of each pixel column.
export function seriesColumns(w, keys) {
  if (!w.decimated) return [Float64Array.from(w.t_s), ...keys.map((k) => Float32Array.from(w[k]))];
  const n = w.t_s.length;
  const x = new Float64Array(2 * n);
  for (let i = 0; i < n; i++) {
    x[2 * i] = w.t_s[i];
    x[2 * i + 1] = w.t_end_s[i];
  }
  return [x, ...keys.map((k) => {
    const { min, max } = w[k];
    const y = new Float32Array(2 * n);
    for (let i = 0; i < n; i++) {
      y[2 * i] = min[i];
      y[2 * i + 1] = max[i];
    }
    return y;
  })];
}

export function windowColumns(w) {
  return seriesColumns(w, CHANNELS.map((c) => c.key));
}

// The overview outside [from, to] around the detail inside it.
export function mergeColumns(overview, detail, from, to) {
  const a = lowerBound(overview[0], from);
  const b = lowerBound(overview[0], to);
  const d0 = detail[0];
  const lo = lowerBound(d0, from);
  const hi = lowerBound(d0, to + 1e-12 * Math.max(1, Math.abs(to)));
  const n = a + (hi - lo) + (overview[0].length - b);
  return overview.map((col, j) => {
    const out = new (j === 0 ? Float64Array : Float32Array)(n);
    out.set(col.subarray(0, a), 0);
    out.set(detail[j].subarray(lo, hi), a);
    out.set(col.subarray(b), a + hi - lo);
    return out;
  });
}

// The measured series (fx_N, fy_N, fz_N) as [x, fx, fy, fz], envelopes as min/max pairs.
export function measuredColumns(w) {
  return seriesColumns(w, ['fx_N', 'fy_N', 'fz_N']);
}

// Columns [xa, ...ya] and [xb, ...yb] on the union of their times (both ascending, repeated times
// kept: an envelope's min and max may share one), null where a series has no sample.
export function unionColumns(a, b) {
  const [xa, xb] = [a[0], b[0]];
  const n = xa.length + xb.length;
  const x = new Float64Array(n);
  const ys = [...a.slice(1), ...b.slice(1)].map(() => new Array(n).fill(null));
  const na = a.length - 1;
  let i = 0;
  let j = 0;
  for (let k = 0; k < n; k++) {
    if (j >= xb.length || (i < xa.length && xa[i] <= xb[j])) {
      x[k] = xa[i];
      for (let c = 0; c < na; c++) ys[c][k] = a[c + 1][i];
      i += 1;
    } else {
      x[k] = xb[j];
      for (let c = 0; c < b.length - 1; c++) ys[na + c][k] = b[c + 1][j];
      j += 1;
    }
  }
  return [x, ...ys];
}

export class ForcePlot {
  // fetchWindow(from_s, to_s, max_points, signal) -> forces window answer; fetchCommanded the same
  // for the commanded resultant (channel f_N), or null for a run without a program.
  constructor(container, { fetchWindow, fetchCommanded = null, limits = {}, onPick, onRange }) {
    this.container = container;
    this.fetchWindow = fetchWindow;
    this.fetchCommanded = fetchCommanded;
    this.commanded = null;   // {overview, current, decimated} columns [x, f] of the commanded resultant
    this.limits = limits;
    this.onPick = onPick;
    this.onRange = onRange;
    this.shaded = [];        // [{t0, t1}] flagged intervals
    this.selected = null;    // {t0, t1} of the selected block
    this.marker = null;      // selected time
    this.show = { torque_Nm: false, power_kW: false, commanded: true };
    this.refineTimer = 0;
    this.inflight = null;
    this.fetchedRange = null;
    this.interactionStart = 0;
    this.currentData = null;
    this.measured = null;    // [x, fx, fy, fz] columns of the attached dynamometer record
    container.addEventListener('keydown', (e) => this.keydown(e));
  }

  async load() {
    // The commanded series is an extra: if it cannot be loaded the actual forces still plot.
    const [w, wc] = await Promise.all([
      this.fetchWindow(undefined, undefined, OVERVIEW_POINTS),
      (this.fetchCommanded?.(undefined, undefined, OVERVIEW_POINTS) ?? Promise.resolve(null)).catch((e) => {
        console.warn('commanded forces unavailable:', e);
        return null;
      }),
    ]);
    this.extent = [w.from_s, w.to_s];
    this.overview = windowColumns(w);
    this.currentData = this.overview;
    this.decimatedOverview = w.decimated;
    if (wc) {
      const overview = seriesColumns(wc, [COMMANDED.key]);
      this.commanded = { overview, current: overview, decimated: wc.decimated };
      if (overview[0].length) this.extent = [Math.min(w.from_s, wc.from_s), Math.max(w.to_s, wc.to_s)];
    }
    this.build();
  }

  // What uPlot draws: the actual columns, joined with the commanded resultant when there is one.
  plotData() {
    if (!this.commanded) return this.currentData;
    const data = unionColumns(this.currentData, this.commanded.current);
    this.container.dataset.commandedPoints = String(this.commanded.current[0].length);
    return data;
  }

  commandedIndex() {
    return this.commanded ? CHANNELS.length + 1 : -1;
  }

  // Shows or hides the commanded resultant (also done by clicking its legend entry).
  setCommanded(on) {
    this.show.commanded = on;
    if (this.u && this.commanded) this.u.setSeries(this.commandedIndex(), { show: on });
  }

  options() {
    const width = Math.max(320, this.container.clientWidth);
    const showOpt = (c) => !c.optional || this.show[c.key];
    const series = [{ label: 't (s)', value: (u, v) => (v == null ? '–' : v.toFixed(4)) }];
    // Joined series have nulls where only the other one has a sample: draw across them.
    const spanGaps = Boolean(this.commanded);
    const line = (c, label, show) => ({
      label, scale: c.scale, stroke: c.stroke, width: c.width || 1, dash: c.dash, show, spanGaps,
      value: (u, v) => (v == null ? '–' : `${v.toFixed(1)} ${c.unit}`), points: { show: false },
    });
    for (const c of CHANNELS) series.push(line(c, this.commanded && c.key === 'f_N' ? ACTUAL_LABEL : c.label, showOpt(c)));
    if (this.commanded) series.push(line(COMMANDED, COMMANDED.label, this.show.commanded));
    const axes = [
      { label: 'time (s)' },
      { scale: 'N', label: 'force (N)', size: 60 },
    ];
    if (this.show.torque_Nm) axes.push({ scale: 'Nm', label: 'torque (N·m)', side: 1, grid: { show: false }, size: 60 });
    if (this.show.power_kW) axes.push({ scale: 'kW', label: 'power (kW)', side: 1, grid: { show: false }, size: 60 });
    const self = this;
    return {
      width,
      height: 340,
      series,
      axes,
      scales: { x: { time: false }, N: { auto: true }, Nm: { auto: true }, kW: { auto: true } },
      legend: { live: true },
      cursor: {
        drag: { x: true, y: false, setScale: true },
        bind: {
          // Shift-drag or middle-drag pans; a plain drag selects a range to zoom into.
          mousedown: (u, targ, handler) => (e) => {
            if (e.button === 1 || (e.button === 0 && e.shiftKey)) {
              self.startPan(e);
              return null;
            }
            self.downAt = [e.clientX, e.clientY];
            return handler(e);
          },
          mouseup: (u, targ, handler) => (e) => {
            if (self.panning) return null;
            const moved = self.downAt ? Math.hypot(e.clientX - self.downAt[0], e.clientY - self.downAt[1]) : 0;
            self.downAt = null;
            if (moved < 3) self.pick(e);
            else self.interactionStart = performance.now();
            return handler(e);
          },
        },
      },
      hooks: {
        drawClear: [(u) => this.drawBands(u)],
        draw: [(u) => this.drawOverlays(u)],
        setScale: [(u, key) => key === 'x' && this.scaleChanged(u)],
        setSeries: [(u, i, opts) => this.seriesToggled(i, opts)],
      },
    };
  }

  build() {
    const range = this.u ? [this.u.scales.x.min, this.u.scales.x.max] : null;
    if (this.u) this.u.destroy();
    this.u = new uPlot(this.options(), this.plotData(), this.container);
    if (range) this.setRange(range[0], range[1]);
    this.u.over.addEventListener('wheel', (e) => this.wheel(e), { passive: false });
    if (!this.resizeObserver) {
      this.resizeObserver = new ResizeObserver(() => {
        const w = Math.max(320, this.container.clientWidth);
        if (this.u && Math.abs(w - this.u.width) > 2) this.u.setSize({ width: w, height: 340 });
      });
      this.resizeObserver.observe(this.container);
    }
    this.publishRange();
  }

  destroy() {
    clearTimeout(this.refineTimer);
    this.inflight?.abort();
    this.resizeObserver?.disconnect();
    this.u?.destroy();
  }

  // A legend click on the commanded series keeps show.commanded (and its checkbox) in step.
  seriesToggled(i, opts) {
    if (i !== this.commandedIndex() || opts?.show === undefined || opts.show === this.show.commanded) return;
    this.show.commanded = opts.show;
    this.container.dispatchEvent(new CustomEvent('commanded-toggle', { detail: opts.show }));
  }

  setChannels(show) {
    Object.assign(this.show, show);
    this.build();
  }

  // The measured series of GET /runs/{id}/measurement, drawn dashed over Fx, Fy, Fz in their colours.
  setMeasured(series) {
    this.measured = series ? measuredColumns(series) : null;
    this.container.dataset.measuredPoints = String(this.measured ? this.measured[0].length : 0);
    this.u?.redraw(false, false);
  }

  setShaded(intervals) {
    this.shaded = intervals;
    this.u?.redraw(false, false);
  }

  select(block, t) {
    this.selected = block ? { t0: block.t_start_s, t1: block.t_end_s } : null;
    this.marker = t ?? null;
    this.u?.redraw(false, false);
  }

  xRange() {
    return [this.u.scales.x.min, this.u.scales.x.max];
  }

  // Synchronous redraw, timed from interactionStart (or now) to the end of drawing.
  setRange(from, to) {
    const t0 = this.interactionStart || performance.now();
    this.interactionStart = 0;
    const [e0, e1] = this.extent;
    const span = Math.min(e1 - e0, Math.max(to - from, 1e-6));
    let a = Math.max(e0, Math.min(from, e1 - span));
    const b = a + span;
    if (b > e1) a = e1 - span;
    this.u.batch(() => this.u.setScale('x', { min: a, max: b }));
    performance.measure('plot-frame', { start: t0, end: performance.now() });
  }

  reset() {
    this.setRange(this.extent[0], this.extent[1]);
  }

  zoom(factor, centre) {
    const [a, b] = this.xRange();
    const c = centre ?? (a + b) / 2;
    this.setRange(c - (c - a) * factor, c + (b - c) * factor);
  }

  pan(fraction) {
    const [a, b] = this.xRange();
    const d = (b - a) * fraction;
    this.setRange(a + d, b + d);
  }

  wheel(e) {
    e.preventDefault();
    this.interactionStart = performance.now();
    const [a, b] = this.xRange();
    if (e.shiftKey || Math.abs(e.deltaX) > Math.abs(e.deltaY)) {
      this.pan(Math.sign(e.deltaX || e.deltaY) * 0.1);
      return;
    }
    const rect = this.u.over.getBoundingClientRect();
    const centre = a + ((e.clientX - rect.left) / rect.width) * (b - a);
    this.zoom(e.deltaY < 0 ? 0.8 : 1.25, centre);
  }

  // uPlot's mousedown listener is passive: no preventDefault here (its overlay selects no text).
  startPan(e) {
    this.panning = true;
    const [a, b] = this.xRange();
    const x0 = e.clientX;
    const perPx = (b - a) / this.u.over.clientWidth;
    const move = (ev) => {
      this.interactionStart = performance.now();
      const d = (x0 - ev.clientX) * perPx;
      this.setRange(a + d, b + d);
    };
    const up = () => {
      this.panning = false;
      window.removeEventListener('mousemove', move);
      window.removeEventListener('mouseup', up);
    };
    window.addEventListener('mousemove', move);
    window.addEventListener('mouseup', up);
  }

  pick(e) {
    const rect = this.u.over.getBoundingClientRect();
    const t = this.u.posToVal(e.clientX - rect.left, 'x');
    this.onPick?.(t);
  }

  keydown(e) {
    const keys = {
      ArrowLeft: () => this.pan(-0.2),
      ArrowRight: () => this.pan(0.2),
      '+': () => this.zoom(0.5),
      '=': () => this.zoom(0.5),
      '-': () => this.zoom(2),
      0: () => this.reset(),
      Home: () => this.reset(),
    };
    const fn = keys[e.key];
    if (!fn) return;
    e.preventDefault();
    this.interactionStart = performance.now();
    fn();
  }

  publishRange() {
    if (!this.u || this.u.scales.x.min == null) return;   // before uPlot's first commit
    const [a, b] = this.xRange();
    this.container.dataset.xMin = String(a);
    this.container.dataset.xMax = String(b);
    this.onRange?.(a, b);
  }

  scaleChanged(u) {
    if (!this.extent) return;
    if (this.interactionStart) {
      // A drag-zoom: uPlot set the scale itself.
      performance.measure('plot-frame', { start: this.interactionStart, end: performance.now() });
      this.interactionStart = 0;
    }
    this.publishRange();
    clearTimeout(this.refineTimer);
    const scaleAt = performance.now();
    this.refineTimer = setTimeout(() => this.refine(u.scales.x.min, u.scales.x.max, scaleAt), REFINE_DELAY_MS);
  }

  // Fetches the visible window at about one bucket per pixel (actual and, with a program, commanded)
  // and splices it into the overviews.
  async refine(from, to, scaleAt) {
    const key = `${from}:${to}`;
    if (this.fetchedRange === key) return;
    this.inflight?.abort();
    this.fetchedRange = key;
    const [e0, e1] = this.extent;
    const whole = from <= e0 && to >= e1;
    const cmd = this.commanded;
    const needActual = this.decimatedOverview && !whole;
    const needCommanded = Boolean(cmd?.decimated) && !whole;
    if (!needActual && !needCommanded) {
      // The overviews already are full resolution, or the window is the whole run.
      this.published(this.decimatedOverview ? 'envelope' : 'full', from, to);
      if (cmd) this.publishedCommanded(cmd.decimated ? 'envelope' : 'full', from, to);
      if (this.currentData === this.overview && (!cmd || cmd.current === cmd.overview)) return;
      this.currentData = this.overview;
      if (cmd) cmd.current = cmd.overview;
      this.u.batch(() => {
        this.u.setData(this.plotData(), false);
        this.u.setScale('x', { min: from, max: to });
      });
      return;
    }
    const ctl = new AbortController();
    this.inflight = ctl;
    const points = Math.min(MAX_WINDOW_POINTS, Math.max(200, Math.round(this.u.over.clientWidth)));
    let w;
    let wc;
    try {
      [w, wc] = await Promise.all([
        needActual ? this.fetchWindow(from, to, points, ctl.signal) : null,
        needCommanded ? this.fetchCommanded(from, to, points, ctl.signal) : null,
      ]);
    } catch (err) {
      if (this.fetchedRange === key) this.fetchedRange = null;
      if (err.name !== 'AbortError') this.container.dispatchEvent(new CustomEvent('plot-error', { detail: err }));
      return;
    }
    if (ctl.signal.aborted) return;
    this.currentData = w ? mergeColumns(this.overview, windowColumns(w), from, to) : this.overview;
    if (cmd) cmd.current = wc ? mergeColumns(cmd.overview, seriesColumns(wc, [COMMANDED.key]), from, to) : cmd.overview;
    this.u.batch(() => {
      this.u.setData(this.plotData(), false);
      this.u.setScale('x', { min: from, max: to });
    });
    this.published(w ? (w.decimated ? 'envelope' : 'full') : 'full', from, to);
    if (cmd) this.publishedCommanded(wc ? (wc.decimated ? 'envelope' : 'full') : 'full', from, to);
    performance.measure('plot-refine', { start: scaleAt, end: performance.now() });
  }

  // What the plot holds for the visible window, as data attributes (read by the browser tests).
  published(resolution, from, to) {
    Object.assign(this.container.dataset, { resolution, windowFrom: String(from), windowTo: String(to) });
  }

  publishedCommanded(resolution, from, to) {
    Object.assign(this.container.dataset, {
      commandedResolution: resolution, commandedWindowFrom: String(from), commandedWindowTo: String(to),
    });
  }

  drawBands(u) {
    const { ctx } = u;
    const { top, height } = u.bbox;
    const band = (t0, t1, fill) => {
      const x0 = u.valToPos(t0, 'x', true);
      const x1 = u.valToPos(t1, 'x', true);
      if (x1 < u.bbox.left || x0 > u.bbox.left + u.bbox.width) return;
      ctx.fillStyle = fill;
      ctx.fillRect(x0, top, Math.max(1, x1 - x0), height);
    };
    ctx.save();
    for (const s of this.shaded) band(s.t0, s.t1, 'rgba(220, 38, 38, 0.13)');
    if (this.selected) band(this.selected.t0, this.selected.t1, 'rgba(37, 99, 235, 0.16)');
    ctx.restore();
  }

  drawOverlays(u) {
    const { ctx } = u;
    const { left, top, width, height } = u.bbox;
    const px = devicePixelRatio || 1;
    ctx.save();
    ctx.beginPath();
    ctx.rect(left, top, width, height);
    ctx.clip();
    const line = (value, scale, colour, label) => {
      if (!value || !u.scales[scale] || u.scales[scale].min == null) return;
      const y = u.valToPos(value, scale, true);
      if (y < top || y > top + height) return;
      ctx.strokeStyle = colour;
      ctx.lineWidth = 1.5 * px;
      ctx.setLineDash([8 * px, 4 * px]);
      ctx.beginPath();
      ctx.moveTo(left, y);
      ctx.lineTo(left + width, y);
      ctx.stroke();
      ctx.setLineDash([]);
      ctx.fillStyle = colour;
      ctx.textAlign = 'left';
      ctx.textBaseline = 'bottom';
      ctx.font = `${11 * px}px sans-serif`;
      ctx.fillText(label, left + 6 * px, y - 3 * px);
    };
    line(this.limits.force_N, 'N', '#b91c1c', `force limit ${this.limits.force_N} N`);
    if (this.show.torque_Nm) line(this.limits.torque_Nm, 'Nm', '#8c2d9c', `torque limit ${this.limits.torque_Nm} N·m`);
    if (this.show.power_kW) line(this.limits.power_kW, 'kW', '#e67e00', `power limit ${this.limits.power_kW} kW`);
    if (this.measured) this.drawMeasured(u, px);
    if (this.marker != null) {
      const x = u.valToPos(this.marker, 'x', true);
      ctx.strokeStyle = '#2563eb';
      ctx.lineWidth = 1.5 * px;
      ctx.beginPath();
      ctx.moveTo(x, top);
      ctx.lineTo(x, top + height);
      ctx.stroke();
    }
    ctx.restore();
  }

  drawMeasured(u, px) {
    const { ctx } = u;
    const [x, ...ys] = this.measured;
    const a = Math.max(0, lowerBound(x, u.scales.x.min) - 1);
    const b = Math.min(x.length, lowerBound(x, u.scales.x.max) + 1);
    ctx.lineWidth = 1.2 * px;
    ctx.setLineDash([5 * px, 3 * px]);
    ys.forEach((y, j) => {
      ctx.strokeStyle = CHANNELS[j].stroke;
      ctx.beginPath();
      for (let i = a; i < b; i++) {
        const cx = u.valToPos(x[i], 'x', true);
        const cy = u.valToPos(y[i], 'N', true);
        if (i === a) ctx.moveTo(cx, cy);
        else ctx.lineTo(cx, cy);
      }
      ctx.stroke();
    });
    ctx.setLineDash([]);
  }

  // The plot canvas with a white background, a title and a legend of the shown series.
  async png(title) {
    const src = this.u.ctx.canvas;
    const px = devicePixelRatio || 1;
    const head = 48 * px;
    const out = document.createElement('canvas');
    out.width = src.width;
    out.height = src.height + head;
    const ctx = out.getContext('2d');
    ctx.fillStyle = '#fff';
    ctx.fillRect(0, 0, out.width, out.height);
    ctx.fillStyle = '#111';
    ctx.font = `bold ${14 * px}px sans-serif`;
    ctx.fillText(title, 10 * px, 18 * px);
    let x = 10 * px;
    ctx.font = `${12 * px}px sans-serif`;
    const shown = CHANNELS.filter((c) => !c.optional || this.show[c.key])
      .map((c) => (this.commanded && c.key === 'f_N' ? { ...c, label: ACTUAL_LABEL } : c));
    if (this.commanded && this.show.commanded) shown.push(COMMANDED);
    shown.forEach((c) => {
      ctx.fillStyle = c.stroke;
      ctx.fillRect(x, 30 * px, 14 * px, 4 * px);
      ctx.fillStyle = '#111';
      ctx.fillText(`${c.label} (${c.unit})`, x + 18 * px, 36 * px);
      x += ctx.measureText(`${c.label} (${c.unit})`).width + 34 * px;
    });
    if (this.measured) {
      ctx.fillStyle = '#111';
      ctx.fillText('dashed: measured', x, 36 * px);
    }
    ctx.drawImage(src, 0, head);
    return new Promise((resolve) => out.toBlob(resolve, 'image/png'));
  }
}
