// Human words for what the API names by key: engine flags, the loads they limit, log warnings,
// optimizer bindings. One place, so every page says the same thing.
import { num } from './dom.js';

// The loads a run spec limits (limits.*), with the block summary key holding each block's peak.
export const QUANTITIES = {
  force: { label: 'Force', unit: 'N', limit: 'force_N', peak: 'peak_force_N' },
  torque: { label: 'Torque', unit: 'N·m', limit: 'torque_Nm', peak: 'peak_torque_Nm' },
  power: { label: 'Power', unit: 'kW', limit: 'power_kW', peak: 'peak_power_kW' },
  chip: { label: 'Chip thickness', unit: 'mm', limit: 'chip_mm', peak: 'max_chip_mm' },
  bending: { label: 'Bending stress', unit: 'MPa', limit: 'bending_MPa', peak: 'max_bending_MPa' },
};

// Engine flags: a collision is worse than any load over its limit, whatever the margin.
export const FLAGS = {
  rapid_in_material: { label: 'Rapid move in material', short: 'Rapid in material', collision: true,
    explain: 'the tool cuts while moving at rapid speed' },
  holder_contact: { label: 'Holder touches the stock', short: 'Holder contact', collision: true,
    explain: 'the tool holder reaches the material' },
  holder_near_miss: { label: 'Holder passes close to the stock', short: 'Holder near miss', unit: 'mm',
    explain: 'the tool holder comes within the run\'s clearance shell (limits.holder_clearance_mm) without touching' },
  force_limit: { label: 'Force over its limit', short: 'Force', quantity: 'force' },
  torque_limit: { label: 'Torque over its limit', short: 'Torque', quantity: 'torque' },
  power_limit: { label: 'Power over its limit', short: 'Power', quantity: 'power' },
  chip_load_limit: { label: 'Chip thickness over its limit', short: 'Chip load', quantity: 'chip' },
  bending_limit: { label: 'Bending stress over its limit', short: 'Bending', quantity: 'bending' },
  unknown_tool: { label: 'Tool not in the run spec', short: 'Unknown tool',
    explain: 'the tool in the spindle is not in the run spec\'s tool table: no forces were predicted' },
  any: { label: 'Any flag', short: 'Any flag' },
};

export function flagLabel(code, { short = false } = {}) {
  const f = FLAGS[code];
  if (!f) return code.replace(/_/g, ' ');
  return short ? f.short : f.label;
}

// Threshold metrics (thresholds.metric).
export const METRICS = {
  peak_force_N: 'Peak force (N)',
  peak_torque_Nm: 'Peak torque (N·m)',
  peak_power_kW: 'Peak power (kW)',
  power_pct: 'Peak power (% of the spindle)',
  max_chip_mm: 'Chip thickness (mm)',
  max_bending_MPa: 'Bending stress (MPa)',
  flag: 'A flag',
};

export function metricLabel(key) {
  return METRICS[key] || key.replace(/_/g, ' ');
}

// Log warnings (inputs.ingest.warnings[].code), said as what they mean for the result.
const WARNINGS = {
  stale_repeat: 'Repeated position readings were dropped (the log read the position again before the control updated it)',
  gap: 'The log has gaps: time stamps jump further than the sampling allows',
  time_backwards: 'Time stamps go backwards in places; those rows were reordered or dropped',
  duplicate_time: 'Several rows share a time stamp',
  out_of_range: 'Some values are outside a plausible range and were left out',
  axis_incomplete: 'An axis is missing in some rows',
  feed_unit_override: 'The feed unit was set by hand and differs from what the log suggests',
  feed_unit_suspect: 'The feed values do not match the motion: check the feed unit',
  no_spindle: 'No spindle speed in the log: 0 rpm assumed (no cutting forces)',
  period_short_log: 'The log is short: the control\'s update period was taken from its time stamps',
  session_backwards: 'The log restarts with earlier times: it was split into sessions',
  session_gap: 'The log pauses: it was split into sessions',
  session_too_short: 'A piece of the log was too short to use and was left out',
  shdr_odd_fields: 'Some MTConnect lines have an odd number of fields',
  shdr_short_line: 'Some MTConnect lines are too short',
  shdr_unterminated: 'The MTConnect log ends in the middle of a line',
  unavailable: 'Some values are UNAVAILABLE in the log',
  unknown_column: 'The log has columns cutload does not use',
};

export function warningText(w) {
  const plain = WARNINGS[w.code] || w.code.replace(/_/g, ' ');
  const count = w.count > 1 ? ` (${w.count} times)` : '';
  return { plain: plain + count, detail: w.message };
}

// Optimizer binding quantities (result.blocks[].binding) use the QUANTITIES keys.
export function quantityLabel(key) {
  return QUANTITIES[key]?.label || key;
}

// "887 N" with the quantity's unit.
export function withUnit(value, quantity) {
  return `${num(value)} ${QUANTITIES[quantity]?.unit || ''}`.trim();
}

export function percent(fraction, digits = 3) {
  return fraction == null || Number.isNaN(fraction) ? '–' : `${num(100 * fraction, digits)} %`;
}
