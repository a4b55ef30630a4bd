// How the tool stands in the 3-D view. A run whose tool was tilted at one fixed orientation while
// it cut (3+2 machining, docs/five_axis.md §2.5) reports that orientation as summary.kinematics;
// every other run cut with the tool along the stock's +Z. No three.js and no DOM here, so node's
// test runner loads this module as it is.
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

// The legend's words for a tilted run (null otherwise), in the stock axes the view labels.
export function toolAxisText(kinematics) {
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
