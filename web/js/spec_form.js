// Form fields for the parts of a run spec (docs/run_spec.md): tool, material, stock, setup,
// limits, resolution. A field group reads to and fills from the spec's JSON shape, and shows the
// server's "key.path: why" messages next to the matching field, with the field's label for the
// key (form_words.js).
import { h, field, setFieldError } from './dom.js';
import { labelParts, parseNumber, requiredMessage, humanizeMessage } from './form_words.js';

// The fields come from the run-spec schema the service publishes (OpenAPI components.RunSpec,
// derived from the service's own parser): loadSpecFields() fills these lists once, before a page
// builds a form. Labels are the schema's titles with its units; a tool field the schema limits to
// some shapes (x-tool-shapes) shows only for them, and x-required-shapes marks it required there.
export let TOOL_FIELDS = [];
export let MATERIAL_FIELDS = [];
export let STOCK_FIELDS = [];
export let SETUP_FIELDS = [];
export let LIMIT_FIELDS = [];
export let RESOLUTION_FIELDS = [];

// Field definitions of an object schema, nested objects flattened to dotted keys. Arrays other
// than x, y, z triples (the tool table) are not form fields: a table comes from a spec file.
export function fieldsOf(objectSchema, prefix = '', parentRequired = true) {
  const defs = [];
  const required = new Set(objectSchema.required || []);
  for (const [name, s] of Object.entries(objectSchema.properties || {})) {
    const key = prefix ? `${prefix}.${name}` : name;
    const isRequired = parentRequired && required.has(name);
    if (s.type === 'object') {
      defs.push(...fieldsOf(s, key, isRequired));
      continue;
    }
    const vec3 = s.type === 'array' && s.minItems === 3 && s.maxItems === 3;
    if (s.type === 'array' && !vec3) continue;
    const def = { key, label: s['x-unit'] ? `${s.title} (${s['x-unit']})` : s.title, required: isRequired };
    if (vec3) def.vec3 = true;
    else if (s.enum) def.options = s.enum;
    else if (s.type === 'string') def.text = true;
    if (s.type === 'integer') def.step = 1;
    if (s['x-tool-shapes']) def.shapes = s['x-tool-shapes'];
    if (s['x-required-shapes']) def.requiredShapes = s['x-required-shapes'];
    defs.push(def);
  }
  return defs;
}

let loading = null;
export function loadSpecFields() {
  loading ??= fetch('/api/v1/openapi.json')
    .then((r) => {
      if (!r.ok) throw new Error(`the run-spec schema could not be loaded (HTTP ${r.status})`);
      return r.json();
    })
    .then((doc) => {
      const spec = doc.components.schemas.RunSpec.properties;
      TOOL_FIELDS = fieldsOf(spec.tool);
      MATERIAL_FIELDS = fieldsOf(spec.material);
      STOCK_FIELDS = fieldsOf(spec.stock);
      SETUP_FIELDS = fieldsOf(spec.setup);
      LIMIT_FIELDS = fieldsOf(spec.limits);
      RESOLUTION_FIELDS = fieldsOf(spec.resolution);
    })
    .catch((e) => {
      loading = null;   // the next page load tries again
      throw e;
    });
  return loading;
}

function getPath(obj, path) {
  return path.split('.').reduce((o, k) => (o == null ? undefined : o[k]), obj);
}

function setPath(obj, path, value) {
  const keys = path.split('.');
  let o = obj;
  for (const k of keys.slice(0, -1)) o = o[k] ??= {};
  o[keys.at(-1)] = value;
}

function control(def, name) {
  if (def.options) return h('select', { name }, def.options.map((o) => h('option', { value: o }, o)));
  if (def.text) return h('input', { name, type: 'text' });
  return h('input', { name, type: 'text', inputmode: 'decimal', autocomplete: 'off' });
}

// prefix: the spec key of the group ("tool", "limits"; "" for a bare material body).
export function fieldGroup(prefix, defs) {
  const inputs = new Map();   // full key path -> control (vec3: the x control; all three in .parts)
  const wrappers = new Map(); // full key path -> the field's element (label, control, error)
  const el = h('div', { class: 'field-grid' });
  for (const def of defs) {
    const path = prefix ? `${prefix}.${def.key}` : def.key;
    const name = path.replace(/\./g, '-');
    if (def.vec3) {
      const parts = ['x', 'y', 'z'].map((a) =>
        h('input', { name: `${name}-${a}`, type: 'text', inputmode: 'decimal', 'aria-label': `${def.label}: ${a}`, class: 'vec' }));
      const group = h('div', { class: 'vec3', role: 'group', id: `${name}-group` }, parts);
      group.parts = parts;
      inputs.set(path, group);
      wrappers.set(path, el.appendChild(field(def.label, group, null, group, { required: def.required })));
    } else {
      const c = control(def, name);
      inputs.set(path, c);
      wrappers.set(path, el.appendChild(field(def.label, c, null, c, { required: def.required || !!def.requiredShapes })));
    }
  }
  // A tool's shape decides which fields apply (a cone's point angle) and which are required.
  const shapeControl = inputs.get(prefix ? `${prefix}.shape` : 'shape');
  const currentShape = () => shapeControl?.value;
  const applies = (def) => !def.shapes || !shapeControl || def.shapes.includes(currentShape());
  const requiredNow = (def) => def.required || (!!def.requiredShapes && def.requiredShapes.includes(currentShape()));
  function syncShape() {
    for (const def of defs) {
      const path = prefix ? `${prefix}.${def.key}` : def.key;
      wrappers.get(path).hidden = !applies(def);
      if (def.requiredShapes) {
        const wrap = wrappers.get(path);
        const star = wrap.querySelector('.req');
        if (star) star.hidden = !requiredNow(def);
        inputs.get(path).setAttribute('aria-required', String(requiredNow(def)));
      }
    }
  }
  shapeControl?.addEventListener('change', syncShape);
  syncShape();
  const labelOf = new Map(defs.map((d) => [prefix ? `${prefix}.${d.key}` : d.key, d.label]));

  // Returns {value, errors: [[path, message]]}: value without the prefix ({diameter_mm: 8} for
  // the tool group); empty optional fields are left out. Every field is checked: all problems
  // at once, each in plain words.
  function read() {
    const value = {};
    const errors = [];
    for (const def of defs) {
      if (!applies(def)) continue;
      const path = prefix ? `${prefix}.${def.key}` : def.key;
      const c = inputs.get(path);
      if (def.vec3) {
        const texts = c.parts.map((p) => p.value);
        if (texts.every((t) => t.trim() === '')) {
          if (def.required) errors.push([path, `Required: enter x, y and z (${labelParts(def.label).unit || 'mm'}).`]);
          continue;
        }
        const parsed = texts.map((t, k) => (t.trim() === '' ? { error: `Enter ${'xyz'[k]} too.` } : parseNumber(t, def.label)));
        const bad = parsed.find((p) => p.error);
        if (bad) errors.push([path, bad.error]);
        else setPath(value, def.key, parsed.map((p) => p.value));
      } else if (c.value.trim() === '') {
        if (requiredNow(def)) errors.push([path, requiredMessage(def.label)]);
      } else if (def.options || def.text) {
        setPath(value, def.key, c.value);
      } else {
        const p = parseNumber(c.value, def.label, { integer: def.step === 1 });
        if (p.error) errors.push([path, p.error]);
        else setPath(value, def.key, p.value);
      }
    }
    return { value, errors };
  }

  function fill(obj) {
    for (const def of defs) {
      const path = prefix ? `${prefix}.${def.key}` : def.key;
      const c = inputs.get(path);
      const v = getPath(obj || {}, def.key);
      if (def.vec3) c.parts.forEach((p, i) => { p.value = Array.isArray(v) ? String(v[i] ?? '') : ''; });
      else c.value = v === undefined || v === null ? (def.options ? def.options[0] : '') : String(v);
    }
    syncShape();
  }

  // Shows message at the field whose key path starts the message ("tool.diameter_mm: ...");
  // returns false when no field of this group matches.
  // The message's key paths become the fields' labels. Returns the control, or null.
  function showError(path, message) {
    let best = null;
    for (const key of inputs.keys()) {
      if ((path === key || path.startsWith(`${key}.`) || path.startsWith(`${key}[`)) && (!best || key.length > best.length)) best = key;
    }
    if (!best) return null;
    setFieldError(inputs.get(best), humanizeMessage(message, labelOf));
    return inputs.get(best);
  }

  function clearErrors() {
    for (const c of inputs.values()) setFieldError(c, '');
  }

  return { el, read, fill, showError, clearErrors, inputs, prefix, labelOf };
}

// "tool.diameter_mm: must be in (0, 200] mm" -> ["tool.diameter_mm", whole message]
export function splitKeyMessage(message) {
  const m = /^([A-Za-z_][\w.[\]]*):\s/.exec(message);
  return m ? [m[1], message] : [null, message];
}
