// The force plot: Fx, Fy, Fz and the resultant (torque and power on demand) over time, on uPlot.
//
// The whole run is held as a coarse overview (min/max envelope); the visible window is fetched
// again at about one bucket per pixel after each zoom or pan, so detail appears as you zoom while
// panning stays instant on the overview. Limit lines, flagged intervals, block names and the
// selection are drawn in uPlot's hooks on the same canvas, so the PNG export shows them too.
//
// With an NC program, the resultant predicted from the commanded motion is one more series. The
// server puts it on the actual run's time axis block by block, but its samples fall at other
// times, so it has its own overview and its own finer windows fetched beside the actual ones;
// the two are joined on the union of their times. An attached dynamometer record is drawn the
// same way: its overview, and its window at full resolution once zoomed in far enough.
//
// What the legend shows under the cursor comes from the answers themselves, not from the joined
// columns: the sample nearest the cursor at full resolution, the bucket's min–max otherwise.
//
// Each interaction records performance.measure('plot-frame') (input to drawn) and
// 'plot-paint' (input to the frame painted after the draw), and each window refinement
// 'plot-refine' (scale change to finer data drawn), for the browser tests and the bench.
import uPlot from '../vendor/uPlot.esm.js';
import { lowerBound, num } from './dom.js';

// Every line has 3:1 contrast or more against the white plot, and its own dash or width, so no
// series is told apart by colour alone (colour-blind safe: blue, vermillion, green, black).
export const CHANNELS = [
  { key: 'fx_N', label: 'Fx', unit: 'N', scale: 'N', stroke: '#0072b2', width: 1 },
  { key: 'fy_N', label: 'Fy', unit: 'N', scale: 'N', stroke: '#c2410c', width: 1, dash: [7, 3] },
  { key: 'fz_N', label: 'Fz', unit: 'N', scale: 'N', stroke: '#047857', width: 1, dash: [2, 2] },
  { key: 'f_N', label: 'F (resultant)', unit: 'N', scale: 'N', stroke: '#111111', width: 1.6 },
  { key: 'torque_Nm', label: 'Torque', unit: 'N·m', scale: 'Nm', stroke: '#6d28d9', width: 1.4, dash: [8, 3, 2, 3], optional: true },
  { key: 'power_kW', label: 'Power', unit: 'kW', scale: 'kW', stroke: '#8a5a00', width: 1.4, dash: [4, 4], optional: true },
];

export const COMMANDED = { key: 'f_N', label: 'F commanded (program)', unit: 'N', scale: 'N', stroke: '#be185d', width: 1.6, dash: [12, 4] };
const ACTUAL_LABEL = 'F actual (dry run)';
const MEASURED_DASH = [3, 2];

// The limit of each scale and its line colour.
const LIMITS = [
  { key: 'force_N', scale: 'N', label: 'force limit', unit: 'N', colour: '#b91c1c', channel: null },
  { key: 'torque_Nm', scale: 'Nm', label: 'torque limit', unit: 'N·m', colour: '#6d28d9', channel: 'torque_Nm' },
  { key: 'power_kW', scale: 'kW', label: 'power limit', unit: 'kW', colour: '#8a5a00', channel: 'power_kW' },
];

const FLAG_STRIP = '#b91c1c';      // 6.5:1 on white
const FLAG_TINT = 'rgba(185, 28, 28, 0.07)';
const SELECT_STRIP = '#1d4ed8';
const SELECT_TINT = 'rgba(29, 78, 216, 0.10)';
const OVERVIEW_POINTS = 2000;   // buckets for the whole run: more than a laptop plot has pixels
const MAX_WINDOW_POINTS = 4000;
const REFINE_DELAY_MS = 120;
// The longest window the service recomputes at full resolution (/forces?resolution=full).
export const MAX_RECOMPUTED_S = 10;
const PLOT_HEIGHT = 340;

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

// The value of channel `key` at time t in a window answer: {value} of the nearest sample at full
// resolution, {min, max} of the bucket holding t (or the nearer one across a gap) otherwise.
export function valueAt(w, key, t) {
  const n = w?.t_s?.length || 0;
  if (!n || !(key in w)) return null;
  if (t < w.t_s[0] - 1e-9 || t > (w.decimated ? w.t_end_s[n - 1] : w.t_s[n - 1]) + 1e-9) return null;
  const k = lowerBound(w.t_s, t);
  if (w.decimated) {
    let c = Math.max(0, Math.min(n - 1, k === n || w.t_s[k] > t ? k - 1 : k));
    if (t > w.t_end_s[c] && c + 1 < n && w.t_s[c + 1] - t < t - w.t_end_s[c]) c += 1;
    const { min, max } = w[key];
    return { min: min[c], max: max[c] };
  }
  let c = Math.min(n - 1, k);
  if (c > 0 && t - w.t_s[c - 1] < w.t_s[c] - t) c -= 1;
  return { value: w[key][c] };
}

// A trace: its whole-run overview answer and, once zoomed, the answer for the window [from, to].
class Trace {
  constructor(overview) {
    this.overview = overview;
    this.detail = null;
    this.range = null;
  }

  setDetail(w, from, to) {
    this.detail = w;
    this.range = w ? [from, to] : null;
  }

  at(key, t) {
    if (this.detail && t >= this.range[0] && t <= this.range[1]) return valueAt(this.detail, key, t);
    return valueAt(this.overview, key, t);
  }
}

function formatValue(v, unit) {
  if (!v) return '–';
  if ('value' in v) return v.value == null ? '–' : `${num(v.value, 4)} ${unit}`;
  if (v.min == null) return '–';
  return `${num(v.min, 4)} to ${num(v.max, 4)} ${unit}`;
}

export class ForcePlot {
  // fetchWindow(from_s, to_s, max_points, signal) -> forces window answer; fetchCommanded the same
  // for the commanded resultant (channel f_N), or null for a run without a program; fetchFull the
  // same recomputed at full resolution (for a run that stored envelopes only), or null.
  // onCursor(t or null): the time under the pointer, at most once a frame.
  constructor(container, { fetchWindow, fetchCommanded = null, fetchFull = null, limits = {}, onPick, onRange, onCursor }) {
    this.container = container;
    this.fetchWindow = fetchWindow;
    this.fetchFull = fetchFull;
    this.fetchCommanded = fetchCommanded;
    this.fetchMeasured = null;
    this.commanded = null;   // {overview, current, decimated} columns [x, f] of the commanded resultant
    this.limits = limits;
    this.onPick = onPick;
    this.onRange = onRange;
    this.onCursor = onCursor;
    this.shaded = [];        // [{t0, t1}] flagged intervals
    this.blocks = [];        // [{block, t_start_s, t_end_s}] sorted by start, for the time-axis names
    this.selected = null;    // {t0, t1} of the selected block
    this.marker = null;      // selected time
    this.show = { torque_Nm: false, power_kW: false, commanded: true };
    this.refineTimer = 0;
    this.inflight = null;
    this.inflightRange = null;
    this.fetchedRange = null;
    this.interactionStart = 0;
    this.currentData = null;
    this.measured = null;    // Trace of the attached dynamometer record
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
    this.actual = new Trace(w);
    this.overview = windowColumns(w);
    this.currentData = this.overview;
    this.decimatedOverview = w.decimated;
    if (wc) {
      const overview = seriesColumns(wc, [COMMANDED.key]);
      this.commanded = { overview, current: overview, decimated: wc.decimated, trace: new Trace(wc) };
      if (overview[0].length) this.extent = [Math.min(w.from_s, wc.from_s), Math.max(w.to_s, wc.to_s)];
    }
    this.build();
  }

  // What uPlot draws: the actual columns, joined with the commanded resultant when there is one.
  // The commanded series comes first, so it is drawn under the actual ones.
  plotData() {
    if (!this.commanded) return this.currentData;
    const data = unionColumns(this.commanded.current, this.currentData);
    this.container.dataset.commandedPoints = String(this.commanded.current[0].length);
    return data;
  }

  commandedIndex() {
    return this.commanded ? 1 : -1;
  }

  // uPlot's series index of CHANNELS[i].
  channelIndex(i) {
    return i + (this.commanded ? 2 : 1);
  }

  // Shows or hides the commanded resultant (also done by clicking its legend entry).
  setCommanded(on) {
    this.show.commanded = on;
    if (this.u && this.commanded) this.u.setSeries(this.commandedIndex(), { show: on });
  }

  // The legend's value for series si at the cursor, from the answers (see valueAt).
  legendValue(u, si) {
    const left = u.cursor.left;
    if (left == null || left < 0 || !this.actual) return '–';
    const t = u.posToVal(left, 'x');
    if (si === 0) return `${t.toFixed(4)} s`;
    if (si === this.commandedIndex()) return formatValue(this.commanded.trace.at(COMMANDED.key, t), COMMANDED.unit);
    const c = CHANNELS[si - (this.commanded ? 2 : 1)];
    return formatValue(this.actual.at(c.key, t), c.unit);
  }

  // A scale's range: the data's, widened to keep its limit line in view with some headroom.
  scaleRange(scale) {
    return (u, min, max) => {
      let lo = min;
      let hi = max;
      if (lo == null || hi == null || !Number.isFinite(lo) || !Number.isFinite(hi)) {
        lo = 0;
        hi = 1;
      }
      const lim = LIMITS.find((l) => l.scale === scale);
      const limit = lim ? this.limits[lim.key] : 0;
      if (limit > 0) hi = Math.max(hi, limit);
      const pad = (hi - Math.min(lo, 0)) * 0.07 || 1;
      return [lo < 0 ? lo - pad : Math.min(0, lo), hi + pad];
    };
  }

  options() {
    const width = Math.max(320, this.container.clientWidth);
    const showOpt = (c) => !c.optional || this.show[c.key];
    const self = this;
    const series = [{ label: 'Time', value: (u) => self.legendValue(u, 0) }];
    // Joined series have nulls where only the other one has a sample: draw across them.
    const spanGaps = Boolean(this.commanded);
    const line = (c, label, show, si) => ({
      label, scale: c.scale, stroke: c.stroke, width: c.width || 1, dash: c.dash, show, spanGaps,
      value: (u) => self.legendValue(u, si), points: { show: false },
    });
    if (this.commanded) series.push(line(COMMANDED, COMMANDED.label, this.show.commanded, this.commandedIndex()));
    CHANNELS.forEach((c, i) => series.push(line(c, this.commanded && c.key === 'f_N' ? ACTUAL_LABEL : c.label, showOpt(c), this.channelIndex(i))));
    const axes = [
      { label: 'time (s)' },
      { scale: 'N', label: 'force (N)', size: 60 },
    ];
    if (this.show.torque_Nm) axes.push({ scale: 'Nm', label: 'torque (N·m)', side: 1, grid: { show: false }, size: 60 });
    if (this.show.power_kW) axes.push({ scale: 'kW', label: 'power (kW)', side: 1, grid: { show: false }, size: 60 });
    return {
      width,
      height: PLOT_HEIGHT,
      series,
      axes,
      scales: {
        x: { time: false },
        N: { auto: true, range: this.scaleRange('N') },
        Nm: { auto: true, range: this.scaleRange('Nm') },
        kW: { auto: true, range: this.scaleRange('kW') },
      },
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
    this.u.over.addEventListener('mousemove', (e) => this.pointerMoved(e));
    this.u.over.addEventListener('mouseleave', () => this.onCursor?.(null));
    if (!this.resizeObserver) {
      this.resizeObserver = new ResizeObserver(() => {
        const w = Math.max(320, this.container.clientWidth);
        if (this.u && Math.abs(w - this.u.width) > 2) this.u.setSize({ width: w, height: PLOT_HEIGHT });
      });
      this.resizeObserver.observe(this.container);
    }
    this.publishRange();
  }

  destroy() {
    clearTimeout(this.refineTimer);
    cancelAnimationFrame(this.cursorFrame);
    this.inflight?.abort();
    this.resizeObserver?.disconnect();
    this.u?.destroy();
  }

  // The pointer's time, once a frame, only when the pointer moves (not when the view moves under
  // it: panning does not drag the listing and the 3-D view along).
  pointerMoved(e) {
    this.pointerX = e.clientX;
    if (!this.onCursor || this.cursorFrame) return;
    this.cursorFrame = requestAnimationFrame(() => {
      this.cursorFrame = 0;
      const rect = this.u.over.getBoundingClientRect();
      this.onCursor(this.u.posToVal(this.pointerX - rect.left, 'x'));
    });
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

  // The measured series of GET /runs/{id}/measurement: its overview (the answer given here) and,
  // with fetch(from, to, max_points, signal), its windows when zoomed in.
  setMeasured(series, fetch = null) {
    this.measured = series ? new Trace(series) : null;
    this.fetchMeasured = series ? fetch : null;
    this.container.dataset.measuredPoints = String(series ? series.t_s.length : 0);
    this.container.dataset.measuredResolution = series ? (series.decimated ? 'envelope' : 'full') : '';
    this.fetchedRange = null;
    if (this.u && series && this.fetchMeasured) {
      const [a, b] = this.xRange();
      if (a > this.extent[0] || b < this.extent[1]) this.refine(a, b, performance.now());
    }
    this.u?.redraw(false, false);
  }

  setShaded(intervals) {
    this.shaded = intervals;
    this.u?.redraw(false, false);
  }

  // Block names along the time axis when few enough blocks are in view.
  setBlocks(blocks) {
    this.blocks = [...blocks].sort((a, b) => a.t_start_s - b.t_start_s);
    // Running maximum of the ends: ascending, so the first block reaching into view is a search away.
    let end = -Infinity;
    this.blockReach = Float64Array.from(this.blocks, (x) => (end = Math.max(end, x.t_end_s)));
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

  // Synchronous redraw, timed from interactionStart (or now) to the end of drawing and to the
  // frame painted after it.
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
    requestAnimationFrame(() => setTimeout(() => performance.measure('plot-paint', { start: t0, end: performance.now() }), 0));
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
      const t0 = this.interactionStart;
      performance.measure('plot-frame', { start: t0, end: performance.now() });
      requestAnimationFrame(() => setTimeout(() => performance.measure('plot-paint', { start: t0, end: performance.now() }), 0));
      this.interactionStart = 0;
    }
    this.publishRange();
    // Offered again once the new range's stored answer says so (refine).
    this.setRecomputable(null, u.scales.x.min, u.scales.x.max);
    // A window still on its way is for a range the user has since left: drop it, or its arrival
    // would set the plot back to that range (under load a burst of key zooms ended at the second).
    if (this.inflight && this.inflightRange !== `${u.scales.x.min}:${u.scales.x.max}`) this.inflight.abort();
    clearTimeout(this.refineTimer);
    const scaleAt = performance.now();
    this.refineTimer = setTimeout(() => this.refine(u.scales.x.min, u.scales.x.max, scaleAt), REFINE_DELAY_MS);
  }

  // Fetches the visible window at about one bucket per pixel (actual, commanded and measured, as
  // far as each overview is coarser) and splices it into the overviews.
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
    const needMeasured = Boolean(this.measured?.overview.decimated && this.fetchMeasured) && !whole;
    if (!needActual && !needCommanded && !needMeasured) {
      // The overviews already are full resolution, or the window is the whole run.
      this.published(this.decimatedOverview ? 'envelope' : 'full', from, to);
      this.setRecomputable(null, from, to);
      if (cmd) this.publishedCommanded(cmd.decimated ? 'envelope' : 'full', from, to);
      this.actual.setDetail(null);
      cmd?.trace.setDetail(null);
      if (this.measured) {
        this.measured.setDetail(null);
        this.container.dataset.measuredResolution = this.measured.overview.decimated ? 'envelope' : 'full';
      }
      if (this.currentData === this.overview && (!cmd || cmd.current === cmd.overview)) {
        this.u.redraw(false, false);
        return;
      }
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
    this.inflightRange = key;
    const points = Math.min(MAX_WINDOW_POINTS, Math.max(200, Math.round(this.u.over.clientWidth)));
    let w;
    let wc;
    let wm;
    try {
      [w, wc, wm] = await Promise.all([
        needActual ? this.fetchWindow(from, to, points, ctl.signal) : null,
        needCommanded ? this.fetchCommanded(from, to, points, ctl.signal) : null,
        // The measured record is sampled far finer than the prediction: allow it more points.
        needMeasured ? this.fetchMeasured(from, to, 4 * points, ctl.signal).catch((e) => {
          if (e.name === 'AbortError') throw e;
          console.warn('measured window unavailable:', e);
          return null;
        }) : null,
      ]);
    } catch (err) {
      if (this.fetchedRange === key) this.fetchedRange = null;
      if (err.name !== 'AbortError') this.container.dispatchEvent(new CustomEvent('plot-error', { detail: err }));
      return;
    }
    if (ctl.signal.aborted) return;
    this.actual.setDetail(w, from, to);
    this.currentData = w ? mergeColumns(this.overview, windowColumns(w), from, to) : this.overview;
    if (cmd) {
      cmd.trace.setDetail(wc, from, to);
      cmd.current = wc ? mergeColumns(cmd.overview, seriesColumns(wc, [COMMANDED.key]), from, to) : cmd.overview;
    }
    if (this.measured) {
      this.measured.setDetail(wm, from, to);
      const m = wm || this.measured.overview;
      this.container.dataset.measuredResolution = m.decimated ? 'envelope' : 'full';
      this.container.dataset.measuredWindowPoints = String(wm ? wm.t_s.length : 0);
    }
    this.u.batch(() => {
      this.u.setData(this.plotData(), false);
      this.u.setScale('x', { min: from, max: to });
    });
    this.published(w ? (w.decimated ? 'envelope' : 'full') : 'full', from, to);
    if (cmd) this.publishedCommanded(wc ? (wc.decimated ? 'envelope' : 'full') : 'full', from, to);
    this.setRecomputable(w, from, to);
    performance.measure('plot-refine', { start: scaleAt, end: performance.now() });
  }

  // Whether the window shown can be recomputed at full resolution: the run stored envelopes only
  // there (the answer's level is above 0) and the window spans at most MAX_RECOMPUTED_S. Said by
  // data-recomputable and a 'recomputable' event (detail: true or false).
  setRecomputable(w, from, to) {
    const can = Boolean(this.fetchFull && w && w.level > 0 && to - from <= MAX_RECOMPUTED_S);
    this.container.dataset.recomputable = String(can);
    this.container.dispatchEvent(new CustomEvent('recomputable', { detail: can }));
  }

  // Recomputes the window shown at full resolution (the service walks the run before it, seconds
  // for a long run) and draws it in place of the envelopes. data-resolution becomes 'recomputed'.
  async recompute() {
    const [from, to] = this.xRange();
    this.inflight?.abort();
    const ctl = new AbortController();
    this.inflight = ctl;
    this.inflightRange = `${from}:${to}`;
    const points = Math.min(MAX_WINDOW_POINTS, Math.max(200, Math.round(this.u.over.clientWidth)));
    let w;
    try {
      w = await this.fetchFull(from, to, points, ctl.signal);
    } catch (err) {
      // The stored answer for the range shown is fetched again (the one in flight was dropped),
      // which also offers the recompute again.
      if (err.name !== 'AbortError') {
        this.fetchedRange = null;
        this.refine(from, to, performance.now());
      }
      throw err;
    }
    if (ctl.signal.aborted) return;
    this.fetchedRange = `${from}:${to}`;   // the refine the redraw schedules has nothing to fetch
    this.actual.setDetail(w, from, to);
    this.currentData = mergeColumns(this.overview, windowColumns(w), from, to);
    this.u.batch(() => {
      this.u.setData(this.plotData(), false);
      this.u.setScale('x', { min: from, max: to });
    });
    this.published('recomputed', from, to);
    this.setRecomputable(null, from, to);
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

  // Flagged blocks and the selected one: a light tint over the interval and a solid strip along
  // the top of the plot area (the strip carries the contrast; the tint only guides the eye).
  // Clipped to the plot area, so axes and their labels stay clear.
  drawBands(u) {
    const { ctx } = u;
    const { left, top, width, height } = u.bbox;
    const px = devicePixelRatio || 1;
    const strip = 5 * px;
    ctx.save();
    ctx.beginPath();
    ctx.rect(left, top, width, height);
    ctx.clip();
    const band = (t0, t1, tint, colour, row) => {
      const x0 = Math.max(left, u.valToPos(t0, 'x', true));
      const x1 = Math.min(left + width, u.valToPos(t1, 'x', true));
      if (x1 < left || x0 > left + width) return;
      const w = Math.max(1, x1 - x0);
      ctx.fillStyle = tint;
      ctx.fillRect(x0, top, w, height);
      ctx.fillStyle = colour;
      ctx.fillRect(x0, top + row * (strip + px), Math.max(2 * px, w), strip);
    };
    for (const s of this.shaded) band(s.t0, s.t1, FLAG_TINT, FLAG_STRIP, 0);
    if (this.selected) band(this.selected.t0, this.selected.t1, SELECT_TINT, SELECT_STRIP, 1);
    ctx.restore();
  }

  drawOverlays(u) {
    if (!this.drawnOnce) {
      this.drawnOnce = true;
      performance.mark('plot-drawn');   // the first draw (the bench times page load to it)
    }
    const { ctx } = u;
    const { left, top, width, height } = u.bbox;
    const px = devicePixelRatio || 1;
    ctx.save();
    ctx.beginPath();
    ctx.rect(left, top, width, height);
    ctx.clip();
    if (this.measured) this.drawMeasured(u, px);
    this.drawBlockNames(u, px);
    this.drawLimits(u, px);
    if (this.marker != null) {
      const x = u.valToPos(this.marker, 'x', true);
      ctx.strokeStyle = SELECT_STRIP;
      ctx.lineWidth = 1.5 * px;
      ctx.beginPath();
      ctx.moveTo(x, top);
      ctx.lineTo(x, top + height);
      ctx.stroke();
    }
    ctx.restore();
  }

  // Dashed limit lines across the plot, labelled at the right end; labels pushed apart so they
  // never overlap. The scales keep every limit in range (scaleRange).
  drawLimits(u, px) {
    const { ctx } = u;
    const { left, top, width, height } = u.bbox;
    const shown = LIMITS.filter((l) => this.limits[l.key] > 0 && (!l.channel || this.show[l.channel]) && u.scales[l.scale]?.min != null)
      .map((l) => ({ ...l, value: this.limits[l.key], y: u.valToPos(this.limits[l.key], l.scale, true) }));
    ctx.font = `${11 * px}px sans-serif`;
    for (const l of shown) {
      ctx.strokeStyle = l.colour;
      ctx.lineWidth = 1.5 * px;
      ctx.setLineDash([8 * px, 4 * px]);
      ctx.beginPath();
      ctx.moveTo(left, l.y);
      ctx.lineTo(left + width, l.y);
      ctx.stroke();
    }
    ctx.setLineDash([]);
    const lineH = 15 * px;
    const labels = shown.map((l) => ({ ...l, text: `${l.label} ${num(l.value)} ${l.unit}`, ly: l.y - 3 * px }))
      .sort((a, b) => a.ly - b.ly);
    for (let i = 0; i < labels.length; i++) {
      labels[i].ly = Math.max(labels[i].ly, top + lineH, i ? labels[i - 1].ly + lineH : -Infinity);
    }
    for (let i = labels.length - 1; i >= 0; i--) {
      const below = i + 1 < labels.length ? labels[i + 1].ly - lineH : top + height - 2 * px;
      labels[i].ly = Math.min(labels[i].ly, below);
    }
    ctx.textAlign = 'right';
    ctx.textBaseline = 'bottom';
    for (const l of labels) {
      const w = ctx.measureText(l.text).width;
      const x = left + width - 6 * px;
      ctx.fillStyle = 'rgba(255, 255, 255, 0.9)';
      ctx.fillRect(x - w - 3 * px, l.ly - lineH + 2 * px, w + 6 * px, lineH - 1 * px);
      ctx.fillStyle = l.colour;
      ctx.fillText(l.text, x, l.ly);
    }
    this.container.dataset.limitLabels = JSON.stringify(labels.map((l) => ({ text: l.text, y: l.ly / px, line: l.y / px })));
  }

  // Block names at their starts along the bottom of the plot, once few enough are in view.
  drawBlockNames(u, px) {
    if (!this.blocks.length) return;
    const { ctx } = u;
    const { left, top, width, height } = u.bbox;
    const [a, b] = this.xRange();
    const i0 = lowerBound(this.blockReach, a);
    const visible = [];
    for (let i = i0; i < this.blocks.length && this.blocks[i].t_start_s <= b; i++) {
      if (this.blocks[i].t_end_s >= a) visible.push(this.blocks[i]);
    }
    const cssWidth = width / px;
    if (visible.length > cssWidth / 45) {
      this.container.dataset.blockLabels = '';
      return;
    }
    ctx.font = `${11 * px}px sans-serif`;
    ctx.textAlign = 'left';
    ctx.textBaseline = 'bottom';
    let lastEnd = -Infinity;
    const drawn = [];
    for (const blk of visible) {
      const x = Math.max(left, u.valToPos(blk.t_start_s, 'x', true));
      ctx.strokeStyle = '#6b7280';
      ctx.lineWidth = px;
      ctx.setLineDash([2 * px, 3 * px]);
      ctx.beginPath();
      ctx.moveTo(x, top + 12 * px);
      ctx.lineTo(x, top + height);
      ctx.stroke();
      ctx.setLineDash([]);
      const w = ctx.measureText(blk.block).width;
      if (x + 3 * px < lastEnd) continue;
      ctx.fillStyle = 'rgba(255, 255, 255, 0.9)';
      ctx.fillRect(x + 2 * px, top + height - 16 * px, w + 4 * px, 14 * px);
      ctx.fillStyle = '#374151';
      ctx.fillText(blk.block, x + 4 * px, top + height - 3 * px);
      lastEnd = x + w + 8 * px;
      drawn.push(blk.block);
    }
    this.container.dataset.blockLabels = drawn.join(' ');
  }

  // The measured Fx, Fy, Fz in the colours of the predicted ones: an envelope as a band between
  // its bucket minima and maxima, full resolution as a dotted line.
  drawMeasured(u, px) {
    const { ctx } = u;
    const [xmin, xmax] = this.xRange();
    const m = this.measured;
    const w = m.detail && m.range[0] <= xmin + 1e-12 && m.range[1] >= xmax - 1e-12 ? m.detail : m.overview;
    const keys = ['fx_N', 'fy_N', 'fz_N'];
    const n = w.t_s.length;
    const a = Math.max(0, lowerBound(w.t_s, xmin) - 1);
    const b = Math.min(n, lowerBound(w.t_s, xmax) + 1);
    keys.forEach((key, j) => {
      const colour = CHANNELS[j].stroke;
      ctx.strokeStyle = colour;
      ctx.lineWidth = 1.2 * px;
      if (w.decimated) {
        const { min, max } = w[key];
        ctx.beginPath();
        for (let i = a; i < b; i++) {
          const cx = u.valToPos((w.t_s[i] + w.t_end_s[i]) / 2, 'x', true);
          const cy = u.valToPos(max[i], 'N', true);
          if (i === a) ctx.moveTo(cx, cy);
          else ctx.lineTo(cx, cy);
        }
        for (let i = b - 1; i >= a; i--) ctx.lineTo(u.valToPos((w.t_s[i] + w.t_end_s[i]) / 2, 'x', true), u.valToPos(min[i], 'N', true));
        ctx.closePath();
        ctx.globalAlpha = 0.18;
        ctx.fillStyle = colour;
        ctx.fill();
        ctx.globalAlpha = 1;
        ctx.setLineDash(MEASURED_DASH.map((d) => d * px));
        ctx.stroke();
      } else {
        ctx.setLineDash(MEASURED_DASH.map((d) => d * px));
        ctx.beginPath();
        for (let i = a; i < b; i++) {
          const cx = u.valToPos(w.t_s[i], 'x', true);
          const cy = u.valToPos(w[key][i], 'N', true);
          if (i === a) ctx.moveTo(cx, cy);
          else ctx.lineTo(cx, cy);
        }
        ctx.stroke();
      }
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
      ctx.strokeStyle = c.stroke;
      ctx.lineWidth = 2 * px;
      ctx.setLineDash((c.dash || []).map((d) => d * px));
      ctx.beginPath();
      ctx.moveTo(x, 32 * px);
      ctx.lineTo(x + 18 * px, 32 * px);
      ctx.stroke();
      ctx.setLineDash([]);
      ctx.fillStyle = '#111';
      ctx.fillText(`${c.label} (${c.unit})`, x + 22 * px, 36 * px);
      x += ctx.measureText(`${c.label} (${c.unit})`).width + 38 * px;
    });
    if (this.measured) {
      ctx.fillStyle = '#111';
      ctx.fillText('dotted, bands: measured', x, 36 * px);
    }
    ctx.drawImage(src, 0, head);
    return new Promise((resolve) => out.toBlob(resolve, 'image/png'));
  }
}
