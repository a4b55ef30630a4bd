// Libraries: machines, tools, materials and alert thresholds. Each section lists its items with
// Edit and Delete, and has a form that creates or updates one; server errors sit by the field.
import { api } from './api.js';
import { h, clear, field, num, setFieldError, statusLine, errorText } from './dom.js';
import { fieldGroup, splitKeyMessage, TOOL_FIELDS, MATERIAL_FIELDS, LIMIT_FIELDS } from './spec_form.js';

const nameField = (label) => [{ key: 'name', label, text: true, required: true }];

// Several field groups read and shown as one form; a group with a prefix reads into that key.
function compose(...groups) {
  return {
    el: h('div', {}, groups.map((g) => g.el)),
    read() {
      const value = {};
      const errors = [];
      for (const g of groups) {
        const r = g.read();
        if (!g.prefix) Object.assign(value, r.value);
        else if (Object.keys(r.value).length) value[g.prefix] = r.value;
        errors.push(...r.errors);
      }
      return { value, errors };
    },
    fill: (item) => groups.forEach((g) => g.fill(item)),
    showError: (path, msg) => groups.some((g) => g.showError(path, msg)),
    clearErrors: () => groups.forEach((g) => g.clearErrors()),
  };
}

function machineForm() {
  return compose(fieldGroup('', [...nameField('Machine name'),
    { key: 'spindle_power_kW', label: 'Spindle power (kW)', required: true },
    { key: 'spindle_torque_Nm', label: 'Spindle torque (N·m)', required: true },
    { key: 'max_feed_mm_min', label: 'Max feed (mm/min)', required: true }]));
}

function toolForm() {
  const name = fieldGroup('', nameField('Tool name'));
  const tool = fieldGroup('tool', TOOL_FIELDS);
  const limits = fieldGroup('limits', LIMIT_FIELDS.filter((f) => f.key !== 'rapid_feed_mm_min')
    .map((f) => ({ ...f, label: `${f.label.replace(/ \(/, ' limit (')}` })));
  const form = compose(name, tool, limits);
  form.fill = (item) => {
    name.fill(item);
    tool.fill(item?.tool);
    limits.fill(item?.limits);
  };
  return form;
}

function materialForm() {
  return compose(fieldGroup('', MATERIAL_FIELDS.map((f) => (f.key === 'name' ? { ...f, required: true } : f))));
}

const METRICS = ['peak_force_N', 'peak_torque_Nm', 'peak_power_kW', 'power_pct', 'max_chip_mm', 'max_bending_MPa', 'flag'];
const FLAGS = ['any', 'force_limit', 'torque_limit', 'power_limit', 'chip_load_limit', 'bending_limit', 'rapid_in_material', 'holder_contact'];

function thresholdForm(lib) {
  const name = h('input', { name: 'name', type: 'text' });
  const target = h('select', { name: 'target' }, h('option', { value: 'any' }, 'every run'),
    ['machines', 'tools', 'materials'].map((k) => h('optgroup', { label: k },
      lib[k].map((x) => h('option', { value: `${k.slice(0, -1)}:${x.id}` }, x.name)))));
  const metric = h('select', { name: 'metric' }, METRICS.map((m) => h('option', { value: m }, m)));
  const flag = h('select', { name: 'flag' }, FLAGS.map((m) => h('option', { value: m }, m)));
  const limit = h('input', { name: 'limit', type: 'text', inputmode: 'decimal' });
  const severity = h('select', { name: 'severity' }, ['warning', 'critical', 'info'].map((m) => h('option', { value: m }, m)));
  const enabled = h('select', { name: 'enabled' }, h('option', { value: 'true' }, 'yes'), h('option', { value: 'false' }, 'no'));
  const flagField = field('Flag', flag);
  const limitField = field('Limit', limit, 'power_pct: percent of the spindle power');
  const sync = () => {
    flagField.hidden = metric.value !== 'flag';
    limitField.hidden = metric.value === 'flag';
  };
  metric.addEventListener('change', sync);
  sync();
  const controls = { name, scope: target, machine_id: target, tool_id: target, material_id: target, metric, flag, limit, severity, enabled };
  return {
    el: h('div', { class: 'field-grid' }, field('Threshold name', name), field('Applies to', target), field('Metric', metric),
      flagField, limitField, field('Severity', severity), field('Enabled', enabled)),
    read() {
      const errors = [];
      const value = { name: name.value.trim(), metric: metric.value, severity: severity.value, enabled: enabled.value === 'true' };
      if (!value.name) errors.push(['name', 'required']);
      const [scope, sid] = target.value.split(':');
      value.scope = scope;
      if (sid) value[`${scope}_id`] = Number(sid);
      if (metric.value === 'flag') value.flag = flag.value;
      else if (limit.value.trim() === '' || !Number.isFinite(Number(limit.value))) errors.push(['limit', 'must be a number']);
      else value.limit = Number(limit.value);
      return { value, errors };
    },
    fill(t) {
      name.value = t?.name || '';
      const sid = t && t.scope !== 'any' ? t[`${t.scope}_id`] : null;
      target.value = sid ? `${t.scope}:${sid}` : 'any';
      metric.value = t?.metric || METRICS[0];
      flag.value = t?.flag || 'any';
      limit.value = t?.limit ?? '';
      severity.value = t?.severity || 'warning';
      enabled.value = String(t?.enabled ?? true);
      sync();
    },
    showError(path, msg) {
      const c = controls[path];
      if (!c) return false;
      setFieldError(c, msg);
      return true;
    },
    clearErrors: () => new Set(Object.values(controls)).forEach((c) => setFieldError(c, '')),
  };
}

function section({ id, title, singular, columns, makeForm, list, create, update, remove }) {
  const tbody = h('tbody');
  const status = statusLine();
  const form = makeForm();
  const formTitle = h('h3', {}, `New ${singular}`);
  const formError = h('p', { class: 'form-error', role: 'alert' });
  const save = h('button', { type: 'submit', class: 'primary' }, 'Create');
  const cancel = h('button', { type: 'button', hidden: true }, 'Cancel edit');
  let editing = null;
  const el = h('section', { class: 'library', id, 'aria-labelledby': `${id}-title` },
    h('h2', { id: `${id}-title` }, title),
    h('table', { class: 'grid' },
      h('thead', {}, h('tr', {}, [...columns.map(([c]) => c), ''].map((c) => h('th', { scope: 'col' }, c)))), tbody),
    status,
    h('form', { class: 'library-form', novalidate: true, 'aria-labelledby': `${id}-form-title`, onsubmit: submit },
      formTitle, form.el, formError, h('div', { class: 'actions' }, save, cancel)));
  formTitle.id = `${id}-form-title`;

  function edit(item) {
    editing = item;
    form.clearErrors();
    formError.textContent = '';
    form.fill(item);
    formTitle.textContent = item ? `Edit ${singular} ${item.name}` : `New ${singular}`;
    save.textContent = item ? 'Save' : 'Create';
    cancel.hidden = !item;
    if (item) form.el.querySelector('input, select')?.focus();
  }
  cancel.addEventListener('click', () => edit(null));

  async function load() {
    try {
      const items = await list();
      tbody.replaceChildren(...items.map((item) => h('tr', {},
        columns.map(([, fn]) => h('td', {}, fn(item))),
        h('td', { class: 'row-actions' },
          h('button', { type: 'button', onclick: () => edit(item), 'aria-label': `Edit ${item.name}` }, 'Edit'),
          h('button', {
            type: 'button',
            'aria-label': `Delete ${item.name}`,
            onclick: async () => {
              if (!window.confirm(`Delete ${singular} ${item.name}?`)) return;
              try {
                await remove(item.id);
                await load();
              } catch (e) {
                status.textContent = errorText(e);
              }
            },
          }, 'Delete')))));
      status.textContent = items.length ? '' : `No ${title.toLowerCase()} yet.`;
    } catch (e) {
      status.textContent = errorText(e);
    }
  }

  async function submit(e) {
    e.preventDefault();
    form.clearErrors();
    formError.textContent = '';
    const { value, errors } = form.read();
    if (errors.length) {
      for (const [path, why] of errors) if (!form.showError(path, `${path}: ${why}`)) formError.textContent = `${path}: ${why}`;
      return;
    }
    try {
      if (editing) await update(editing.id, value);
      else await create(value);
      edit(null);
      await load();
    } catch (ex) {
      const [path] = splitKeyMessage(ex.message);
      const key = ex.code === 'name_taken' ? 'name' : path;
      if (!key || !form.showError(key, ex.message)) formError.textContent = ex.message;
    }
  }

  edit(null);
  load();
  return el;
}

export async function renderLibraries(main) {
  const lib = {};
  for (const k of ['machines', 'tools', 'materials']) {
    try {
      lib[k] = await api.library(k);
    } catch {
      lib[k] = [];
    }
  }
  const crud = (kind) => ({
    list: () => api.library(kind),
    create: (b) => api.createItem(kind, b),
    update: (id, b) => api.updateItem(kind, id, b),
    remove: (id) => api.deleteItem(kind, id),
  });
  const scopeName = (t) => {
    if (t.scope === 'any') return 'every run';
    const item = lib[`${t.scope}s`].find((x) => x.id === t[`${t.scope}_id`]);
    return `${t.scope} ${item ? item.name : `#${t[`${t.scope}_id`]}`}`;
  };
  clear(main, h('h1', {}, 'Libraries'),
    h('nav', { class: 'toc', 'aria-label': 'Library sections' },
      h('a', { href: '#/libraries', onclick: jump('lib-machines') }, 'Machines'),
      h('a', { href: '#/libraries', onclick: jump('lib-tools') }, 'Tools'),
      h('a', { href: '#/libraries', onclick: jump('lib-materials') }, 'Materials'),
      h('a', { href: '#/libraries', onclick: jump('lib-thresholds') }, 'Thresholds')),
    section({ id: 'lib-machines', title: 'Machines', singular: 'machine', makeForm: machineForm, ...crud('machines'),
      columns: [['Name', (m) => m.name], ['Spindle power', (m) => `${num(m.spindle_power_kW)} kW`],
        ['Spindle torque', (m) => `${num(m.spindle_torque_Nm)} N·m`], ['Max feed', (m) => `${num(m.max_feed_mm_min)} mm/min`]] }),
    section({ id: 'lib-tools', title: 'Tools', singular: 'tool', makeForm: toolForm, ...crud('tools'),
      columns: [['Name', (t) => t.name], ['Shape', (t) => t.tool.shape], ['Diameter', (t) => `${t.tool.diameter_mm} mm`],
        ['Flutes', (t) => t.tool.flutes], ['Limits', (t) => Object.entries(t.limits || {}).map(([k, v]) => `${k} ${v}`).join(', ') || '–']] }),
    section({ id: 'lib-materials', title: 'Materials', singular: 'material', makeForm: materialForm, ...crud('materials'),
      columns: [['Name', (m) => m.name], ['Ktc', (m) => `${num(m.Ktc_N_mm2)} N/mm²`], ['Krc', (m) => `${num(m.Krc_N_mm2)} N/mm²`],
        ['Kte', (m) => `${num(m.Kte_N_mm)} N/mm`]] }),
    section({ id: 'lib-thresholds', title: 'Thresholds', singular: 'threshold', makeForm: () => thresholdForm(lib),
      list: () => api.thresholds(), create: (b) => api.createItem('thresholds', b),
      update: (id, b) => api.updateItem('thresholds', id, b), remove: (id) => api.deleteItem('thresholds', id),
      columns: [['Name', (t) => t.name], ['Applies to', scopeName],
        ['Rule', (t) => (t.metric === 'flag' ? `flag ${t.flag}` : `${t.metric} > ${num(t.limit)}`)],
        ['Severity', (t) => t.severity], ['Enabled', (t) => (t.enabled ? 'yes' : 'no')]] }));
  return null;
}

function jump(id) {
  return (e) => {
    e.preventDefault();
    const el = document.getElementById(id);
    el.scrollIntoView();
    el.querySelector('h2').setAttribute('tabindex', '-1');
    el.querySelector('h2').focus();
  };
}
