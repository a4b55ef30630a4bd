// New run: drop a dry-run log, choose machine, tool, material from the libraries or define them
// inline, give the stock, optionally a base run and the NC program with its reading options;
// errors appear next to the field they concern.
import { api } from './api.js';
import { h, clear, field, setFieldError, statusLine, errorSummary } from './dom.js';
import { parseNumber, humanizeMessage } from './form_words.js';
import { loadLibraries } from './runs.js';
import {
  fieldGroup, loadSpecFields, splitKeyMessage, TOOL_FIELDS, MATERIAL_FIELDS, STOCK_FIELDS, SETUP_FIELDS, LIMIT_FIELDS, RESOLUTION_FIELDS,
} from './spec_form.js';

const INLINE = 'inline';
// The tool choice that takes the tool table of a loaded spec file (its `tools`, by T number).
const TABLE = 'table';

function librarySelect(name, items, { none, inline }) {
  return h('select', { name },
    none ? h('option', { value: '' }, none) : null,
    items.map((x) => h('option', { value: x.id }, x.name)),
    inline ? h('option', { value: INLINE }, 'Define inline…') : null);
}

function dropZone(fileInput, onFile) {
  const label = h('span', { class: 'drop-name' });
  const zone = h('div', { class: 'drop', 'data-testid': 'drop-zone' },
    h('p', {}, 'Drop the dry-run log here (CSV or SHDR), or ', h('label', { for: fileInput.id, class: 'link' }, 'choose a file'), '.'),
    label, fileInput);
  const show = () => {
    const f = fileInput.files[0];
    label.textContent = f ? `${f.name} (${(f.size / 1024).toFixed(1)} KiB)` : '';
    onFile?.(f);
  };
  fileInput.addEventListener('change', show);
  zone.addEventListener('dragover', (e) => {
    e.preventDefault();
    zone.classList.add('over');
  });
  zone.addEventListener('dragleave', () => zone.classList.remove('over'));
  zone.addEventListener('drop', (e) => {
    e.preventDefault();
    zone.classList.remove('over');
    if (!e.dataTransfer.files.length) return;
    fileInput.files = e.dataTransfer.files;
    show();
  });
  return zone;
}

// The program reading options (nc_options of POST /runs), each with the key the server names in its errors.
function programOptions() {
  const c = {
    map_blocks: h('input', { type: 'checkbox', name: 'map_blocks' }),
    decimal_less_is_increment: h('input', { type: 'checkbox', name: 'decimal_less_is_increment' }),
    ignore_words: h('input', { type: 'text', name: 'ignore_words', placeholder: 'G28,H', spellcheck: 'false' }),
    rapid_feed_mm_min: h('input', { type: 'text', inputmode: 'decimal', name: 'rapid_feed_mm_min', placeholder: '30000' }),
    block_lead_ms: h('input', { type: 'text', inputmode: 'decimal', name: 'block_lead_ms', placeholder: '0' }),
    work_offsets_mm: h('input', { type: 'text', name: 'work_offsets_mm', placeholder: 'G55=-150,250,340', spellcheck: 'false' }),
  };
  const check = (box, label) => {
    const wrap = field(label, box);
    wrap.classList.add('check');
    return wrap;
  };
  const el = h('details', { class: 'nc-options' }, h('summary', {}, 'Program options'),
    h('div', { class: 'field-grid' },
      check(c.map_blocks, 'Map blocks from the program'),
      field('Ignore words', c.ignore_words, 'Comma-separated codes or letters, dropped before reading'),
      field('G00 rapid feed (mm/min)', c.rapid_feed_mm_min, 'Speed of rapids in the commanded motion'),
      field('Block lead (ms)', c.block_lead_ms, 'Machine lag used when mapping blocks'),
      field('Work offsets', c.work_offsets_mm, 'Machine position of each system\'s zero: G55=x,y,z; G56=…'),
      check(c.decimal_less_is_increment, 'X10 means 10 least increments (0.010 mm)')));

  // {value, errors: [[control, message]]}: the nc_options object, empty when nothing is set.
  function read() {
    const value = {};
    const errors = [];
    const number = (key, ok, why) => {
      const text = c[key].value.trim();
      if (!text) return;
      const p = parseNumber(text, c[key].dataset.label || key);
      if (p.error) errors.push([c[key], p.error]);
      else if (!ok(p.value)) errors.push([c[key], why]);
      else value[key] = p.value;
    };
    if (c.map_blocks.checked) value.map_blocks = true;
    if (c.decimal_less_is_increment.checked) value.decimal_less_is_increment = true;
    const words = c.ignore_words.value.split(/[\s,]+/).filter(Boolean).map((w) => w.toUpperCase());
    const badWord = words.find((w) => !/^[A-Z](\d+(\.\d+)?)?$/.test(w));
    if (badWord) errors.push([c.ignore_words, `“${badWord}” is not a code (like G28) or a letter (like H).`]);
    else if (words.length) value.ignore_words = words;
    number('rapid_feed_mm_min', (v) => v > 0, 'Enter a feed above 0 mm/min, e.g. 30000.');
    number('block_lead_ms', (v) => v >= 0, 'Enter 0 or more milliseconds.');
    const offsets = {};
    for (const item of c.work_offsets_mm.value.split(';').map((x) => x.trim()).filter(Boolean)) {
      const m = /^(G5[4-9])\s*=\s*(.+)$/i.exec(item);
      const parts = m ? m[2].split(',').map((x) => x.trim()) : [];
      // Number('') is 0: an empty component must not pass as zero.
      const xyz = parts.every((x) => x !== '') ? parts.map(Number) : [];
      if (!m || xyz.length !== 3 || !xyz.every(Number.isFinite)) {
        errors.push([c.work_offsets_mm, `“${item}” is not a work offset: write G54..G59=x,y,z in mm, e.g. G55=-150,250,340.`]);
        break;
      }
      offsets[m[1].toUpperCase()] = xyz;
    }
    if (Object.keys(offsets).length) value.work_offsets_mm = offsets;
    return { value, errors };
  }
  // The options are folded away by default: unfold them to show an error inside.
  function showError(control, message) {
    el.open = true;
    setFieldError(control, message);
    return control;
  }
  return { el, controls: c, read, showError };
}

export async function renderNewRun(main) {
  try {
    await loadSpecFields();
  } catch (e) {
    main.append(h('p', { class: 'form-error', role: 'alert' }, `${e.message}: reload the page.`));
    return;
  }
  const lib = await loadLibraries();
  let doneRuns = [];
  try {
    doneRuns = (await api.listRuns({ state: 'done' })).items;
  } catch {
    // No read access: the base run list stays empty.
  }

  const log = h('input', { type: 'file', id: 'log-file', name: 'log', accept: '.csv,.txt,.shdr,.log', class: 'file' });
  const specFile = h('input', { type: 'file', name: 'spec-file', accept: '.json,application/json' });
  const mapping = h('input', { type: 'file', name: 'mapping', accept: '.json,application/json' });
  const name = h('input', { name: 'name', type: 'text' });
  const program = h('input', { name: 'program', type: 'text', placeholder: 'O1234' });
  const format = h('select', { name: 'format' }, ['auto', 'csv', 'shdr'].map((f) => h('option', { value: f }, f)));
  const units = h('select', { name: 'units' }, h('option', { value: '' }, 'as logged'),
    h('option', { value: 'mm' }, 'mm'), h('option', { value: 'in' }, 'in'));
  const machine = librarySelect('machine_id', lib.machines, { none: 'none (limits from the spec)' });
  const tool = librarySelect('tool_id', lib.tools, { inline: true });
  const material = librarySelect('material_id', lib.materials, { inline: true });
  const ncProgram = h('input', { type: 'file', id: 'nc-program-file', name: 'nc_program', class: 'file' });
  const ncOptions = programOptions();
  const baseRun = h('select', { name: 'base_run' }, h('option', { value: '' }, 'none: start from the stock box'),
    doneRuns.map((r) => h('option', { value: r.id }, `#${r.id} ${r.name || r.program || r.inputs?.log?.filename || ''}`)));
  if (!lib.tools.length) tool.value = INLINE;
  if (!lib.materials.length) material.value = INLINE;

  const groups = {
    tool: fieldGroup('tool', TOOL_FIELDS),
    material: fieldGroup('material', MATERIAL_FIELDS),
    stock: fieldGroup('stock', STOCK_FIELDS),
    setup: fieldGroup('setup', SETUP_FIELDS),
    limits: fieldGroup('limits', LIMIT_FIELDS),
    resolution: fieldGroup('resolution', RESOLUTION_FIELDS),
  };
  const toolBox = h('div', { class: 'inline-def' }, groups.tool.el);
  const materialBox = h('div', { class: 'inline-def' }, groups.material.el);
  const syncInline = () => {
    toolBox.hidden = tool.value !== INLINE;
    materialBox.hidden = material.value !== INLINE;
  };
  tool.addEventListener('change', syncInline);
  material.addEventListener('change', syncInline);
  syncInline();

  const formError = h('p', { class: 'form-error', role: 'alert' });
  const summary = h('div', { class: 'error-summary', id: 'error-summary', role: 'alert' });
  const status = statusLine();
  const submit = h('button', { type: 'submit', class: 'primary' }, 'Upload and compute');
  const form = h('form', { class: 'new-run', novalidate: true, 'aria-label': 'New run' },
    h('fieldset', {}, h('legend', {}, 'Dry-run log'),
      field('Log file', dropZone(log), 'Actual positions, feed and spindle speed from the dry run', log, { required: true }),
      h('div', { class: 'field-grid' }, field('Run name', name), field('Program', program), field('Format', format), field('Length units', units)),
      h('details', {}, h('summary', {}, 'Channel mapping (for logs with other column names)'), field('Mapping file (JSON)', mapping))),
    h('fieldset', {}, h('legend', {}, 'NC program'),
      field('NC program file (optional)', ncProgram,
        'ISO 6983 (FANUC dialect): adds the prediction from the commanded path, the per-block comparison and feed optimization'),
      ncOptions.el),
    h('fieldset', {}, h('legend', {}, 'Machine, tool and material'),
      field('Run spec file (RUN.json)', specFile, 'Optional: fills the fields below from a spec used with cutload predict'),
      h('div', { class: 'field-grid' }, field('Machine', machine), field('Tool', tool), field('Material', material)),
      toolBox, materialBox),
    h('fieldset', {}, h('legend', {}, 'Stock and setup'), groups.stock.el, groups.setup.el,
      h('div', { class: 'field-grid' }, field('Base run', baseRun, 'Start from the final stock of a finished run'))),
    h('fieldset', {}, h('legend', {}, 'Limits (0 or empty: from the tool and machine)'), groups.limits.el),
    h('details', {}, h('summary', {}, 'Resolution'), groups.resolution.el),
    summary, formError, h('div', { class: 'actions' }, submit), status);
  clear(main, h('h1', {}, 'New run'),
    h('p', { class: 'required-note muted' }, 'Fields marked ', h('span', { class: 'req' }, '*'), ' are required.'), form);

  // A spec file's tool table travels with the run as it is (the form has no fields for it); the
  // tool choice says so, and a tool chosen beside it cuts the samples that name no tool.
  let toolTable = null;
  function useToolTable(table) {
    toolTable = Array.isArray(table) && table.length ? table : null;
    tool.querySelector(`option[value="${TABLE}"]`)?.remove();
    if (!toolTable) {
      if (tool.value === TABLE) tool.value = INLINE;
      return;
    }
    const names = toolTable.map((t) => `T${t.number}`).join(', ');
    tool.append(h('option', { value: TABLE }, `Tool table from the spec file (${names})`));
  }

  specFile.addEventListener('change', async () => {
    setFieldError(specFile, '');
    const f = specFile.files[0];
    if (!f) return;
    try {
      const spec = JSON.parse(await f.text());
      for (const [k, g] of Object.entries(groups)) g.fill(spec[k]);
      useToolTable(spec.tools);
      if (toolTable && !spec.tool) tool.value = TABLE;
      if (spec.tool) tool.value = INLINE;
      if (spec.material) material.value = INLINE;
      syncInline();
    } catch (e) {
      setFieldError(specFile, `${f.name}: ${e.message}`);
    }
  });

  const selects = {
    machine_id: machine, tool_id: tool, material_id: material, base_run: baseRun, format, units, log, mapping, nc_program: ncProgram,
  };

  function clearErrors() {
    formError.textContent = '';
    errorSummary(summary, []);
    Object.values(groups).forEach((g) => g.clearErrors());
    Object.values(selects).forEach((c) => setFieldError(c, ''));
    Object.values(ncOptions.controls).forEach((c) => setFieldError(c, ''));
  }

  // Puts a server message next to its field (key paths said as the fields' labels) and in the
  // summary; unmatched messages go under the form.
  function showServerError(e) {
    const msg = e.message;
    const at = (c, text = msg) => {
      setFieldError(c, text);
      errorSummary(summary, [[c, text]]);
    };
    if (e.code === 'bad_log' || /part 'log'/.test(msg)) return at(log);
    if (/^ignore word/.test(msg)) return ncOptions.showError(ncOptions.controls.ignore_words, msg);
    if (e.code === 'bad_program' || /part 'nc_program'/.test(msg)) return at(ncProgram);
    if (/nc_options/.test(msg)) {
      const key = /nc_options\W+(\w+)/.exec(msg)?.[1];
      const c = ncOptions.controls[key];
      if (c) {
        const text = humanizeMessage(msg.replace(/nc_options\.?/, ''), new Map([[key, c.dataset.label || key]]));
        ncOptions.showError(c, text);
        return errorSummary(summary, [[c, text]]);
      }
      return at(ncProgram);
    }
    for (const [partName, c] of Object.entries(selects)) {
      if (new RegExp(`^(part )?${partName}\\b`).test(msg)) return at(c);
    }
    const [path] = splitKeyMessage(msg);
    if (path) {
      const top = path.split(/[.[]/)[0];
      if (top === 'tool' && tool.value !== INLINE) return at(tool);
      if (top === 'material' && material.value !== INLINE) return at(material);
      const c = groups[top]?.showError(path, msg);
      if (c) return errorSummary(summary, [[c, document.getElementById(`${c.id}-err`)?.textContent || msg]]);
    }
    formError.textContent = msg;
    return undefined;
  }

  form.addEventListener('submit', async (ev) => {
    ev.preventDefault();
    clearErrors();
    const spec = {};
    const problems = [];
    for (const [k, g] of Object.entries(groups)) {
      if ((k === 'tool' && tool.value !== INLINE) || (k === 'material' && material.value !== INLINE)) continue;
      const { value, errors } = g.read();
      for (const [path, why] of errors) problems.push(() => [g.showError(path, why), why]);
      if (Object.keys(value).length) spec[k] = value;
    }
    const fieldError = (c, why) => () => {
      setFieldError(c, why);
      return [c, why];
    };
    if (!log.files[0]) problems.push(fieldError(log, 'Required: choose the dry-run log file (CSV or MTConnect SHDR).'));
    const programOpts = ncOptions.read();
    for (const [control, why] of programOpts.errors) problems.push(() => [ncOptions.showError(control, why), why]);
    if (!ncProgram.files[0] && (Object.keys(programOpts.value).length || programOpts.errors.length)) {
      problems.push(fieldError(ncProgram, 'Choose the NC program file the program options apply to, or clear the options.'));
    }
    if (problems.length) {
      // Every problem at once: by its field, and listed above the button.
      const shown = problems.map((p) => p());
      errorSummary(summary, shown.map(([c, why]) => [c.closest?.('[role=group]') || c, why]));
      form.querySelector('[aria-invalid="true"]')?.focus();
      return;
    }
    if (tool.value !== INLINE && tool.value !== TABLE) spec.tool_id = Number(tool.value);
    if (toolTable) spec.tools = toolTable;
    if (material.value !== INLINE) spec.material_id = Number(material.value);
    if (machine.value) spec.machine_id = Number(machine.value);

    const fd = new FormData();
    fd.append('log', log.files[0], log.files[0].name);
    fd.append('spec', JSON.stringify(spec));
    if (name.value.trim()) fd.append('name', name.value.trim());
    if (program.value.trim()) fd.append('program', program.value.trim());
    if (format.value !== 'auto') fd.append('format', format.value);
    if (units.value) fd.append('units', units.value);
    if (baseRun.value) fd.append('base_run', baseRun.value);
    if (mapping.files[0]) fd.append('mapping', mapping.files[0], mapping.files[0].name);
    if (ncProgram.files[0]) {
      fd.append('nc_program', ncProgram.files[0], ncProgram.files[0].name);
      if (Object.keys(programOpts.value).length) fd.append('nc_options', JSON.stringify(programOpts.value));
    }

    submit.disabled = true;
    status.textContent = 'Uploading…';
    try {
      const run = await api.createRun(fd);
      location.hash = `#/runs/${run.id}`;
    } catch (e) {
      status.textContent = '';
      showServerError(e);
      form.querySelector('[aria-invalid="true"]')?.focus();
    } finally {
      submit.disabled = false;
    }
  });
  return null;
}

