// A run: live progress while it computes (polling the run), then the force plot, the tool path,
// the block table and the run's alerts; with an NC program also the commanded prediction on the
// plot, the per-block comparison in the table and the feed optimization. Selecting a time or a block in any of them selects it in
// all of them; selecting a block in the table zooms the plot to it.
import { api } from './api.js';
import { h, clear, num, seconds, when, download, statusLine, errorText, lowerBound } from './dom.js';
import { loadLibraries, toolLabel, stateBadge } from './runs.js';
import { ForcePlot } from './force_plot.js';
import { PathView, pathPoints } from './path_view.js';
import { BlockTable, withComparison } from './block_table.js';
import { programSection, optimizePanel } from './program.js';
import { alertTable } from './alerts.js';

const POLL_MS = 250;   // the server updates progress at most every 250 ms
const MIN_BLOCK_SPAN_S = 1e-3;

function meta(run, lib) {
  const spec = run.inputs?.spec || {};
  const material = run.material_id ? lib.byId('materials', run.material_id)?.name : spec.material?.name;
  const machine = run.machine_id ? lib.byId('machines', run.machine_id)?.name ?? `#${run.machine_id}` : '–';
  const rows = [
    ['Log', `${run.inputs?.log?.filename || '–'} (${run.inputs?.ingest?.rows ?? '?'} rows, ${seconds(run.inputs?.ingest?.duration_s)})`],
    ['Program', run.program || '–'],
    ['NC program', run.inputs?.nc_program ? `${run.inputs.nc_program.filename} (${num(run.inputs.nc_program.bytes / 1024)} KiB)` : '–'],
    ['Machine', machine],
    ['Tool', toolLabel(run, lib)],
    ['Material', material || '–'],
    ['Base run', run.base_run ? h('a', { href: `#/runs/${run.base_run}` }, `#${run.base_run}`) : '–'],
    ['Created', when(run.created_at)],
    ['Finished', when(run.finished_at)],
  ];
  return h('dl', { class: 'meta' }, rows.map(([k, v]) => [h('dt', {}, k), h('dd', {}, v)]));
}

function summaryCards(s, limits) {
  const card = (label, value, limit, unit) => h('div', { class: `card${limit && value > limit ? ' over' : ''}` },
    h('span', { class: 'card-label' }, label),
    h('span', { class: 'card-value' }, `${num(value)} ${unit}`),
    limit ? h('span', { class: 'card-limit' }, `limit ${num(limit)} ${unit}`) : null);
  return h('div', { class: 'cards', 'aria-label': 'Summary' },
    card('Peak force', s.peak_force_N, limits.force_N, 'N'),
    card('Peak torque', s.peak_torque_Nm, limits.torque_Nm, 'N·m'),
    card('Peak power', s.peak_power_kW, limits.power_kW, 'kW'),
    card('Max chip', s.max_chip_mm, limits.chip_mm, 'mm'),
    card('Max bending', s.max_bending_MPa, limits.bending_MPa, 'MPa'),
    h('div', { class: `card${s.flagged_blocks ? ' over' : ''}` }, h('span', { class: 'card-label' }, 'Flagged blocks'),
      h('span', { class: 'card-value', id: 'flagged-count' }, `${s.flagged_blocks} of ${s.blocks}`)),
    h('div', { class: 'card' }, h('span', { class: 'card-label' }, 'Computed'),
      h('span', { class: 'card-value' }, `${num(s.compute_s)} s`), h('span', { class: 'card-limit' }, `${s.samples} samples, ${s.device}`)));
}

// The comparison metrics of an attached dynamometer record, overall and per block.
function metricsTable(report) {
  const axes = [['x', 'Fx'], ['y', 'Fy'], ['z', 'Fz'], ['resultant', '|F|']];
  const rows = [report.overall, ...report.blocks].flatMap((scope) => axes.map(([k, label], i) => {
    const m = scope[k];
    return h('tr', {}, h('td', {}, i === 0 ? scope.scope : ''), h('td', {}, label), h('td', {}, num(m.mean_error_N)),
      h('td', {}, num(m.rmse_N)), h('td', {}, num(m.nrmse)), h('td', {}, num(m.peak_error_N)), h('td', {}, num(m.correlation)));
  }));
  return h('table', { class: 'metrics', id: 'measurement-metrics' },
    h('caption', {}, `Predicted minus measured (${report.measured.file}, ${num(report.measured.rate_Hz)} Hz, offset ${num(report.offset_s)} s ${report.offset_source})`),
    h('thead', {}, h('tr', {}, ['Scope', 'Axis', 'Mean error (N)', 'RMSE (N)', 'NRMSE', 'Peak error (N)', 'Correlation'].map((c) => h('th', { scope: 'col' }, c)))),
    h('tbody', {}, rows));
}

// "Attach measurement": a dynamometer file and its axis matrix; the comparison once attached.
function measurementSection(id, plot) {
  const file = h('input', { type: 'file', id: 'measurement-file', accept: '.csv,.txt', 'aria-describedby': 'measurement-file-err' });
  const axes = h('input', { type: 'text', id: 'measurement-axes', placeholder: '1,0,0,0,1,0,0,0,1', size: 24 });
  const err = h('span', { class: 'field-error', id: 'measurement-file-err', role: 'alert' });
  const result = h('div', { id: 'measurement-result' });
  const show = (cmp) => {
    plot.setMeasured(cmp ? cmp.series : null);
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
      err.textContent = 'choose the dynamometer file (DynoWare CSV export or plain CSV t,fx,fy,fz)';
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
    h('p', { class: 'hint muted' }, 'Dashed lines on the plot: measured Fx, Fy, Fz (force on the tool, machine axes).'),
    h('div', { class: 'measurement-form' },
      h('label', { for: 'measurement-file' }, 'Dynamometer file '), file,
      h('label', { for: 'measurement-axes' }, ' Axis matrix (dynamometer to machine, row-major) '), axes,
      h('button', { type: 'button', onclick: attach }, 'Attach measurement'), err),
    result);
  return { section, load };
}

async function showResults(body, run, lib, disposers) {
  const id = run.id;
  const limits = run.inputs?.spec?.limits || {};
  const status = statusLine('Loading results…');
  clear(body, status);
  // A missing comparison is shown in its section; the rest of the page works without it.
  const [runBlocks, motion, program] = await Promise.all([api.blocks(id), api.motion(id, { max_points: 6000 }),
    run.links?.program ? api.program(id).catch((error) => ({ error })) : null]);
  const comparing = Boolean(program && !program.error);
  const blocks = comparing ? withComparison(runBlocks, program.blocks) : runBlocks;

  const plotBox = h('div', { class: 'plot', id: 'force-plot', tabindex: 0, role: 'group',
    'aria-label': 'Force plot. Left and right arrows pan, plus and minus zoom, 0 shows the whole run.' });
  const rangeText = h('span', { class: 'range', id: 'plot-range', 'aria-live': 'polite' });
  const selText = h('p', { class: 'selection', id: 'selection', 'aria-live': 'polite' }, 'Click the plot, the path or a block to select it.');
  const plot = new ForcePlot(plotBox, {
    fetchWindow: (from_s, to_s, max_points, signal) => api.forces(id, { from_s, to_s, max_points }, signal),
    fetchCommanded: comparing ? (from_s, to_s, max_points, signal) => api.commandedForces(id, { from_s, to_s, max_points }, signal) : null,
    limits,
    onPick: (t) => selectTime(t),
    onRange: (a, b) => {
      rangeText.textContent = `${a.toFixed(4)} – ${b.toFixed(4)} s`;
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
  const controls = h('div', { class: 'plot-controls', role: 'toolbar', 'aria-label': 'Plot controls' },
    channel('torque_Nm', 'Torque'), channel('power_kW', 'Power'),
    comparing ? h('label', { class: 'inline' }, commandedBox, ' Commanded (program)') : null,
    h('span', { class: 'sep' }),
    btn('−', 'Zoom out', () => plot.zoom(2)), btn('+', 'Zoom in', () => plot.zoom(0.5)),
    btn('◀', 'Pan left', () => plot.pan(-0.25)), btn('▶', 'Pan right', () => plot.pan(0.25)),
    btn('Whole run', 'Show the whole run', () => plot.reset()),
    h('span', { class: 'sep' }),
    btn('Export CSV', 'Download the visible window as CSV', async () => {
      const [a, b] = plot.xRange();
      exportStatus.textContent = 'Preparing CSV…';
      try {
        const csv = await api.forcesCsv(id, { from_s: a, to_s: b, max_points: 20000 });
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

  const measurementBox = measurementSection(id, plot);

  const pathBox = h('div', { class: 'path-box' });
  const tableBox = h('div');
  const optimizer = run.links?.program ? optimizePanel(run) : null;
  if (optimizer) disposers.push(optimizer.dispose);
  const alertsBox = h('section', { class: 'run-alerts', 'aria-labelledby': 'run-alerts-title' },
    h('h2', { id: 'run-alerts-title' }, 'Alerts'));
  clear(body,
    summaryCards(run.summary, limits),
    h('section', { class: 'forces', 'aria-labelledby': 'forces-title' },
      h('div', { class: 'section-head' }, h('h2', { id: 'forces-title' }, 'Forces'), h('span', { class: 'muted' }, 'Showing '), rangeText),
      controls,
      h('p', { class: 'hint muted' }, 'Drag to zoom into a range, wheel to zoom, Shift-drag or Shift-wheel to pan, double-click to reset. Shaded: flagged blocks.',
        comparing ? ' Cyan: the resultant predicted from the programmed motion, each block drawn over the time the machine took for it.' : ''),
      plotBox, selText),
    program ? programSection(run, program) : null,
    measurementBox.section,
    h('section', { class: 'path', 'aria-labelledby': 'path-title' }, h('h2', { id: 'path-title' }, 'Tool path'), pathBox),
    tableBox, optimizer?.section, alertsBox, status);

  await plot.load();
  status.textContent = '';
  await measurementBox.load();
  await optimizer?.load();
  plot.setShaded(blocks.filter((b) => b.flags.length).map((b) => ({ t0: b.t_start_s, t1: b.t_end_s })));

  const [ox, of] = [plot.overview[0], plot.overview[4]];
  let fmax = limits.force_N || 0;
  for (const v of of) fmax = Math.max(fmax, v);
  const forceAt = (t) => {
    const i = lowerBound(ox, t);
    return Math.max(of[Math.max(0, i - 1)] || 0, of[Math.min(of.length - 1, i)] || 0);
  };
  const stock = run.inputs?.spec?.stock?.box_mm || null;
  const path = new PathView(pathBox, {
    points: pathPoints(motion, run.inputs?.spec?.setup?.offset_mm),
    forceAt,
    forceMax: fmax,
    stock,
    onPick: (t) => selectTime(t),
  });
  disposers.push(() => path.destroy());

  const table = new BlockTable(tableBox, blocks, {
    onSelect: (b) => selectBlock(b, null, true),
    comparison: comparing,
  });

  function selectBlock(b, t, zoom) {
    table.select(b ? b.idx : null);
    plot.select(b, t);
    path.select(b, t);
    const at = t == null ? '' : `t = ${t.toFixed(4)} s, `;
    selText.textContent = b
      ? `Selected ${at}block ${b.block} (${b.t_start_s.toFixed(4)}–${b.t_end_s.toFixed(4)} s, peak ${num(b.peak_force_N)} N${b.flags.length ? `, flags: ${b.flags.map((f) => f.flag).join(', ')}` : ''})`
      : `Selected t = ${t?.toFixed(4)} s (no block)`;
    if (zoom && b) {
      const mid = (b.t_start_s + b.t_end_s) / 2;
      const half = Math.max(b.t_end_s - b.t_start_s, MIN_BLOCK_SPAN_S) / 2;
      plot.setRange(mid - half, mid + half);
    }
  }
  function selectTime(t) {
    const b = blocks.find((x) => t >= x.t_start_s && t <= x.t_end_s) || null;
    selectBlock(b, t, false);
  }

  if (run.summary?.alerts) alertTable(alertsBox, () => ({ run_id: id }), { showRun: false });
  else alertsBox.append(h('p', { class: 'muted' }, 'No alerts were raised for this run.'));
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
    badge.replaceChildren(stateBadge(run));
    clear(metaBox, meta(run, lib));
    const active = run.state === 'queued' || run.state === 'running';
    clear(actions,
      active ? action('Cancel', async () => { await api.cancelRun(id); clearTimeout(timer); poll(); }) : null,
      !active ? action('Delete', async () => {
        if (!window.confirm(`Delete run #${id} and its results?`)) return;
        await api.deleteRun(id);
        location.hash = '#/runs';
      }) : null);
    progressBox.hidden = !active;
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
