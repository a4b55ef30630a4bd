// Small DOM and formatting helpers shared by the pages.

// h('button', {class: 'x', onclick: f}, 'text', child): an element with attributes, properties
// (on* handlers, dataset) and children; null/false children are skipped.
export function h(tag, attrs = {}, ...children) {
  const el = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (v === undefined || v === null || v === false) continue;
    if (k.startsWith('on') && typeof v === 'function') el.addEventListener(k.slice(2), v);
    else if (k === 'dataset') Object.assign(el.dataset, v);
    else if (k === 'value' || k === 'checked' || k === 'selected') el[k] = v;
    else el.setAttribute(k, v === true ? '' : v);
  }
  append(el, children);
  return el;
}

function append(el, children) {
  for (const c of children.flat(Infinity)) {
    if (c === null || c === undefined || c === false) continue;
    el.append(c instanceof Node ? c : String(c));
  }
}

export function clear(el, ...children) {
  el.replaceChildren();
  append(el, children);
  return el;
}

let uid = 0;
export function nextId(prefix) {
  uid += 1;
  return `${prefix}-${uid}`;
}

// Significant-figure formatting for forces, torques and the like.
export function num(v, digits = 3) {
  if (v === null || v === undefined || Number.isNaN(v)) return '–';
  if (v === 0) return '0';
  const a = Math.abs(v);
  if (a >= 1e5 || a < 1e-3) return v.toExponential(digits - 1);
  return Number(v.toPrecision(digits)).toLocaleString('en-US', { maximumFractionDigits: 6 });
}

export function seconds(v) {
  if (v === null || v === undefined) return '–';
  return `${v.toFixed(v < 10 ? 3 : 2)} s`;
}

export function when(iso) {
  if (!iso) return '–';
  const d = new Date(iso);
  return Number.isNaN(d.getTime()) ? iso : d.toLocaleString();
}

export function download(filename, blob) {
  const url = URL.createObjectURL(blob);
  const a = h('a', { href: url, download: filename });
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10000);
}

// A status line for a region: role=status so screen readers announce it.
export function statusLine(text = '') {
  return h('p', { class: 'status', role: 'status' }, text);
}

export function errorText(e) {
  return e?.message || String(e);
}

// One labelled form control: <div class=field><label/> control <p class=field-error/></div>.
// target is the element named by the label and described by the error slot: the control itself,
// or an input inside it (a drop zone), or a role=group (three inputs of a vector).
// required: the label gets a red asterisk and the control aria-required.
export function field(label, control, hint, target = control, { required = false } = {}) {
  const id = target.id || nextId('f');
  target.id = id;
  const labelable = /^(INPUT|SELECT|TEXTAREA)$/.test(target.tagName);
  // The asterisk sits beside the label, not in it: the control's name stays the label's words.
  const lab = h('label', labelable ? { for: id } : { id: `${id}-label` }, label);
  const head = required ? h('span', { class: 'label-row' }, lab, h('span', { class: 'req', 'aria-hidden': 'true' }, '*')) : lab;
  if (!labelable) target.setAttribute('aria-labelledby', `${id}-label`);
  if (required) {
    target.setAttribute('aria-required', 'true');
    target.dataset.label = label;
  }
  const err = h('p', { class: 'field-error', id: `${id}-err`, 'aria-live': 'polite' });
  target.setAttribute('aria-describedby', `${id}-err`);
  target.dataset.label = label;
  return h('div', { class: 'field' }, head, control, hint ? h('small', { class: 'muted' }, hint) : null, err);
}

// "Some fields need attention" with a link to each: errors [[control, message]].
export function errorSummary(box, errors) {
  if (!errors.length) {
    box.replaceChildren();
    return;
  }
  box.replaceChildren(h('strong', {}, errors.length === 1 ? 'One field needs attention:' : `${errors.length} fields need attention:`),
    h('ul', {}, errors.map(([control, message]) => h('li', {}, h('a', {
      href: `#${control.id}`,
      onclick: (e) => {
        e.preventDefault();
        (control.querySelector?.('input') || control).focus();
      },
    }, control.dataset.label || 'Field'), `: ${message}`))));
}

export function setFieldError(control, message) {
  const err = document.getElementById(`${control.id}-err`);
  if (err) err.textContent = message || '';
  control.toggleAttribute('aria-invalid', Boolean(message));
  if (message) control.setAttribute('aria-invalid', 'true');
}

// First index with x[i] >= v in an ascending array.
export function lowerBound(x, v) {
  let lo = 0;
  let hi = x.length;
  while (lo < hi) {
    const mid = (lo + hi) >> 1;
    if (x[mid] < v) lo = mid + 1;
    else hi = mid;
  }
  return lo;
}
