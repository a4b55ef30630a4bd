// Libraries: machines, tools, materials and alert thresholds. Each section lists its items with
// Edit and Delete, and has a form that creates or updates one; server errors sit by the field.
import { api } from './api.js';
import { h, clear, field, num, setFieldError, statusLine, errorText, errorSummary } from './dom.js';
import { METRICS, metricLabel, flagLabel, QUANTITIES } from './labels.js';
import { parseNumber } from './form_words.js';
import { fieldGroup, loadSpecFields, splitKeyMessage, TOOL_FIELDS, MATERIAL_FIELDS, LIMIT_FIELDS } from './spec_form.js';

const nameField = (label) => [{ key: 'name', label, text: true, required: true }];

// "force_N 860" -> "Force 860 N".
function limitText(key, v) {
  const q = Object.values(QUANTITIES).find((x) => x.limit === key);
  return q ? `${q.label} ${num(v)} ${q.unit}` : `${key.replace(/_/g, ' ')} ${num(v)}`;
}

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
    showError: (path, msg) => groups.reduce((found, g) => found || g.showError(path, msg), null),
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

const METRIC_KEYS = Object.keys(METRICS);
const FLAG_KEYS = ['any', 'force_limit', 'torque_limit', 'power_limit', 'chip_load_limit', 'bending_limit', 'rapid_in_material', 'holder_contact', 'holder_near_miss', 'unknown_tool'];

function thresholdForm(lib) {
  const name = h('input', { name: 'name', type: 'text' });
  const target = h('select', { name: 'target' }, h('option', { value: 'any' }, 'every run'),
    ['machines', 'tools', 'materials'].map((k) => h('optgroup', { label: k },
      lib[k].map((x) => h('option', { value: `${k.slice(0, -1)}:${x.id}` }, x.name)))));
  const metric = h('select', { name: 'metric' }, METRIC_KEYS.map((m) => h('option', { value: m }, metricLabel(m))));
  const flag = h('select', { name: 'flag' }, FLAG_KEYS.map((m) => h('option', { value: m }, flagLabel(m))));
  const limit = h('input', { name: 'limit', type: 'text', inputmode: 'decimal' });
  const severity = h('select', { name: 'severity' }, ['warning', 'critical', 'info'].map((m) => h('option', { value: m }, m)));
  const enabled = h('select', { name: 'enabled' }, h('option', { value: 'true' }, 'yes'), h('option', { value: 'false' }, 'no'));
  const flagField = field('Flag', flag);
  const limitField = field('Limit', limit, 'In the unit of the metric; for peak power as % of the spindle, a percentage', limit, { required: true });
  const sync = () => {
    flagField.hidden = metric.value !== 'flag';
    limitField.hidden = metric.value === 'flag';
  };
  metric.addEventListener('change', sync);
  sync();
  const controls = { name, scope: target, machine_id: target, tool_id: target, material_id: target, metric, flag, limit, severity, enabled };
  return {
    el: h('div', { class: 'field-grid' }, field('Threshold name', name, null, name, { required: true }), field('Applies to', target), field('Metric', metric),
      flagField, limitField, field('Severity', severity), field('Enabled', enabled)),
    read() {
      const errors = [];
      const value = { name: name.value.trim(), metric: metric.value, severity: severity.value, enabled: enabled.value === 'true' };
      if (!value.name) errors.push(['name', 'Required: enter a name for the threshold.']);
      const [scope, sid] = target.value.split(':');
      value.scope = scope;
      if (sid) value[`${scope}_id`] = Number(sid);
      if (metric.value === 'flag') value.flag = flag.value;
      else if (limit.value.trim() === '') errors.push(['limit', 'Required: enter the limit the metric must stay under.']);
      else {
        const p = parseNumber(limit.value, 'Limit');
        if (p.error) errors.push(['limit', p.error]);
        else value.limit = p.value;
      }
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
      if (!c) return null;
      setFieldError(c, msg.replace(/^(name|scope|machine_id|tool_id|material_id|metric|flag|limit|severity|enabled):\s*/, ''));
      return c;
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
  const summary = h('div', { class: 'error-summary', role: 'alert' });
  const save = h('button', { type: 'submit', class: 'primary' }, 'Create');
  const cancel = h('button', { type: 'button', hidden: true }, 'Cancel edit');
  let editing = null;
  const el = h('section', { class: 'library', id, 'aria-labelledby': `${id}-title` },
    h('h2', { id: `${id}-title` }, title),
    h('table', { class: 'grid' },
      h('thead', {}, h('tr', {}, [...columns.map(([c]) => c), ''].map((c) => h('th', { scope: 'col' }, c)))), tbody),
    status,
    h('form', { class: 'library-form', novalidate: true, 'aria-labelledby': `${id}-form-title`, onsubmit: submit },
      formTitle, h('p', { class: 'required-note muted' }, 'Fields marked ', h('span', { class: 'req' }, '*'), ' are required.'),
      form.el, summary, formError, h('div', { class: 'actions' }, save, cancel)));
  formTitle.id = `${id}-form-title`;

  function edit(item) {
    editing = item;
    form.clearErrors();
    formError.textContent = '';
    errorSummary(summary, []);
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
    errorSummary(summary, []);
    const { value, errors } = form.read();
    if (errors.length) {
      // Every problem at once, by its field and in the list above the button.
      const shown = [];
      for (const [path, why] of errors) {
        const c = form.showError(path, why);
        if (c) shown.push([c, why]);
        else formError.textContent = why;
      }
      errorSummary(summary, shown);
      el.querySelector('[aria-invalid="true"]')?.focus();
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
      const c = key ? form.showError(key, ex.message) : null;
      if (c) errorSummary(summary, [[c, document.getElementById(`${c.id}-err`)?.textContent || ex.message]]);
      else formError.textContent = ex.message;
    }
  }

  edit(null);
  load();
  return el;
}

export async function renderLibraries(main) {
  try {
    await loadSpecFields();
  } catch (e) {
    main.append(h('p', { class: 'form-error', role: 'alert' }, `${e.message}: reload the page.`));
    return;
  }
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
        ['Flutes', (t) => t.tool.flutes], ['Limits', (t) => Object.entries(t.limits || {}).filter(([, v]) => v > 0).map(([k, v]) => limitText(k, v)).join(', ') || '–']] }),
    section({ id: 'lib-materials', title: 'Materials', singular: 'material', makeForm: materialForm, ...crud('materials'),
      columns: [['Name', (m) => m.name], ['Ktc', (m) => `${num(m.Ktc_N_mm2)} N/mm²`], ['Krc', (m) => `${num(m.Krc_N_mm2)} N/mm²`],
        ['Kte', (m) => `${num(m.Kte_N_mm)} N/mm`]] }),
    section({ id: 'lib-thresholds', title: 'Thresholds', singular: 'threshold', makeForm: () => thresholdForm(lib),
      list: () => api.thresholds(), create: (b) => api.createItem('thresholds', b),
      update: (id, b) => api.updateItem('thresholds', id, b), remove: (id) => api.deleteItem('thresholds', id),
      columns: [['Name', (t) => t.name], ['Applies to', scopeName],
        ['Rule', (t) => (t.metric === 'flag' ? `flag: ${flagLabel(t.flag)}` : `${metricLabel(t.metric)} over ${num(t.limit)}`)],
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
