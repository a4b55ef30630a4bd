// Form messages in plain words, built from a field's label ("Diameter (mm)") so that no form
// keeps its own copy of what a field is: the label names it, the unit comes from the label.
//
// "8,5" gets a hint about the decimal point; a required field that is empty says what to enter;
// a server message "tool.diameter_mm: must be in (0, 200] mm" is shown as "Diameter (mm): must
// be in (0, 200] mm" next to the field.

// "Diameter (mm)" -> {name: "diameter", unit: "mm"}.
export function labelParts(label) {
  const m = /^(.*?)\s*\(([^)]*)\)\s*$/.exec(label);
  const name = (m ? m[1] : label).trim();
  // A word starts lower case inside a sentence; a symbol (Ktc, Kae) keeps its case.
  const first = name.split(/[\s-]/)[0];
  const word = /^[A-Z][a-z]/.test(first) && first.length > 3;
  return { name: word ? name[0].toLowerCase() + name.slice(1) : name, unit: m ? m[2] : '' };
}

export function requiredMessage(label) {
  const { name, unit } = labelParts(label);
  return `Required: enter the ${name}${unit ? ` in ${unit}` : ''}.`;
}

// Parses a number as typed; {value} or {error} in plain words.
export function parseNumber(text, label, { integer = false } = {}) {
  const t = text.trim();
  const { name, unit } = labelParts(label);
  if (/^[+-]?\d*,\d+$/.test(t)) {
    return { error: `“${t}” has a decimal comma: write ${t.replace(',', '.')} with a decimal point.` };
  }
  const v = Number(t);
  if (t === '' || !Number.isFinite(v)) {
    return { error: `“${t}” is not a number: enter the ${name}${unit ? ` in ${unit}` : ''}, e.g. ${integer ? '2' : '8.5'}.` };
  }
  if (integer && !Number.isInteger(v)) return { error: `Enter a whole number for the ${name} (“${t}” has a fraction).` };
  return { value: v };
}

// Replaces key paths in a server message by the labels of the fields they name, longest first:
// "tool.diameter_mm: must be > 0" -> "Diameter (mm): must be > 0".
export function humanizeMessage(message, labelOf) {
  let out = message;
  const keys = [...labelOf.keys()].sort((a, b) => b.length - a.length);
  for (const k of keys) {
    if (!out.includes(k)) continue;
    out = out.split(k).join(labelOf.get(k));
  }
  return out.charAt(0).toUpperCase() + out.slice(1);
}
