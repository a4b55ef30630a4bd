// How the tool stands in the 3-D view. A run whose tool was tilted at one fixed orientation while
// it cut (3+2 machining, docs/five_axis.md §2.5) reports that orientation as summary.kinematics;
// a run whose tool turned while it cut (simultaneous five-axis, §3.4: kinematics.turning) carries
// its axis per sample in its /motion answer (tool_axis_x, _y, _z); every other run cut with the
// tool along the stock's +Z. No three.js and no DOM here, so node's test runner loads this module
// as it is.
import { num } from './dom.js';

// The fixed tilt's axis (unit, tip to spindle, stock axes), or null where the tool stands along
// +Z: a three-axis run, a five-axis run that never leaned, or a summary without a usable axis.
export function toolAxis(kinematics) {
  const a = kinematics?.fixed_tilt ? kinematics.tool_axis : null;
  if (!Array.isArray(a) || a.length !== 3 || !a.every(Number.isFinite)) return null;
  const len = Math.hypot(a[0], a[1], a[2]);
  return len > 0 ? a.map((v) => v / len) : null;
}

// The quaternion [x, y, z, w] turning +Z onto the unit `axis` along the shortest arc: the tool is
// built around +Z from its tip. Straight down has no shortest arc; half a turn about X is taken.
export function axisQuaternion(axis) {
  const [ax, ay, az] = axis;
  const w = 1 + az;
  if (w < 1e-12) return [1, 0, 0, 0];
  const n = Math.hypot(ay, ax, w);
  return [-ay / n, ax / n, 0, w / n];
}

// The tool's axis per sample of a /motion answer (unit, tip to spindle, stock axes) as x, y, z
// triples in one Float32Array, or null where the answer carries none (every run but a turning
// tool's, and a turning run stored before the axis was). A decimated answer's bucket gives the
// middle of each component's range, made unit again: the axis turns little within a bucket.
export function motionAxes(w) {
  const cols = [w?.tool_axis_x, w?.tool_axis_y, w?.tool_axis_z];
  if (!cols.every(Boolean)) return null;
  const n = w.t_s.length;
  const out = new Float32Array(3 * n);
  const at = (c, i) => (w.decimated ? (c.min[i] + c.max[i]) / 2 : c[i]);
  for (let i = 0; i < n; i++) {
    const v = cols.map((c) => at(c, i));
    const len = Math.hypot(v[0], v[1], v[2]);
    // A missing value (null) or a zero vector: the one before, else +Z.
    if (!(len > 0)) {
      if (i > 0) out.copyWithin(3 * i, 3 * (i - 1), 3 * i);
      else out[2] = 1;
      continue;
    }
    for (let k = 0; k < 3; k++) out[3 * i + k] = v[k] / len;
  }
  return out;
}

// The axis at path point i ([x, y, z]) of a path that carries one per point (path.axis, as
// motionAxes gives it), else null.
export function pointAxis(path, i) {
  const a = path?.axis;
  if (!a || i == null || i < 0 || 3 * i + 2 >= a.length) return null;
  return [a[3 * i], a[3 * i + 1], a[3 * i + 2]];
}

// Short strokes up the tool's axis from path points about `spacing_mm` apart along the path (the
// first point, then the first one at least that far on, ...), each `length_mm` long: how the tool leans along the path, for the 3-D view. At most
// `max` strokes (the spacing grows to fit). Returns {segments: Float32Array of x0 y0 z0 x1 y1 z1
// per stroke, points: the path indices}; none for a path without an axis per point.
export function axisTicks(path, { spacing_mm, length_mm, max = 400 }) {
  if (!path?.axis) return { segments: new Float32Array(0), points: [] };
  const { x, y, z } = path;
  const n = x.length;
  let total = 0;
  for (let i = 1; i < n; i++) total += Math.hypot(x[i] - x[i - 1], y[i] - y[i - 1], z[i] - z[i - 1]);
  const spacing = Math.max(spacing_mm, total / Math.max(1, max - 1), 1e-9);
  const points = [];
  let since = Infinity;
  for (let i = 0; i < n; i++) {
    if (i > 0) since += Math.hypot(x[i] - x[i - 1], y[i] - y[i - 1], z[i] - z[i - 1]);
    if (since >= spacing && points.length < max) {
      points.push(i);
      since = 0;
    }
  }
  const segments = new Float32Array(6 * points.length);
  points.forEach((i, k) => {
    const a = pointAxis(path, i);
    segments.set([x[i], y[i], z[i], x[i] + length_mm * a[0], y[i] + length_mm * a[1], z[i] + length_mm * a[2]], 6 * k);
  });
  return { segments, points };
}

// The legend's words for a tilted or turning run (null otherwise), in the stock axes the view
// labels. `perSample`: the path carries the turning tool's axis per point (motionAxes).
export function toolAxisText(kinematics, { perSample = false } = {}) {
  if (kinematics?.turning) {
    const lean = Number.isFinite(kinematics.tool_lean_deg) ? `, leaning up to ${num(kinematics.tool_lean_deg)}° from +Z` : '';
    return perSample
      ? `Tool turning while it cuts (simultaneous five-axis)${lean}: drawn on its axis at the cursor, its axis along the path as short strokes; the stock shown is the final stock`
      : `Tool turning while it cuts (simultaneous five-axis)${lean}: this run was stored without its axis per sample, so the tool is drawn along +Z`;
  }
  const a = toolAxis(kinematics);
  if (!a) return null;
  // The server's unit vector carries float noise (6e-17 for a nought): shown as 0, not 6e-17.
  const parts = a.map((v) => num(Math.abs(v) < 5e-4 ? 0 : v));
  const leanDeg = Number.isFinite(kinematics.tool_lean_deg) ? kinematics.tool_lean_deg : (Math.acos(Math.min(1, Math.max(-1, a[2]))) * 180) / Math.PI;
  return `Tool axis (${parts.join(', ')}), lean ${num(leanDeg)}° from +Z, fixed while it cuts (3+2)`;
}

// A tilted cutter's lowest point above each spot near its tip, for the in-process stock's height
// field: the cutter is the solid of revolution about `axis` from its tip, between its end profile
// (`profile(r_mm)`: height above the tip at r from the axis, as view3d's toolProfile) and
// `length_mm` up the axis, no wider than `radius_mm`. Seen from the stock's +Z the orientation is
// fixed, so each offset's lowest point is worked out once per tool and kept in a table with
// `step_mm` between nodes (coarser where that would exceed MAX_LIFT_NODES).
//
// Along a vertical line the cutter is one interval (a convex solid): with s the height along the
// axis and rho the distance from it, f(t) = max(G(rho) - s, s - length, K (rho - radius)) is convex
// in t and f <= 0 exactly inside. G is the profile continued steeply (K) past the radius, where
// the profile itself is Infinity, so the search still sees which way the cutter lies when the
// line misses it.
const MAX_LIFT_NODES = 40000;
const OUTSIDE_SLOPE = 1e3;
const GOLDEN = (Math.sqrt(5) - 1) / 2;
// Golden-section and bisection steps: 0.62^50 and 0.5^50 of a 100 mm reach are under 1e-8 mm.
const SEARCH_STEPS = 50;

export function tiltedLift({ profile, radius_mm: R, length_mm: L, axis, step_mm }) {
  const [ax, ay, az] = axis;
  const edge = profile(R);
  const G = (rho) => (rho <= R ? profile(rho) : edge + OUTSIDE_SLOPE * (rho - R));
  const reach = Math.hypot(L, R) + 1;

  // Height of the cutter's lowest point above the tip at (dx, dy) from it; Infinity: none there.
  function bottom(dx, dy) {
    const s0 = dx * ax + dy * ay;
    const q2 = dx * dx + dy * dy;
    const f = (t) => {
      const s = s0 + t * az;
      const rho = Math.sqrt(Math.max(0, q2 + t * t - s * s));
      return Math.max(G(rho) - s, s - L, OUTSIDE_SLOPE * (rho - R));
    };
    let lo = -reach, hi = reach;
    let t1 = hi - GOLDEN * (hi - lo), t2 = lo + GOLDEN * (hi - lo);
    let f1 = f(t1), f2 = f(t2);
    for (let k = 0; k < SEARCH_STEPS; k++) {
      if (f1 <= f2) {
        hi = t2; t2 = t1; f2 = f1;
        t1 = hi - GOLDEN * (hi - lo); f1 = f(t1);
      } else {
        lo = t1; t1 = t2; f1 = f2;
        t2 = lo + GOLDEN * (hi - lo); f2 = f(t2);
      }
    }
    let inside = f1 <= f2 ? t1 : t2;
    if (f(inside) > 0) return Infinity;
    let outside = -reach;
    for (let k = 0; k < SEARCH_STEPS; k++) {
      const mid = (outside + inside) / 2;
      if (f(mid) <= 0) inside = mid;
      else outside = mid;
    }
    return inside;
  }

  // What the cutter covers seen from above: the tip's disc and the top's, each grown by R.
  const x0 = Math.min(0, L * ax) - R, x1 = Math.max(0, L * ax) + R;
  const y0 = Math.min(0, L * ay) - R, y1 = Math.max(0, L * ay) + R;
  const step = Math.max(step_mm, Math.sqrt(((x1 - x0) * (y1 - y0)) / MAX_LIFT_NODES));
  const nx = Math.ceil((x1 - x0) / step) + 1;
  const ny = Math.ceil((y1 - y0) / step) + 1;
  const table = new Float64Array(nx * ny);
  for (let j = 0; j < ny; j++) {
    for (let i = 0; i < nx; i++) table[j * nx + i] = bottom(x0 + i * step, y0 + j * step);
  }

  // Between nodes: bilinear where all four hold cutter, the nearest node at the cutter's edge.
  function at(dx, dy) {
    const u = (dx - x0) / step, v = (dy - y0) / step;
    if (!(u >= 0 && v >= 0 && u <= nx - 1 && v <= ny - 1)) return Infinity;
    const i = Math.min(nx - 2, Math.floor(u)), j = Math.min(ny - 2, Math.floor(v));
    const fu = u - i, fv = v - j;
    const a = table[j * nx + i], b = table[j * nx + i + 1];
    const c = table[(j + 1) * nx + i], d = table[(j + 1) * nx + i + 1];
    if (a === Infinity || b === Infinity || c === Infinity || d === Infinity) {
      return table[(j + (fv < 0.5 ? 0 : 1)) * nx + i + (fu < 0.5 ? 0 : 1)];
    }
    return (a * (1 - fu) + b * fu) * (1 - fv) + (c * (1 - fu) + d * fu) * fv;
  }

  return { x0_mm: x0, x1_mm: x1, y0_mm: y0, y1_mm: y1, step_mm: step, bottom, at };
}
