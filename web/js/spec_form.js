// Form fields for the parts of a run spec (docs/run_spec.md): tool, material, stock, setup,
// limits, resolution. A field group reads to and fills from the spec's JSON shape, and shows the
// server's "key.path: why" messages next to the matching field, with the field's label for the
// key (form_words.js). These lists are the page's one copy of the spec's fields.
import { h, field, setFieldError } from './dom.js';
import { labelParts, parseNumber, requiredMessage, humanizeMessage } from './form_words.js';

export const TOOL_FIELDS = [
  { key: 'shape', label: 'Shape', options: ['flat', 'ball', 'bull'], required: true },
  { key: 'diameter_mm', label: 'Diameter (mm)', required: true },
  { key: 'flutes', label: 'Flutes', required: true, step: 1 },
  { key: 'helix_deg', label: 'Helix (deg)', required: true },
  { key: 'corner_radius_mm', label: 'Corner radius (mm)' },
  { key: 'flute_length_mm', label: 'Flute length (mm)', required: true },
  { key: 'stickout_mm', label: 'Stick-out (mm)', required: true },
  { key: 'holder.diameter_mm', label: 'Holder diameter (mm)' },
  { key: 'holder.length_mm', label: 'Holder length (mm)' },
];

export const MATERIAL_FIELDS = [
  { key: 'name', label: 'Material name', text: true },
  { key: 'Ktc_N_mm2', label: 'Ktc (N/mm²)', required: true },
  { key: 'Krc_N_mm2', label: 'Krc (N/mm²)', required: true },
  { key: 'Kac_N_mm2', label: 'Kac (N/mm²)', required: true },
  { key: 'Kte_N_mm', label: 'Kte (N/mm)', required: true },
  { key: 'Kre_N_mm', label: 'Kre (N/mm)', required: true },
  { key: 'Kae_N_mm', label: 'Kae (N/mm)', required: true },
];

export const STOCK_FIELDS = [
  { key: 'box_mm.min', label: 'Stock min x, y, z (mm)', vec3: true, required: true },
  { key: 'box_mm.max', label: 'Stock max x, y, z (mm)', vec3: true, required: true },
];

export const SETUP_FIELDS = [{ key: 'offset_mm', label: 'Offset x, y, z (mm)', vec3: true }];

export const LIMIT_FIELDS = [
  { key: 'force_N', label: 'Force (N)' },
  { key: 'torque_Nm', label: 'Torque (N·m)' },
  { key: 'power_kW', label: 'Power (kW)' },
  { key: 'chip_mm', label: 'Chip thickness (mm)' },
  { key: 'bending_MPa', label: 'Bending (MPa)' },
  { key: 'rapid_feed_mm_min', label: 'Rapid feed (mm/min)' },
];

export const RESOLUTION_FIELDS = [
  { key: 'angle_step_deg', label: 'Angle step (deg)' },
  { key: 'axial_step_mm', label: 'Axial step (mm)' },
  { key: 'grid_mm', label: 'Grid (mm)' },
];

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
      el.append(field(def.label, group, null, group, { required: def.required }));
    } else {
      const c = control(def, name);
      inputs.set(path, c);
      el.append(field(def.label, c, null, c, { required: def.required }));
    }
  }
  const labelOf = new Map(defs.map((d) => [prefix ? `${prefix}.${d.key}` : d.key, d.label]));

  // Returns {value, errors: [[path, message]]}: value without the prefix ({diameter_mm: 8} for
  // the tool group); empty optional fields are left out. Every field is checked: all problems
  // at once, each in plain words.
  function read() {
    const value = {};
    const errors = [];
    for (const def of defs) {
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
        if (def.required) errors.push([path, requiredMessage(def.label)]);
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
