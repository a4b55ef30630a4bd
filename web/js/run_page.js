// A run: live progress while it computes (polling the run), then what a shop engineer asks first:
// the worst blocks (which block overloads, by how much, where, with its NC text), the force plot
// beside the NC listing, the 3-D view of the stock, tool and path, the block table, the program
// comparison and feed optimization, the measurement and the run's alerts. Selecting a block
// anywhere selects it everywhere and zooms the plot to it; the plot cursor moves the listing and
// the tool in the 3-D view.
import { api } from './api.js';
import { h, clear, num, seconds, when, download, statusLine, errorText, lowerBound } from './dom.js';
import { loadLibraries, toolLabel, stateBadge } from './runs.js';
import { LiveView } from './live_view.js';
import { ForcePlot, MAX_RECOMPUTED_S } from './force_plot.js';
import { BlockTable, withComparison } from './block_table.js';
import { programSection, optimizePanel } from './program.js';
import { alertTable } from './alerts.js';
import { problemsPanel, worstLoad } from './problems.js';
import { Listing, programRows, blockRows } from './listing.js';
import { flagLabel, warningText, QUANTITIES } from './labels.js';
import { setTitle } from './title.js';
import { toolAxisText, motionAxes } from './tool_axis.js';

const POLL_MS = 250;   // the server updates progress at most every 250 ms
const MIN_BLOCK_SPAN_S = 1e-3;
const PATH_POINTS = 6000;
const STOCK_CELLS = 40000;

// The five-axis machine the log's axes went through, and how the tool stood against the part. An
// axis component below 5e-7 is the rotation's rounding (6e-17 for a 0), shown as 0.
function kinematicsText(run) {
  const k = run.inputs?.kinematics;
  if (!k) return '–';
  const o = run.summary?.kinematics;
  const stand = !o ? '' : o.turning
    ? `; tool turning while it cuts (simultaneous five-axis), leaning up to ${num(o.tool_lean_deg)}° from the stock's +Z (its axis per row: FORCES.csv tool_axis_x, _y, _z)`
    : o.fixed_tilt
      ? `; tool tilted ${num(o.tool_lean_deg)}° from the stock's +Z, axis (${o.tool_axis.map((v) => num(Math.abs(v) < 5e-7 ? 0 : v)).join(', ')}), fixed while it cuts (3+2)`
      : '; tool vertical to the stock';
  return `${k.filename}${k.errors ? ' with geometric errors' : ''}, tool length ${num(k.tool_length_mm)} mm${stand}`;
}

function meta(run, lib) {
  const spec = run.inputs?.spec || {};
  const material = run.material_id ? lib.byId('materials', run.material_id)?.name : spec.material?.name;
  const machine = run.machine_id ? lib.byId('machines', run.machine_id)?.name ?? `#${run.machine_id}` : '–';
  const rows = [
    ['Log', `${run.inputs?.log?.filename || '–'} (${run.inputs?.ingest?.rows ?? '?'} rows, ${seconds(run.inputs?.ingest?.duration_s)})`],
    ['Program', run.program || '–'],
    ['NC program', run.inputs?.nc_program ? `${run.inputs.nc_program.filename} (${num(run.inputs.nc_program.bytes / 1024)} KiB)` : '–'],
    ['Machine', machine],
    ['Kinematics', kinematicsText(run)],
    ['Tool', toolLabel(run, lib)],
    ['Material', material || '–'],
    ['Base run', run.base_run ? h('a', { href: `#/runs/${run.base_run}` }, `#${run.base_run}`) : '–'],
    ['Created', when(run.created_at)],
    ['Finished', when(run.finished_at)],
  ];
  return h('dl', { class: 'meta' }, rows.map(([k, v]) => [h('dt', {}, k), h('dd', {}, v)]));
}

// The log's warnings (inputs.ingest.warnings), in plain words with the server's detail.
function logWarnings(run) {
  const list = run.inputs?.ingest?.warnings || [];
  if (!list.length) return null;
  return h('section', { class: 'log-warnings', id: 'log-warnings', 'aria-labelledby': 'log-warnings-title' },
    h('h2', { id: 'log-warnings-title' }, `The log had ${list.length === 1 ? 'a problem' : `${list.length} problems`} (the prediction used the repaired log)`),
    h('ul', {}, list.map((w) => {
      const t = warningText(w);
      return h('li', { dataset: { code: w.code } }, h('strong', {}, t.plain), h('br'), h('span', { class: 'muted' }, t.detail));
    })));
}

function summaryCards(s, limits) {
  const card = (label, value, limit, unit) => h('div', { class: `card${limit && value > limit ? ' over' : ''}` },
    h('span', { class: 'card-label' }, label),
    h('span', { class: 'card-value' }, `${num(value)} ${unit}`),
    limit ? h('span', { class: 'card-limit' }, `limit ${num(limit)} ${unit} (${num((100 * value) / limit)} %)`) : h('span', { class: 'card-limit' }, 'no limit set'));
  return h('div', { class: 'cards', 'aria-label': 'Summary' },
    card('Peak force', s.peak_force_N, limits.force_N, 'N'),
    card('Peak torque', s.peak_torque_Nm, limits.torque_Nm, 'N·m'),
    card('Peak power', s.peak_power_kW, limits.power_kW, 'kW'),
    card('Max chip thickness', s.max_chip_mm, limits.chip_mm, 'mm'),
    card('Max bending stress', s.max_bending_MPa, limits.bending_MPa, 'MPa'),
    h('div', { class: `card${s.flagged_blocks ? ' over' : ''}` }, h('span', { class: 'card-label' }, 'Flagged blocks'),
      h('span', { class: 'card-value', id: 'flagged-count' }, `${s.flagged_blocks} of ${s.blocks}`)),
    h('div', { class: 'card' }, h('span', { class: 'card-label' }, 'Computed in'),
      h('span', { class: 'card-value' }, `${num(s.compute_s)} s`), h('span', { class: 'card-limit' }, `${s.samples} samples, ${s.device}`)));
}

// The comparison metrics of an attached dynamometer record: overall per axis, per block folded.
function metricsTable(report) {
  const axes = [['x', 'Fx'], ['y', 'Fy'], ['z', 'Fz'], ['resultant', '|F|']];
  const head = ['Axis', 'Mean error (N)', 'RMSE (N)', 'NRMSE', 'Peak error (N)', 'Correlation'];
  const cells = (m) => [num(m.mean_error_N), num(m.rmse_N), num(m.nrmse), num(m.peak_error_N), num(m.correlation)].map((v) => h('td', {}, v));
  const overall = h('table', { class: 'metrics', id: 'measurement-metrics' },
    h('caption', {}, `Predicted minus measured over the whole record (${report.measured.file}, ${num(report.measured.rate_Hz)} Hz, offset ${num(report.offset_s)} s ${report.offset_source})`),
    h('thead', {}, h('tr', {}, head.map((c) => h('th', { scope: 'col' }, c)))),
    h('tbody', {}, axes.map(([k, label]) => h('tr', {}, h('th', { scope: 'row' }, label), cells(report.overall[k])))));
  const perBlock = h('details', { class: 'per-block-metrics' },
    h('summary', {}, `Per block (${report.blocks.length} blocks, resultant)`),
    h('div', { class: 'table-scroll' }, h('table', { class: 'metrics', id: 'measurement-block-metrics' },
      h('thead', {}, h('tr', {}, ['Block', ...head.slice(1)].map((c) => h('th', { scope: 'col' }, c)))),
      h('tbody', {}, report.blocks.map((b) => h('tr', {}, h('th', { scope: 'row' }, b.scope), cells(b.resultant)))))));
  return h('div', {}, overall, perBlock);
}

// "Attach measurement": a dynamometer file and its axis matrix; the comparison once attached.
function measurementSection(id, plot) {
  const file = h('input', { type: 'file', id: 'measurement-file', accept: '.csv,.txt', 'aria-describedby': 'measurement-file-err' });
  const axes = h('input', { type: 'text', id: 'measurement-axes', placeholder: '1,0,0,0,1,0,0,0,1', size: 24 });
  const err = h('span', { class: 'field-error', id: 'measurement-file-err', role: 'alert' });
  const result = h('div', { id: 'measurement-result' });
  const fetchWindow = (from_s, to_s, max_points, signal) => api.measurement(id, { from_s, to_s, max_points }, signal).then((r) => r.series);
  const show = (cmp) => {
    plot.setMeasured(cmp ? cmp.series : null, cmp ? fetchWindow : null);
    clear(result, cmp ? metricsTable(cmp.report) : h('p', { class: 'muted' }, 'No measurement attached.'));
  };
  const load = async () => {
    try {
      show(await api.measurement(id, { max_points: 4000 }));
    } catch (e) {
      if (e.status !== 404) err.textContent = errorText(e);
      show(null);
    }
  };
  const attach = async () => {
    err.textContent = '';
    file.removeAttribute('aria-invalid');
    if (!file.files.length) {
      err.textContent = 'Choose the dynamometer file (a DynoWare CSV export or a plain CSV with t, fx, fy, fz).';
      file.setAttribute('aria-invalid', 'true');
      return;
    }
    const form = new FormData();
    form.append('file', file.files[0], file.files[0].name);
    if (axes.value.trim()) form.append('axes', axes.value.trim());
    try {
      await api.attachMeasurement(id, form);
      await load();
    } catch (e) {
      err.textContent = errorText(e);
      file.setAttribute('aria-invalid', 'true');
    }
  };
  const section = h('section', { class: 'measurement', 'aria-labelledby': 'measurement-title' },
    h('h2', { id: 'measurement-title' }, 'Measurement'),
    h('p', { class: 'hint muted' }, 'Measured Fx, Fy, Fz appear on the plot dotted in the colours of the predicted ones (force on the tool, machine axes): a band from minimum to maximum where the view holds more samples than pixels, the samples themselves when zoomed in.'),
    h('div', { class: 'measurement-form' },
      h('label', { for: 'measurement-file' }, 'Dynamometer file '), file,
      h('label', { for: 'measurement-axes' }, ' Axis matrix (dynamometer to machine, row by row) '), axes,
      h('button', { type: 'button', onclick: attach }, 'Attach measurement'), err),
    result);
  return { section, load };
}

// What the alerts box says when the run raised none.
function noAlertsText(run) {
  const flags = run.summary?.flags || {};
  const unknownTool = flags.unknown_tool || 0;
  const limitFlags = Object.entries(flags).some(([k, n]) => k !== 'unknown_tool' && n > 0);
  if (unknownTool && !limitFlags) {
    return `${unknownTool} block(s) ran with a tool the run spec's tool table does not have: no forces were predicted there. `
      + 'That is not a limit, so it raises no alert unless a threshold on it (Tool not in the run spec) applies to this run.';
  }
  if (run.summary?.flagged_blocks) {
    return `${run.summary.flagged_blocks} block(s) exceed the run's limits (see Worst blocks first), but no alert was raised: `
      + 'this server raises none for a run\'s own limits (cutload serve --no-limit-alerts) and no threshold in the libraries applies to this run.';
  }
  return 'No alerts were raised for this run.';
}

// Load / limit per path point from the plot's overview (force, torque and power, whichever is
// highest against its limit); without any limit, load / the run's peak force.
function pathLoad(points, plot, limits) {
  const cols = plot.overview;   // [x, fx, fy, fz, f, torque, power] (envelope pairs)
  const [x, , , , f, torque, power] = cols;
  const parts = [[f, limits.force_N], [torque, limits.torque_Nm], [power, limits.power_kW]].filter(([, l]) => l > 0);
  let relative = false;
  if (!parts.length) {
    let peak = 0;
    for (const v of f) peak = Math.max(peak, v);
    parts.push([f, peak || 1]);
    relative = true;
  }
  const at = (col, i) => Math.max(col[Math.max(0, i - 1)] || 0, col[Math.min(col.length - 1, i)] || 0);
  const ratio = Float32Array.from(points.t, (t) => {
    const i = lowerBound(x, t);
    let r = 0;
    for (const [col, lim] of parts) r = Math.max(r, at(col, i) / lim);
    return r;
  });
  return { ratio, relative };
}

// Motion window answer -> {t, x, y, z} in stock coordinates, and axis (a turning tool's axis
// per point, tool_axis.js motionAxes) where the answer carries it; buckets of a decimated answer
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
  const axis = motionAxes(w);
  return axis ? { t, ...p, axis } : { t, ...p };
}

// The 3-D view section: loads three.js and the stock only now, so the plot never waits for them.
// The run spec's tool at time t from the blocks' tools and the spec's tool table (null: none known).
function toolAtTime(spec, blocks) {
  const table = spec?.tools;
  if (!table?.length) return null;
  const byStart = blocks.filter((b) => b.tool != null).sort((a, b) => a.t_start_s - b.t_start_s);
  const starts = byStart.map((b) => b.t_start_s);
  return (t) => {
    const i = lowerBound(starts, t + 1e-12) - 1;
    const b = byStart[Math.max(0, i)];
    return b ? table.find((x) => x.number === b.tool) || null : null;
  };
}

function view3dSection(run, disposers, blocks = []) {
  const box = h('div', { class: 'view3d', id: 'view3d' });
  const status = statusLine('Loading the 3-D view…');
  const legend = h('div', { class: 'path-legend', id: 'path-legend' });
  const controls = h('div', { class: 'plot-controls', role: 'toolbar', 'aria-label': '3-D view controls' });
  const section = h('section', { class: 'path', 'aria-labelledby': 'path-title' },
    h('div', { class: 'section-head' }, h('h2', { id: 'path-title' }, 'Stock, tool and path'),
      h('span', { class: 'muted' }, 'Drag to orbit, wheel to zoom, right-drag to pan; click the path to select its time.')),
    controls, box, legend, status);
  let view = null;
  const pending = { time: undefined, block: undefined };
  async function load({ plot, onPick }) {
    try {
      const loadStarted = performance.now();
      const [{ View3D, webglAvailable, fieldHeights, LOAD_CLASSES, CONTINUOUS_STOPS, TOOL_AXIS_COLOUR }, motion, field, baseField] = await Promise.all([
        import('./view3d.js'),
        api.motion(run.id, { max_points: PATH_POINTS }),
        api.stock(run.id, { max_cells: STOCK_CELLS }),
        run.base_run ? api.stock(run.base_run, { max_cells: STOCK_CELLS }).catch(() => null) : null,
      ]);
      if (!webglAvailable()) {
        status.textContent = 'This browser cannot draw 3-D (WebGL is off); the worst blocks and the block table list the same data.';
        return;
      }
      const started = performance.now();
      const points = pathPoints(motion, run.inputs?.spec?.setup?.offset_mm);
      const { ratio, relative } = pathLoad(points, plot, run.inputs?.spec?.limits || {});
      const sameGrid = baseField && baseField.nx === field.nx && baseField.ny === field.ny && baseField.cell_mm === field.cell_mm;
      view = new View3D(box, {
        field, path: points, ratio, relative, onPick,
        tool: run.inputs.spec.tool || run.inputs.spec.tools?.[0], toolAt: toolAtTime(run.inputs.spec, blocks),
        startTop: sameGrid ? fieldHeights(baseField) : null, kinematics: run.summary?.kinematics,
      });
      disposers.push(() => view.destroy());
      box.view3d = view;   // for the bench, which turns the view frame by frame
      box.dataset.buildMs = String(performance.now() - started);
      view.render();
      // To the frame painted with it (the render only queues the drawing).
      await new Promise((r) => requestAnimationFrame(() => setTimeout(r, 0)));
      box.dataset.firstDrawMs = String(performance.now() - started);
      box.dataset.loadToFirstDrawMs = String(performance.now() - loadStarted);
      box.dataset.ready = 'true';
      const btn = (label, fn, attrs = {}) => h('button', { type: 'button', onclick: fn, ...attrs }, label);
      const measure = btn('Measure', () => {
        const on = measure.getAttribute('aria-pressed') !== 'true';
        measure.setAttribute('aria-pressed', String(on));
        view.setMeasuring(on);
      }, { 'aria-pressed': 'false', id: 'measure-toggle' });
      const mode = h('select', { id: 'path-colour', 'aria-label': 'Path colour' },
        h('option', { value: 'classes' }, 'Path colour: under 80 %, 80–100 %, over the limit'),
        h('option', { value: 'continuous' }, 'Path colour: continuous scale'));
      mode.addEventListener('change', () => {
        view.setColourMode(mode.value);
        showLegend(mode.value);
      });
      clear(controls,
        btn('Iso', () => view.setView('iso')), btn('Top (X-Y)', () => view.setView('top')),
        btn('Front (X-Z)', () => view.setView('front')), btn('Side (Y-Z)', () => view.setView('side')),
        btn('Whole stock', () => view.setView('iso', 'stock'), { title: 'Frame the whole stock (the view starts on the region the tool cuts)' }),
        h('span', { class: 'sep' }), mode, measure,
        btn('Final stock', () => view.setTime(null), { title: 'Show the final stock without the tool' }));
      const limitWord = relative ? 'of the peak force (no limit set)' : 'of the limit';
      const axisText = toolAxisText(run.summary?.kinematics, { perSample: Boolean(points.axis) });
      const showLegend = (m) => {
        if (m === 'continuous') {
          clear(legend, h('span', {}, '0 %'),
            h('span', { class: 'ramp', style: `background: linear-gradient(to right, ${CONTINUOUS_STOPS.join(',')})` }),
            h('span', {}, `120 % ${limitWord}`));
        } else {
          clear(legend, LOAD_CLASSES.map((c) => h('span', { class: 'key' },
            h('span', { class: 'swatch', style: `border-top: 2px ${c.dashed ? 'dashed' : 'solid'} ${c.colour}` },
              c.marker ? h('span', { class: 'marker', style: `background: ${c.colour}` }) : null),
            c.key === 'air' ? c.label : c.label.replace('of the limit', limitWord))));
        }
        legend.append(h('span', { class: 'muted' }, ` Stock ${num(field.box_mm.max[0] - field.box_mm.min[0])} × ${num(field.box_mm.max[1] - field.box_mm.min[1])} × ${num(field.box_mm.max[2] - field.box_mm.min[2])} mm, shown in ${num(field.cell_mm)} mm cells.`));
        // A turning tool's axis along the path: its strokes' key.
        if (points.axis) {
          legend.append(h('span', { class: 'key' },
            h('span', { class: 'swatch', style: `border-top: 2px solid ${TOOL_AXIS_COLOUR}` }), 'tool axis along the path'));
        }
        // A tilted tool reads wrong against the X, Y, Z of the view unless its axis is said too.
        if (axisText) legend.append(h('span', { class: 'tool-axis', id: 'tool-axis' }, axisText));
      };
      showLegend('classes');
      status.textContent = '';
      if (pending.block !== undefined) view.select(pending.block);
      if (pending.time !== undefined) view.setTime(pending.time);
    } catch (e) {
      status.textContent = `Could not draw the 3-D view: ${errorText(e)}`;
    }
  }
  return {
    section,
    load,
    setTime: (t) => (view ? view.setTime(t) : (pending.time = t)),
    select: (b) => (view ? view.select(b) : (pending.block = b)),
    view: () => view,
  };
}

async function showResults(body, run, lib, disposers) {
  const id = run.id;
  const limits = run.inputs?.spec?.limits || {};
  const status = statusLine('Loading results…');
  clear(body, status);
  const plotBox = h('div', { class: 'plot', id: 'force-plot', tabindex: 0, role: 'group',
    'aria-label': 'Force plot. Left and right arrows pan, plus and minus zoom, 0 shows the whole run.' });
  const rangeText = h('span', { class: 'range', id: 'plot-range', 'aria-live': 'polite' });
  const selText = h('p', { class: 'selection', id: 'selection', 'aria-live': 'polite' }, 'Click the plot, the path or a block to select it.');
  let blocks = [];
  let listing = null;
  let view3d = null;
  let table = null;
  const comparing = Boolean(run.links?.program);
  const plot = new ForcePlot(plotBox, {
    fetchWindow: (from_s, to_s, max_points, signal) => api.forces(id, { from_s, to_s, max_points }, signal),
    fetchFull: (from_s, to_s, max_points, signal) => api.forces(id, { from_s, to_s, max_points, resolution: 'full' }, signal),
    fetchCommanded: comparing ? (from_s, to_s, max_points, signal) => api.commandedForces(id, { from_s, to_s, max_points }, signal) : null,
    limits,
    onPick: (t) => selectTime(t),
    onRange: (a, b) => {
      rangeText.textContent = `${a.toFixed(4)} – ${b.toFixed(4)} s`;
    },
    onCursor: (t) => {
      if (t == null) return;
      listing?.highlight(blockAt(t)?.block ?? null);
      view3d?.setTime(t);
    },
  });
  disposers.push(() => plot.destroy());
  plotBox.addEventListener('plot-error', (e) => {
    status.textContent = `Could not load finer data: ${errorText(e.detail)}`;
  });

  const channel = (key, label) => {
    const box = h('input', { type: 'checkbox', id: `show-${key}` });
    box.addEventListener('change', () => plot.setChannels({ [key]: box.checked }));
    return h('label', { class: 'inline' }, box, ` ${label}`);
  };
  // Symbol buttons are named by their title; worded ones by their words.
  const btn = (label, title, fn) => h('button', { type: 'button', title, 'aria-label': label.length === 1 ? title : null, onclick: fn }, label);
  // The commanded resultant starts shown; its legend entry toggles it too.
  const commandedBox = h('input', { type: 'checkbox', id: 'show-commanded', checked: true });
  commandedBox.addEventListener('change', () => plot.setCommanded(commandedBox.checked));
  plotBox.addEventListener('commanded-toggle', (e) => {
    commandedBox.checked = e.detail;
  });
  const exportStatus = h('span', { class: 'muted', role: 'status' });
  // A long run stores envelopes (min/max of 64 rows) rather than every row: a window of up to 10 s
  // can be predicted again, every row, on request (docs/api.md, "Recomputed windows").
  const fullButton = h('button', {
    type: 'button', id: 'plot-full', disabled: true,
    title: `This run stored envelopes only: predict the window shown again at full resolution (at most ${MAX_RECOMPUTED_S} s; takes a few seconds for a long run)`,
    onclick: async () => {
      fullButton.disabled = true;
      exportStatus.textContent = 'Recomputing the window at full resolution…';
      try {
        await plot.recompute();
        exportStatus.textContent = '';
      } catch (e) {
        // Left for another range (the request was dropped): nothing to say.
        exportStatus.textContent = e.name === 'AbortError' ? '' : errorText(e);
      }
    },
  }, 'Full resolution');
  plotBox.addEventListener('recomputable', (e) => {
    fullButton.disabled = !e.detail;
  });
  const controls = h('div', { class: 'plot-controls', role: 'toolbar', 'aria-label': 'Plot controls' },
    channel('torque_Nm', 'Torque'), channel('power_kW', 'Power'),
    comparing ? h('label', { class: 'inline' }, commandedBox, ' Commanded (program)') : null,
    h('span', { class: 'sep' }),
    btn('−', 'Zoom out', () => plot.zoom(2)), btn('+', 'Zoom in', () => plot.zoom(0.5)),
    btn('◀', 'Pan left', () => plot.pan(-0.25)), btn('▶', 'Pan right', () => plot.pan(0.25)),
    btn('Whole run', 'Show the whole run', () => plot.reset()),
    fullButton,
    h('span', { class: 'sep' }),
    btn('Export CSV', 'Download the visible window as CSV', async () => {
      const [a, b] = plot.xRange();
      exportStatus.textContent = 'Preparing CSV…';
      // What the plot shows: recomputed rows when it shows them for this very range.
      const d = plotBox.dataset;
      const recomputed = d.resolution === 'recomputed' && Number(d.windowFrom) === a && Number(d.windowTo) === b;
      try {
        const csv = await api.forcesCsv(id, { from_s: a, to_s: b, max_points: 20000, resolution: recomputed ? 'full' : undefined });
        download(`run-${id}-forces-${a.toFixed(3)}-${b.toFixed(3)}.csv`, new Blob([csv], { type: 'text/csv' }));
        exportStatus.textContent = '';
      } catch (e) {
        exportStatus.textContent = errorText(e);
      }
    }),
    btn('Export PNG', 'Download the plot as PNG', async () => {
      download(`run-${id}-forces.png`, await plot.png(`Run #${id} ${run.name || ''}: cutting forces`));
    }),
    exportStatus);

  // The page's frame first, the plot in it, so the plot draws at its width as soon as its data
  // is in; the worst blocks, the listing and the rest fill in when the blocks and the program
  // arrive (fetched at the same time).
  const problemsBox = h('div');
  const listingBox = h('div', { class: 'listing-box' });
  const restBox = h('div');
  clear(body,
    logWarnings(run),
    summaryCards(run.summary, limits),
    problemsBox,
    h('section', { class: 'forces', 'aria-labelledby': 'forces-title' },
      h('div', { class: 'section-head' }, h('h2', { id: 'forces-title' }, 'Forces'), h('span', { class: 'muted' }, 'Showing '), rangeText),
      controls,
      h('p', { class: 'hint muted' }, 'Drag to zoom into a range, wheel to zoom, Shift-drag or Shift-wheel to pan, double-click for the whole run. Red strip on top: flagged blocks; blue strip: the selected block; dashed lines: limits.',
        comparing ? ' Magenta dashed: the resultant predicted from the programmed motion, each block drawn over the time the machine took for it.' : ''),
      h('div', { class: 'plot-and-listing' }, plotBox, listingBox),
      selText),
    restBox, status);
  const plotReady = plot.load();
  const [runBlocks, program, source] = await Promise.all([api.blocks(id),
    comparing ? api.program(id).catch((error) => ({ error })) : null,
    comparing ? api.text(`/api/v1/runs/${id}/program/source`).catch(() => null) : null]);
  const compared = Boolean(program && !program.error);
  blocks = compared ? withComparison(runBlocks, program.blocks) : runBlocks;
  const rows = compared && source != null && program.blocks.some((b) => b.line) ? programRows(source, program.blocks) : null;
  if (rows) {
    const textOf = new Map();
    for (const r of rows) if (r.block && !textOf.has(r.block)) textOf.set(r.block, r.text.trim());
    blocks = blocks.map((b) => ({ ...b, nc_text: textOf.get(b.block) ?? null }));
  }
  const byStart = [...blocks].sort((a, b) => a.t_start_s - b.t_start_s);
  const starts = Float64Array.from(byStart, (b) => b.t_start_s);
  function blockAt(t) {
    const i = lowerBound(starts, t + 1e-12) - 1;
    for (let k = i; k >= Math.max(0, i - 3); k--) if (t >= byStart[k].t_start_s && t <= byStart[k].t_end_s) return byStart[k];
    return null;
  }

  const flaggedNames = new Set(blocks.filter((b) => b.flags.length).map((b) => b.block));
  listing = new Listing(listingBox, rows
    ? { title: `NC program ${run.inputs?.nc_program?.filename || ''}`, rows, flagged: flaggedNames, onSelect: (name) => selectByName(name) }
    : { title: 'Blocks of the log', rows: blockRows(blocks), flagged: flaggedNames, onSelect: (name) => selectByName(name),
      caption: comparing ? 'The program text is not available for this run.' : 'No NC program attached: the log\'s block names.' });

  const problems = problemsPanel(blocks, limits, { ncText: (name) => listing.textOf(name), onSelect: (b) => selectBlock(b, null, true) });
  const threeD = view3dSection(run, disposers, blocks);
  view3d = threeD;
  const tableBox = h('div');
  const optimizer = comparing ? optimizePanel(run, { blocks }) : null;
  if (optimizer) disposers.push(optimizer.dispose);
  const measurementBox = measurementSection(id, plot);
  const alertsBox = h('section', { class: 'run-alerts', 'aria-labelledby': 'run-alerts-title' },
    h('h2', { id: 'run-alerts-title' }, 'Alerts'));
  problemsBox.append(problems.section);
  restBox.append(threeD.section, tableBox, program ? programSection(run, program) : '',
    optimizer?.section || '', measurementBox.section, alertsBox);

  await plotReady;
  status.textContent = '';
  plot.setShaded(blocks.filter((b) => b.flags.length).map((b) => ({ t0: b.t_start_s, t1: b.t_end_s })));
  plot.setBlocks(blocks);
  table = new BlockTable(tableBox, blocks, {
    onSelect: (b) => selectBlock(b, null, true),
    comparison: compared,
    onToolFilter: (tool) => showTool(tool),
  });

  // The plot follows the tool filter: the span of that tool's blocks (a tool runs in one stretch
  // between its changes), the whole run for all tools.
  function showTool(tool) {
    const mine = blocks.filter((b) => String(b.tool) === tool);
    if (!tool || !mine.length) {
      plot.reset();
      return;
    }
    plot.setRange(Math.min(...mine.map((b) => b.t_start_s)), Math.max(...mine.map((b) => b.t_end_s)));
  }

  function selectBlock(b, t, zoom) {
    table?.select(b ? b.idx : null);
    plot.select(b, t);
    view3d?.select(b);
    listing?.select(b ? b.block : null);
    for (const li of document.querySelectorAll('#problem-list li')) li.classList.toggle('selected', Boolean(b) && li.dataset.block === b.block);
    const at = t == null ? '' : `t = ${t.toFixed(4)} s, `;
    const load = b ? worstLoad(b, limits) : null;
    const loadText = load ? `, ${QUANTITIES[load.quantity].label.toLowerCase()} ${num(100 * load.ratio)} % of its limit` : '';
    selText.textContent = b
      ? `Selected ${at}block ${b.block} (${b.t_start_s.toFixed(4)}–${b.t_end_s.toFixed(4)} s, peak force ${num(b.peak_force_N)} N${loadText}${b.flags.length ? `; ${b.flags.map((f) => flagLabel(f.flag)).join(', ')}` : ''})`
      : `Selected t = ${t?.toFixed(4)} s (no block)`;
    if (zoom && b) {
      const mid = (b.t_start_s + b.t_end_s) / 2;
      const half = Math.max(b.t_end_s - b.t_start_s, MIN_BLOCK_SPAN_S) / 2;
      plot.setRange(mid - half, mid + half);
      view3d?.setTime(b.t_start_s);
    }
  }
  function selectTime(t) {
    const b = blocks.find((x) => t >= x.t_start_s && t <= x.t_end_s) || null;
    selectBlock(b, t, false);
    view3d?.setTime(t);
  }
  function selectByName(name) {
    const b = blocks.find((x) => x.block === name);
    if (b) selectBlock(b, null, true);
  }

  if (run.summary?.alerts) alertTable(alertsBox, () => ({ run_id: id }), { showRun: false });
  else alertsBox.append(h('p', { class: 'muted', id: 'no-alerts' }, noAlertsText(run)));

  // The rest after the plot is up: the measurement, the newest optimization, and the 3-D view
  // once its section comes into view (loading three.js and building the scene would hold up the
  // plot's first interactions otherwise).
  const loads = [measurementBox.load(), optimizer?.load()];
  await new Promise((resolve) => {
    const seen = new IntersectionObserver((entries) => {
      if (!entries.some((e) => e.isIntersecting)) return;
      seen.disconnect();
      resolve();
    });
    seen.observe(threeD.section);
    disposers.push(() => {
      seen.disconnect();
      resolve();
    });
  });
  if (!body.isConnected) return;
  await Promise.all([threeD.load({ plot, onPick: (t) => selectTime(t) }), ...loads]);
}

export async function renderRun(main, id) {
  const lib = await loadLibraries();
  const title = h('h1', {}, `Run #${id}`);
  const badge = h('span');
  const actions = h('div', { class: 'actions' });
  const metaBox = h('div');
  const progress = h('progress', { id: 'run-progress', max: 100, 'aria-labelledby': 'progress-label' });
  const progressLabel = h('span', { id: 'progress-label' });
  const progressBox = h('div', { class: 'progress', hidden: true }, progressLabel, progress);
  const errorBox = h('p', { class: 'form-error', role: 'alert', hidden: true });
  const body = h('div', { class: 'results' });
  clear(main, h('div', { class: 'page-head' }, title, badge, actions), metaBox, progressBox, errorBox, body);

  const disposers = [];
  let stopped = false;
  let timer = 0;
  let shown = false;
  let live = null;   // the live view while the run is live

  const action = (label, fn) => h('button', {
    type: 'button',
    onclick: async () => {
      try {
        await fn();
      } catch (e) {
        errorBox.hidden = false;
        errorBox.textContent = errorText(e);
      }
    },
  }, label);

  async function poll() {
    if (stopped) return;
    let run;
    try {
      run = await api.getRun(id);
    } catch (e) {
      errorBox.hidden = false;
      errorBox.textContent = errorText(e);
      if (e.status !== 404 && e.status !== 401 && e.status !== 403) timer = setTimeout(poll, 2000);
      return;
    }
    if (stopped) return;
    errorBox.hidden = true;
    title.textContent = `Run #${id}${run.name ? `: ${run.name}` : ''}`;
    const flagged = run.summary?.flagged_blocks;
    setTitle(`Run #${id}${run.name ? ` ${run.name}` : ''}${run.state === 'done' ? (flagged ? ` (${flagged} flagged)` : '') : ` (${run.state})`}`);
    badge.replaceChildren(stateBadge(run));
    clear(metaBox, meta(run, lib));
    const isLive = run.state === 'live';
    const active = run.state === 'queued' || run.state === 'running' || isLive;
    clear(actions,
      isLive ? action('Stop', async () => { await api.stopLive(id); }) : null,
      active && !isLive ? action('Cancel', async () => { await api.cancelRun(id); clearTimeout(timer); poll(); }) : null,
      !active ? action('Delete', async () => {
        if (!window.confirm(`Delete run #${id} and its results?`)) return;
        await api.deleteRun(id);
        location.hash = '#/runs';
      }) : null);
    progressBox.hidden = !active || isLive;
    if (isLive) {
      if (!live) {
        live = new LiveView(id);
        body.prepend(live.el);
        disposers.push(() => live && live.dispose());
      }
      try {
        await live.poll();
      } catch (e) {
        errorBox.hidden = false;
        errorBox.textContent = errorText(e);
      }
    } else if (live) {
      live.el.remove();
      live.dispose();
      live = null;
    }
    if (run.state === 'queued') {
      progress.removeAttribute('value');
      progressLabel.textContent = 'Queued: waiting for a worker';
    } else if (run.state === 'running') {
      progress.value = Math.round(run.progress * 1000) / 10;
      progressLabel.textContent = `Computing: ${Math.round(run.progress * 100)} %`;
    }
    if (active) {
      timer = setTimeout(poll, POLL_MS);
      return;
    }
    if (run.state === 'failed') {
      errorBox.hidden = false;
      errorBox.textContent = `The prediction failed: ${run.error}`;
    } else if (run.state === 'done' && !shown) {
      shown = true;
      try {
        await showResults(body, run, lib, disposers);
      } catch (e) {
        errorBox.hidden = false;
        errorBox.textContent = `Could not load the results: ${errorText(e)}`;
      }
    }
  }
  poll();
  return () => {
    stopped = true;
    clearTimeout(timer);
    disposers.forEach((d) => d());
  };
}
