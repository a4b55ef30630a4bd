// The NC program parts of a run page: how well the log was attributed to the program's blocks,
// the commanded prediction beside the actual one, and the feed optimization panel (a job like a
// run: started, polled for progress, its recommendations shown with the rewritten program).
import { api } from './api.js';
import { h, clear, field, setFieldError, num, download, errorText } from './dom.js';
import { flagLabel, quantityLabel } from './labels.js';

const POLL_MS = 250;
const TARGET_RANGE = [0.05, 1];

const pct = (fraction, digits = 3) => (fraction == null ? '–' : `${num(100 * fraction, digits)} %`);

// A link to an API path that needs the key: the click fetches it with the key and saves the text.
export function apiDownload(path, filename, label, { id, accept = 'text/plain', onError } = {}) {
  const a = h('a', { href: path, download: filename, id }, label);
  a.addEventListener('click', async (e) => {
    e.preventDefault();
    try {
      download(filename, new Blob([await api.text(path, accept)], { type: accept }));
    } catch (err) {
      onError?.(err);
    }
  });
  return a;
}

// "demo_program.nc" -> "demo_program": the server names the optimized program <stem>_opt.nc.
function stem(filename) {
  return (filename || 'program').replace(/\.[^.]*$/, '');
}

export function mappingLine(m) {
  const source = m.source === 'log' ? "blocks from the log's block channel" : 'blocks mapped from the program path';
  const parts = [
    `${m.matched} of ${m.samples} samples matched (${pct(m.matched_fraction)})`,
    `distance from the programmed path mean ${num(m.mean_distance_mm)} mm, p95 ${num(m.p95_distance_mm)} mm, max ${num(m.max_distance_mm)} mm`,
    `path covered ${pct(m.coverage)}`,
  ];
  if (m.agreement != null) parts.push(`agreement with the logged blocks ${pct(m.agreement)}`);
  if (m.estimated_lead_ms != null) parts.push(`estimated block lead ${num(m.estimated_lead_ms)} ms`);
  const missing = m.blocks_without_samples || [];
  if (missing.length) parts.push(`blocks without samples: ${missing.join(', ')}`);
  return `Block mapping (${source}): ${parts.join('; ')}.`;
}

// The program summary: file, commanded against actual peak and duration, mapping quality, downloads.
export function programSection(run, program) {
  const id = run.id;
  const err = h('p', { class: 'form-error', role: 'alert' });
  const filename = run.inputs?.nc_program?.filename || program?.filename || 'program.nc';
  const head = h('h2', { id: 'program-title' }, 'NC program');
  if (program.error) {
    err.textContent = `Could not load the program comparison: ${errorText(program.error)}`;
    return h('section', { class: 'program', 'aria-labelledby': 'program-title' }, head, err);
  }
  const cmd = program.commanded || {};
  const actual = run.summary || {};
  const actualDuration = actual.simulated_s ?? run.inputs?.ingest?.duration_s;
  const onError = (e) => {
    err.textContent = errorText(e);
  };
  return h('section', { class: 'program', 'aria-labelledby': 'program-title' }, head,
    h('p', { id: 'program-summary' },
      `${filename}: ${program.program_blocks} blocks. Peak force commanded ${num(cmd.peak_force_N)} N, actual ${num(actual.peak_force_N)} N; `
      + `duration commanded ${num(cmd.simulated_s)} s, actual ${num(actualDuration)} s.`),
    h('p', { id: 'mapping-quality', class: 'mapping' }, mappingLine(program.mapping)),
    h('p', { class: 'links' },
      apiDownload(`/api/v1/runs/${id}/program?format=csv`, `run-${id}-program-blocks.csv`, 'Per-block comparison (CSV)',
        { id: 'program-csv', accept: 'text/csv', onError }),
      ' · ',
      apiDownload(`/api/v1/runs/${id}/program/source`, filename, `Program as uploaded (${filename})`,
        { id: 'program-source', onError })),
    err);
}

// Per block: F as programmed and as recommended, the change, the time it saves or costs
// (estimated from the block's duration as logged), the binding load before and after, and the
// flags the change clears. Only changed rows are tinted.
function resultTable(result, durations) {
  const head = ['Block', 'F programmed (mm/min)', 'F recommended (mm/min)', 'Change', 'Time change (s, est.)', 'Binding',
    'Load before (%)', 'Load after (%)', 'Flags'];
  const rows = result.blocks.map((b) => {
    const changed = b.recommended_feed_mm_min !== b.programmed_feed_mm_min;
    const d = durations.get(b.block);
    // A block's cutting time scales with 1 / feed (acceleration aside: an estimate).
    const dt = changed && d > 0 ? d * (b.programmed_feed_mm_min / b.recommended_feed_mm_min - 1) : 0;
    const cleared = b.flags_cleared || [];
    const still = b.flags_after || [];
    const flags = [
      ...cleared.map((f) => h('span', { class: 'flag-cleared' }, `clears: ${flagLabel(f, { short: true })}`)),
      ...still.map((f) => h('span', { class: 'flag' }, `still: ${flagLabel(f, { short: true })}`)),
    ];
    return h('tr', { class: changed ? 'changed' : null, dataset: { block: b.block, changed: String(changed) } },
      h('th', { scope: 'row' }, b.block),
      h('td', { class: 'num' }, num(b.programmed_feed_mm_min, 6)),
      h('td', { class: 'num' }, changed ? num(b.recommended_feed_mm_min, 6) : num(b.recommended_feed_mm_min, 6)),
      h('td', { class: 'num' }, changed ? `${b.recommended_feed_mm_min > b.programmed_feed_mm_min ? '+' : '−'}${num(Math.abs(100 * (b.recommended_feed_mm_min / b.programmed_feed_mm_min - 1)), 2)} %` : 'unchanged'),
      h('td', { class: 'num' }, changed && d > 0 ? `${dt >= 0 ? '+' : '−'}${Math.abs(dt).toFixed(3)}` : ''),
      h('td', {}, quantityLabel(b.binding) + (b.at_feed_limit ? ' (at the feed limit)' : '')),
      h('td', { class: 'num' }, num(100 * b.ratio_before)),
      h('td', { class: 'num' }, num(100 * b.ratio_after)),
      h('td', {}, flags.length ? flags : ''));
  });
  // Changed blocks only by default when some changed: the list a shop loads the program by.
  const changedOnly = h('input', { type: 'checkbox', id: 'optimize-changed-only', checked: result.changed_blocks > 0 });
  const apply = () => rows.forEach((tr) => {
    tr.hidden = changedOnly.checked && tr.dataset.changed !== 'true';
  });
  changedOnly.addEventListener('change', apply);
  apply();
  return h('div', {},
    h('label', { class: 'inline' }, changedOnly, ' Changed blocks only'),
    h('div', { class: 'table-scroll' },
    h('table', { class: 'grid', id: 'optimize-table' },
      h('caption', { class: 'sr-only' }, 'Recommended feed per block; load is the binding quantity as a percentage of its limit'),
      h('thead', {}, h('tr', {}, head.map((c) => h('th', { scope: 'col' }, c)))),
      h('tbody', {}, rows))));
}

function resultSummary(opt) {
  const r = opt.result;
  const change = r.cycle_before_s ? (100 * (r.cycle_after_s - r.cycle_before_s)) / r.cycle_before_s : 0;
  const cleared = r.blocks.filter((b) => (b.flags_cleared || []).length).length;
  return `${r.changed_blocks} of ${r.blocks.length} blocks changed. Target ${pct(opt.params.target)} of each limit `
    + `${r.target_met ? 'met' : 'not met'} (highest load after ${pct(r.max_ratio_after)}${r.max_ratio_block ? ` in ${r.max_ratio_block}` : ''}). `
    + (r.exceeds_limit ? `Warning: ${r.max_ratio_block} still exceeds a limit with these feeds; check it before running the program. ` : '')
    + (r.blocks.some((b) => b.flags_cleared) ? `${cleared} block(s) lose a flag. ` : '')
    + `Cycle time ${r.cycle_before_s.toFixed(2)} s before, ${r.cycle_after_s.toFixed(2)} s after (${change >= 0 ? '+' : '−'}${Math.abs(change).toFixed(1)} %); `
    + `${r.predictions} predictions on the ${opt.params.basis} motion.`;
}

// "Optimize feeds": target and basis, start, progress, then the recommendations and the program.
// blocks: the run's blocks (with the comparison's durations), for the time each change costs.
export function optimizePanel(run, { blocks = [] } = {}) {
  const durations = new Map(blocks.map((b) => [b.block, b.t_end_s - b.t_start_s]));
  const target = h('input', { type: 'number', id: 'optimize-target', min: TARGET_RANGE[0], max: TARGET_RANGE[1], step: 0.05, value: '0.8' });
  const basis = h('select', { id: 'optimize-basis' },
    h('option', { value: 'actual' }, 'actual motion (dry run)'),
    h('option', { value: 'commanded' }, 'commanded motion (program)'));
  const onlyFlagged = h('input', { type: 'checkbox', id: 'optimize-only-flagged' });
  const neverRaise = h('input', { type: 'checkbox', id: 'optimize-never-raise' });
  const step = h('input', { type: 'number', id: 'optimize-step', min: 0, max: 1000, step: 10, value: '50' });
  const check = (box, label, hint) => {
    const f = field(label, box, hint);
    f.classList.add('check');
    return f;
  };
  const start = h('button', { type: 'button', class: 'primary' }, 'Optimize feeds');
  const cancel = h('button', { type: 'button', hidden: true }, 'Cancel');
  const progress = h('progress', { id: 'optimize-progress', max: 100, 'aria-labelledby': 'optimize-progress-label' });
  const progressLabel = h('span', { id: 'optimize-progress-label' });
  const progressBox = h('div', { class: 'progress', hidden: true }, progressLabel, progress);
  const error = h('p', { class: 'form-error', id: 'optimize-error', role: 'alert' });
  const result = h('div', { id: 'optimize-result' });
  const section = h('section', { class: 'optimize', id: 'optimize', 'aria-labelledby': 'optimize-title' },
    h('h2', { id: 'optimize-title' }, 'Optimize feeds'),
    h('p', { class: 'hint muted' }, 'Per block, the feed that brings the binding quantity (peak force, torque, power, chip thickness or bending stress, '
      + 'whichever is closest to its limit) '
      + 'to the target fraction of its limit within the machine\'s feed range; the program is rewritten with only its F words '
      + 'changed and predicted again.'),
    h('div', { class: 'optimize-form' },
      field('Target (fraction of each limit, 0.05–1)', target),
      field('Basis', basis),
      field('Round feeds to (mm/min)', step, '0: any feed an F word can state'),
      check(onlyFlagged, 'Only flagged blocks', 'other blocks keep their feed'),
      check(neverRaise, 'Never raise the feed', 'only slow blocks down'),
      h('div', { class: 'field actions' }, h('div', { class: 'actions' }, start, cancel))),
    progressBox, error, result);

  let timer = 0;
  let stopped = false;
  let current = null;

  const busy = (on) => {
    start.disabled = on;
    cancel.hidden = !on;
    progressBox.hidden = !on;
  };

  function showResult(opt) {
    const filename = `${stem(run.inputs?.nc_program?.filename)}_opt.nc`;
    clear(result,
      h('p', { id: 'optimize-summary' }, resultSummary(opt)),
      h('p', {}, apiDownload(opt.links.program, filename, `Download the optimized program (${filename})`, {
        id: 'optimized-program',
        onError: (e) => {
          error.textContent = errorText(e);
        },
      })),
      resultTable(opt.result, durations));
  }

  function show(opt) {
    current = opt;
    const active = opt.state === 'queued' || opt.state === 'running';
    busy(active);
    if (opt.state === 'queued') {
      progress.removeAttribute('value');
      progressLabel.textContent = 'Queued: waiting for a worker';
    } else if (opt.state === 'running') {
      progress.value = Math.round(opt.progress * 1000) / 10;
      progressLabel.textContent = `Optimizing: ${Math.round(opt.progress * 100)} %`;
    } else if (opt.state === 'done') {
      showResult(opt);
    } else if (opt.state === 'failed') {
      error.textContent = `The optimization failed: ${opt.error}`;
    } else if (opt.state === 'cancelled') {
      error.textContent = 'The optimization was cancelled.';
    }
    return active;
  }

  // A failed poll (a network blip, a restarting server) is retried with a growing delay while
  // the job may still be running; only an answer that the job is gone ends the following.
  async function poll(oid, failures = 0) {
    if (stopped) return;
    try {
      const opt = await api.optimization(oid);
      if (stopped) return;
      error.textContent = '';
      if (show(opt)) timer = setTimeout(() => poll(oid), POLL_MS);
    } catch (e) {
      if (stopped) return;
      error.textContent = errorText(e);
      if (e.status === 404 || failures >= 8) {
        busy(false);
        return;
      }
      timer = setTimeout(() => poll(oid, failures + 1), POLL_MS * 2 ** Math.min(failures + 1, 5));
    }
  }

  start.addEventListener('click', async () => {
    error.textContent = '';
    setFieldError(target, '');
    setFieldError(step, '');
    const t = Number(target.value);
    const st = Number(step.value || 0);
    let bad = null;
    if (!target.value.trim() || !(t >= TARGET_RANGE[0] && t <= TARGET_RANGE[1])) {
      setFieldError(target, `Enter a fraction from ${TARGET_RANGE[0]} to ${TARGET_RANGE[1]}, e.g. 0.8 for 80 % of each limit`);
      bad = bad || target;
    }
    if (!(st >= 0 && st <= 1000)) {
      setFieldError(step, 'Enter a step from 0 to 1000 mm/min, e.g. 50');
      bad = bad || step;
    }
    if (bad) {
      bad.focus();
      return;
    }
    clearTimeout(timer);
    clear(result);
    busy(true);
    progress.removeAttribute('value');
    progressLabel.textContent = 'Starting…';
    try {
      const opt = await api.createOptimization(run.id, {
        target: t, basis: basis.value, only_flagged: onlyFlagged.checked, never_raise: neverRaise.checked, feed_step_mm_min: st,
      });
      if (show(opt)) timer = setTimeout(() => poll(opt.id), POLL_MS);
    } catch (e) {
      busy(false);
      if (/^target\b/.test(e.message)) setFieldError(target, e.message);
      else error.textContent = errorText(e);
    }
  });

  cancel.addEventListener('click', async () => {
    if (!current) return;
    try {
      await api.cancelOptimization(current.id);
    } catch (e) {
      error.textContent = errorText(e);
    }
  });

  // The newest optimization of the run, so a reload shows it again (or follows it while it runs).
  async function load() {
    let items;
    try {
      items = await api.optimizations(run.id);
    } catch (e) {
      error.textContent = errorText(e);
      return;
    }
    const newest = items[0];
    if (!newest || stopped) return;
    target.value = String(newest.params.target);
    basis.value = newest.params.basis;
    onlyFlagged.checked = Boolean(newest.params.only_flagged);
    neverRaise.checked = Boolean(newest.params.never_raise);
    step.value = String(newest.params.feed_step_mm_min ?? 0);
    if (show(newest)) timer = setTimeout(() => poll(newest.id), POLL_MS);
  }

  return {
    section,
    load,
    dispose: () => {
      stopped = true;
      clearTimeout(timer);
    },
  };
}
