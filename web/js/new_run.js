// New run: drop a dry-run log, choose machine, tool, material from the libraries or define them
// inline, give the stock, optionally a base run; errors appear next to the field they concern.
import { api } from './api.js';
import { h, clear, field, setFieldError, statusLine } from './dom.js';
import { loadLibraries } from './runs.js';
import {
  fieldGroup, splitKeyMessage, TOOL_FIELDS, MATERIAL_FIELDS, STOCK_FIELDS, SETUP_FIELDS, LIMIT_FIELDS, RESOLUTION_FIELDS,
} from './spec_form.js';

const INLINE = 'inline';

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

export async function renderNewRun(main) {
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
  const status = statusLine();
  const submit = h('button', { type: 'submit', class: 'primary' }, 'Upload and compute');
  const form = h('form', { class: 'new-run', novalidate: true, 'aria-label': 'New run' },
    h('fieldset', {}, h('legend', {}, 'Dry-run log'),
      field('Log file', dropZone(log), 'Actual positions, feed and spindle speed from the dry run', log),
      h('div', { class: 'field-grid' }, field('Run name', name), field('Program', program), field('Format', format), field('Length units', units)),
      h('details', {}, h('summary', {}, 'Channel mapping (for logs with other column names)'), field('Mapping file (JSON)', mapping))),
    h('fieldset', {}, h('legend', {}, 'Machine, tool and material'),
      field('Run spec file (RUN.json)', specFile, 'Optional: fills the fields below from a spec used with cutload predict'),
      h('div', { class: 'field-grid' }, field('Machine', machine), field('Tool', tool), field('Material', material)),
      toolBox, materialBox),
    h('fieldset', {}, h('legend', {}, 'Stock and setup'), groups.stock.el, groups.setup.el,
      h('div', { class: 'field-grid' }, field('Base run', baseRun, 'Start from the final stock of a finished run'))),
    h('fieldset', {}, h('legend', {}, 'Limits (0 or empty: from the tool and machine)'), groups.limits.el),
    h('details', {}, h('summary', {}, 'Resolution'), groups.resolution.el),
    formError, h('div', { class: 'actions' }, submit), status);
  clear(main, h('h1', {}, 'New run'), form);

  specFile.addEventListener('change', async () => {
    setFieldError(specFile, '');
    const f = specFile.files[0];
    if (!f) return;
    try {
      const spec = JSON.parse(await f.text());
      for (const [k, g] of Object.entries(groups)) g.fill(spec[k]);
      if (spec.tool) tool.value = INLINE;
      if (spec.material) material.value = INLINE;
      syncInline();
    } catch (e) {
      setFieldError(specFile, `${f.name}: ${e.message}`);
    }
  });

  const selects = { machine_id: machine, tool_id: tool, material_id: material, base_run: baseRun, format, units, log, mapping };

  function clearErrors() {
    formError.textContent = '';
    Object.values(groups).forEach((g) => g.clearErrors());
    Object.values(selects).forEach((c) => setFieldError(c, ''));
  }

  // Puts a server message next to its field; unmatched messages go under the form.
  function showServerError(e) {
    const msg = e.message;
    if (e.code === 'bad_log' || /part 'log'/.test(msg)) return setFieldError(log, msg);
    for (const [partName, c] of Object.entries(selects)) {
      if (new RegExp(`^(part )?${partName}\\b`).test(msg)) return setFieldError(c, msg);
    }
    const [path] = splitKeyMessage(msg);
    if (path) {
      const top = path.split(/[.[]/)[0];
      if (top === 'tool' && tool.value !== INLINE) return setFieldError(tool, msg);
      if (top === 'material' && material.value !== INLINE) return setFieldError(material, msg);
      if (groups[top]?.showError(path, msg)) return undefined;
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
      for (const [path, why] of errors) problems.push(() => g.showError(path, `${path}: ${why}`));
      if (Object.keys(value).length) spec[k] = value;
    }
    if (!log.files[0]) problems.push(() => setFieldError(log, 'choose the dry-run log file'));
    if (problems.length) {
      problems.forEach((p) => p());
      formError.textContent = 'Some fields need attention.';
      form.querySelector('[aria-invalid="true"]')?.focus();
      return;
    }
    if (tool.value !== INLINE) spec.tool_id = Number(tool.value);
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

