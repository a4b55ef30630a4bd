// The 3-D view's tool on a fixed-tilt run (3+2 machining, docs/five_axis.md §2.5): the axis the
// view takes from summary.kinematics, the turn that stands the tool on it, the tilted cutter's
// lowest points for the in-process stock and the legend's words, in node; a turning tool's axis
// per path point from /motion and the strokes along the path; then, in Chromium, the view's tool
// group on that axis with its tip at the path point, and the sweep cutting along it, and a
// turning tool on each point's own axis. The browser part needs no server: the assembled site is
// served as static files (tests/web/turning_tool.test.mjs takes a turning run through the service).
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import http from 'node:http';
import path from 'node:path';
import { CHROMIUM, env, launchBrowser } from './harness.mjs';
import {
  toolAxis, axisQuaternion, toolAxisText, tiltedLift, motionAxes, pointAxis, axisTicks,
} from '../../web/js/tool_axis.js';

// v turned by the unit quaternion q = [x, y, z, w] (written out here, not taken from the module).
function turn([x, y, z, w], v) {
  const [vx, vy, vz] = v;
  const tx = 2 * (y * vz - z * vy), ty = 2 * (z * vx - x * vz), tz = 2 * (x * vy - y * vx);
  return [vx + w * tx + (y * tz - z * ty), vy + w * ty + (z * tx - x * tz), vz + w * tz + (x * ty - y * tx)];
}

function near(actual, expected, tol, what) {
  for (let k = 0; k < expected.length; k++) {
    assert.ok(Math.abs(actual[k] - expected[k]) <= tol, `${what}: [${actual}] against [${expected}]`);
  }
}

const S = Math.SQRT1_2;
const flat = (R) => (r) => (r > R ? Infinity : 0);
const ball = (R) => (r) => (r > R ? Infinity : R - Math.sqrt(Math.max(0, R * R - r * r)));

test('the axis: the fixed tilt\'s, else none (+Z)', () => {
  assert.equal(toolAxis(undefined), null);
  assert.equal(toolAxis({ tool_axis: [0, 0, 1], tool_lean_deg: 0, fixed_tilt: false }), null);
  assert.equal(toolAxis({ tool_axis: [0.5, 0, 0.866], tool_lean_deg: 30, fixed_tilt: false }), null, 'not fixed: not turned');
  assert.equal(toolAxis({ tool_axis: [0, 0, 0], fixed_tilt: true }), null);
  near(toolAxis({ tool_axis: [0, 3, 4], tool_lean_deg: 36.87, fixed_tilt: true }), [0, 0.6, 0.8], 1e-15, 'normalised');
});

test('the turn stands +Z on the axis, the tip staying put', () => {
  const axes = [[0, 0, 1], [1, 0, 0], [0, -1, 0], [S, 0, S], [0.5, 6e-17, Math.sqrt(3) / 2], [-0.36, 0.48, -0.8], [0, 0, -1], [1e-9, 0, -1]];
  for (const raw of axes) {
    const a = raw.map((v) => v / Math.hypot(...raw));
    const q = axisQuaternion(a);
    assert.ok(Math.abs(Math.hypot(...q) - 1) < 1e-12, `unit quaternion for [${a}]`);
    near(turn(q, [0, 0, 1]), a, 1e-6, `+Z turned onto [${a}]`);
    near(turn(q, [0, 0, 0]), [0, 0, 0], 0, 'the tip');
    // A rotation: the tool's radius stays its radius.
    assert.ok(Math.abs(Math.hypot(...turn(q, [3, 4, 0])) - 5) < 1e-12);
  }
  near(axisQuaternion([0, 0, 1]), [0, 0, 0, 1], 0, 'a vertical tool is not turned');
});

test('a tilted cutter\'s lowest points', () => {
  // Flat D10 lying along +X: under (dx, dy) the bottom of its cylinder, none before its end face
  // or past its 20 mm; the end face reaches down the full radius.
  const lying = tiltedLift({ profile: flat(5), radius_mm: 5, length_mm: 20, axis: [1, 0, 0], step_mm: 0.125 });
  assert.ok(Math.abs(lying.bottom(10, 3) + 4) < 1e-9, String(lying.bottom(10, 3)));
  assert.ok(Math.abs(lying.bottom(0, 0) + 5) < 1e-9);
  assert.ok(Math.abs(lying.bottom(20, 0) + 5) < 1e-9);
  for (const [dx, dy] of [[10, 5.2], [-0.3, 0], [20.3, 0]]) assert.equal(lying.bottom(dx, dy), Infinity, `(${dx}, ${dy})`);
  assert.ok(Math.abs(lying.at(10.06, 3.03) - lying.bottom(10.06, 3.03)) < 0.01, 'the table between its nodes');
  assert.ok(lying.x0_mm <= -5 && lying.x1_mm >= 25 && lying.y0_mm <= -5 && lying.y1_mm >= 5, 'the reach covers the cutter');
  // Upright, the lowest point is the profile itself (what the three-axis sweep uses).
  const upright = tiltedLift({ profile: ball(5), radius_mm: 5, length_mm: 20, axis: [0, 0, 1], step_mm: 0.125 });
  for (const [dx, dy] of [[0, 0], [1, 2], [-3, 3.9], [4.9, 0.1]]) {
    assert.ok(Math.abs(upright.bottom(dx, dy) - ball(5)(Math.hypot(dx, dy))) < 1e-9, `(${dx}, ${dy})`);
  }
  assert.equal(upright.bottom(4, 4), Infinity);
  // A D10 ball leaning 45° toward +X: its centre 5 mm up the axis, its sphere below that.
  const leaning = tiltedLift({ profile: ball(5), radius_mm: 5, length_mm: 20, axis: [S, 0, S], step_mm: 0.125 });
  const c = 5 * S;
  for (const [dx, dy] of [[c, 0], [c + 2, 1], [c - 3, -2]]) {
    const sphere = c - Math.sqrt(25 - (dx - c) ** 2 - dy ** 2);
    assert.ok(Math.abs(leaning.bottom(dx, dy) - sphere) < 1e-9, `(${dx}, ${dy}): ${leaning.bottom(dx, dy)} against ${sphere}`);
  }
});

test('the legend names a tilted tool\'s axis and lean', () => {
  assert.equal(toolAxisText({ tool_axis: [0, 0, 1], tool_lean_deg: 0, fixed_tilt: false }), null);
  assert.equal(toolAxisText(null), null);
  assert.equal(toolAxisText({ tool_axis: [0.5, 6e-17, 0.8660254037844387], tool_lean_deg: 30.000000001, fixed_tilt: true }),
    'Tool axis (0.5, 0, 0.866), lean 30° from +Z, fixed while it cuts (3+2)');
});

test('a turning tool\'s axis per sample from /motion: unit, midpoints of buckets, none without', () => {
  assert.equal(motionAxes({ t_s: [0, 1], x_mm: [0, 1] }), null, 'a run without the channels');
  assert.equal(motionAxes(null), null);
  const raw = motionAxes({ t_s: [0, 1, 2, 3], tool_axis_x: [0, 0.6, 0, null], tool_axis_y: [0, 0, 0, null], tool_axis_z: [1, 0.8, 0, null] });
  near(raw, [0, 0, 1, 0.6, 0, 0.8, 0.6, 0, 0.8, 0.6, 0, 0.8], 1e-7, 'raw: a zero or missing axis is the one before');
  // Float noise off unit length is taken out.
  near(motionAxes({ t_s: [0], tool_axis_x: [0.5000001], tool_axis_y: [0], tool_axis_z: [0.8660254] }), [0.5, 0, Math.sqrt(3) / 2], 1e-7, 'unit');
  const dec = motionAxes({
    decimated: true, t_s: [0, 1], t_end_s: [0.9, 1.9],
    tool_axis_x: { min: [0, 0.5], max: [0.2, 0.7] }, tool_axis_y: { min: [0, -0.1], max: [0, 0.1] }, tool_axis_z: { min: [0.98, 0.71], max: [1, 0.87] },
  });
  const m0 = [0.1, 0, 0.99], m1 = [0.6, 0, 0.79];
  near(dec, [...m0.map((v) => v / Math.hypot(...m0)), ...m1.map((v) => v / Math.hypot(...m1))], 1e-7, 'decimated: the middle, unit');
  const path = { axis: Float32Array.from([0, 0, 1, 1, 0, 0]) };
  assert.deepEqual(pointAxis(path, 1), [1, 0, 0]);
  assert.equal(pointAxis(path, 2), null);
  assert.equal(pointAxis({}, 0), null, 'a path without an axis per point');
});

test('strokes up a turning tool\'s axis along the path, evenly spaced', () => {
  // 101 points 0.1 mm apart along X, the axis leaning from +Z toward +Y as it goes.
  const n = 101;
  const lean = (i) => (i / (n - 1)) * (Math.PI / 4);
  const path = {
    x: Float32Array.from({ length: n }, (_, i) => i * 0.1), y: new Float32Array(n), z: new Float32Array(n).fill(2),
    axis: Float32Array.from({ length: 3 * n }, (_, k) => [0, Math.sin(lean(Math.floor(k / 3))), Math.cos(lean(Math.floor(k / 3)))][k % 3]),
  };
  const { segments, points } = axisTicks(path, { spacing_mm: 1, length_mm: 3 });
  assert.deepEqual(points, [0, 10, 20, 30, 40, 50, 60, 70, 80, 90, 100]);
  for (const [k, i] of points.entries()) {
    const s = segments.subarray(6 * k, 6 * k + 6);
    near(s, [i * 0.1, 0, 2, i * 0.1, 3 * Math.sin(lean(i)), 2 + 3 * Math.cos(lean(i))], 1e-5, `stroke ${k} up the axis of point ${i}`);
  }
  assert.equal(axisTicks(path, { spacing_mm: 0.01, length_mm: 3, max: 5 }).points.length, 5, 'at most max');
  assert.equal(axisTicks({ ...path, axis: undefined }, { spacing_mm: 1, length_mm: 3 }).points.length, 0, 'none without an axis');
});

test('the legend says a turning tool is drawn on its axis, or why not', () => {
  const turning = { tool_axis: [0.5, 0, 0.866], tool_lean_deg: 30, fixed_tilt: false, turning: true };
  assert.equal(toolAxisText(turning, { perSample: true }),
    'Tool turning while it cuts (simultaneous five-axis), leaning up to 30° from +Z: drawn on its axis at the cursor, its axis along the path as short strokes; the stock shown is the final stock');
  assert.match(toolAxisText(turning), /stored without its axis per sample, so the tool is drawn along \+Z$/);
});

// ---- in the browser --------------------------------------------------------------------------

const TYPES = { '.html': 'text/html', '.js': 'text/javascript', '.css': 'text/css' };
let site;
let browser;
const browserSkip = !fs.existsSync(CHROMIUM) && `${CHROMIUM} is not installed`;

before(async () => {
  if (browserSkip) return;
  const root = env('CUTLOAD_WEB_SITE');
  // The site's import map, on a page that loads nothing else (no API behind it).
  const index = fs.readFileSync(path.join(root, 'index.html'), 'utf8');
  const importMap = /<script type="importmap">[^<]*<\/script>/.exec(index)[0];
  const blank = `<!doctype html><html><head><meta charset="utf-8">${importMap}</head><body></body></html>`;
  site = http.createServer((req, res) => {
    const url = new URL(req.url, 'http://x').pathname;
    if (url === '/blank.html') return res.writeHead(200, { 'Content-Type': 'text/html' }).end(blank);
    const file = path.join(root, path.normalize(url));
    if (!file.startsWith(root) || !fs.existsSync(file) || !fs.statSync(file).isFile()) return res.writeHead(404).end();
    res.writeHead(200, { 'Content-Type': TYPES[path.extname(file)] || 'application/octet-stream' }).end(fs.readFileSync(file));
  });
  await new Promise((r) => site.listen(0, '127.0.0.1', r));
  browser = await launchBrowser();
});

after(async () => {
  await browser?.close();
  site?.close();
});

// A 40 x 20 x 10 mm box in 0.5 mm cells whose final top is 1 mm (so nothing the sweep cuts is
// lifted back to the final stock), a flat D6 (12 mm flutes, holder) whose tip runs along +X from
// (5, 10, 8) to (15, 10, 8); the view with the cursor half way (tip at (10, 10, 8)).
async function viewOf(page, kinematics, { leanFrom_deg = null, leanTo_deg = null, times = [1.0] } = {}) {
  return page.evaluate(async ({ kin, leanFrom_deg, leanTo_deg, times }) => {
    const { View3D } = await import('/js/view3d.js');
    const THREE = await import('three');
    const box = document.createElement('div');
    box.style.width = '640px';
    document.body.replaceChildren(box);
    const nx = 80, ny = 40;
    const field = { nx, ny, cell_mm: 0.5, x0_mm: 0, y0_mm: 0, top_mm: new Array(nx * ny).fill(1), box_mm: { min: [0, 0, 0], max: [40, 20, 10] } };
    const n = 21;
    const path = { t: Float64Array.from({ length: n }, (_, i) => i * 0.1) };
    path.x = Float32Array.from({ length: n }, (_, i) => 5 + (10 * i) / (n - 1));
    path.y = new Float32Array(n).fill(10);
    path.z = new Float32Array(n).fill(8);
    // A turning tool: its axis leaning toward +Y from leanFrom_deg to leanTo_deg along the path.
    if (leanFrom_deg != null) {
      path.axis = new Float32Array(3 * n);
      for (let i = 0; i < n; i++) {
        const a = ((leanFrom_deg + ((leanTo_deg - leanFrom_deg) * i) / (n - 1)) * Math.PI) / 180;
        path.axis.set([0, Math.sin(a), Math.cos(a)], 3 * i);
      }
    }
    const tool = { shape: 'flat', diameter_mm: 6, flutes: 3, flute_length_mm: 12, stickout_mm: 30, holder: { diameter_mm: 32, length_mm: 40 } };
    const view = new View3D(box, { field, path, ratio: new Float32Array(n).fill(0.5), tool, kinematics: kin });
    // The tool group's axis and tip at each of `times` but the last.
    const at = [];
    for (const t of times.slice(0, -1)) {
      view.setTime(t);
      view.toolGroup.updateMatrixWorld(true);
      const m = view.toolGroup.matrixWorld.elements;
      at.push({ t, index: view.toolIndex, tip: [m[12], m[13], m[14]], axis: [m[8], m[9], m[10]], pathAxis: path.axis ? Array.from(path.axis.subarray(3 * view.toolIndex, 3 * view.toolIndex + 3)) : null });
    }
    view.setTime(times.at(-1));
    const g = view.toolGroup;
    g.updateMatrixWorld(true);
    const e = g.matrixWorld.elements;
    // The cutter's top centre, from its own geometry into the world.
    const cutter = g.children[0];
    const pos = cutter.geometry.attributes.position;
    let top = 0;
    const onAxis = (i) => Math.hypot(pos.getX(i), pos.getY(i)) < 1e-9;
    for (let i = 1; i < pos.count; i++) if (onAxis(i) && pos.getZ(i) > pos.getZ(top)) top = i;
    const topWorld = cutter.localToWorld(new THREE.Vector3().fromBufferAttribute(pos, top));
    const holder = g.children[2];
    holder.geometry.computeBoundingBox();
    const holderCentre = holder.localToWorld(holder.geometry.boundingBox.getCenter(new THREE.Vector3()));
    const heights = view.heightsAt(n);
    const cell = (x, y) => heights[Math.floor(y / 0.5) * nx + Math.floor(x / 0.5)];
    const result = {
      tip: [e[12], e[13], e[14]], axis: [e[8], e[9], e[10]], top: topWorld.toArray(), topLocalZ: pos.getZ(top),
      holder: holderCentre.toArray(), under: { x10: cell(10.1, 10.1), x20: cell(20.1, 10.1), x30: cell(30.1, 10.1) },
      at, ticks: Number(box.dataset.axisTicks), midHeights: Array.from(view.heightsAt(10)).every((v, k) => v === heights[k] && v === 1),
    };
    view.destroy();
    return result;
  }, { kin: kinematics, leanFrom_deg, leanTo_deg, times });
}

test('the view stands the tool, its holder and its sweep on the run\'s axis', { skip: browserSkip }, async () => {
  const page = await browser.newPage();
  const errors = [];
  page.on('pageerror', (e) => errors.push(e.message));
  await page.goto(`http://127.0.0.1:${site.address().port}/blank.html`);

  // Three-axis (no kinematics) and a five-axis run that never leaned: upright, as ever.
  for (const kin of [null, { tool_axis: [0, 0, 1], tool_lean_deg: 0, fixed_tilt: false }]) {
    const v = await viewOf(page, kin);
    near(v.tip, [10, 10, 8], 1e-6, 'tip at the path point');
    near(v.axis, [0, 0, 1], 1e-6, 'upright');
    near(v.top, [10, 10, 8 + v.topLocalZ], 1e-5, 'cutter top');
    near(v.holder, [10, 10, 8 + 30 + 20], 1e-5, 'holder centre');
    assert.ok(Math.abs(v.under.x10 - 8) < 1e-6 && v.under.x20 === 10, `the flat end cuts under its tip only: ${JSON.stringify(v.under)}`);
  }

  // Tilted 30° toward +X: everything on the axis, from the tip.
  const a = [0.5, 0, Math.sqrt(3) / 2];
  const tilted = await viewOf(page, { tool_axis: a, tool_lean_deg: 30, fixed_tilt: true });
  near(tilted.tip, [10, 10, 8], 1e-6, 'tip at the path point');
  near(tilted.axis, a, 1e-6, 'the tool on the run\'s axis');
  near(tilted.top, a.map((c, k) => [10, 10, 8][k] + tilted.topLocalZ * c), 1e-5, 'cutter top up the axis');
  near(tilted.holder, a.map((c, k) => [10, 10, 8][k] + 50 * c), 1e-5, 'holder centre up the axis');

  // Lying along +X 2 mm under the top: the flank cuts 3 mm below the tip's height along its 12 mm.
  const lying = await viewOf(page, { tool_axis: [1, 0, 0], tool_lean_deg: 90, fixed_tilt: true });
  near(lying.axis, [1, 0, 0], 1e-6, 'lying along +X');
  // (The cells' centres are 0.25 mm off the tip's line.)
  const flank = 8 - Math.sqrt(9 - 0.25 ** 2);
  assert.ok(Math.abs(lying.under.x10 - flank) < 0.01 && Math.abs(lying.under.x20 - flank) < 0.01, `the flank cut: ${JSON.stringify(lying.under)}`);
  assert.equal(lying.under.x30, 10, 'nothing past the flutes');
  assert.equal(lying.ticks, 0, 'no strokes along the path without an axis per point');
  assert.deepEqual(errors, []);
  await page.close();
});

test('the view stands a turning tool on each point\'s own axis and strokes its axis along the path', { skip: browserSkip }, async () => {
  const page = await browser.newPage();
  const errors = [];
  page.on('pageerror', (e) => errors.push(e.message));
  await page.goto(`http://127.0.0.1:${site.address().port}/blank.html`);
  // The lean turns from 0 to 40° toward +Y along the path (2° a point); the points at 0.5 s and
  // 1.5 s lean 10° and 30°.
  const kin = { tool_axis: [0, 0, 1], tool_lean_deg: 40, fixed_tilt: false, turning: true };
  const v = await viewOf(page, kin, { leanFrom_deg: 0, leanTo_deg: 40, times: [0.5, 1.5, 1.0] });
  const axisOf = (deg) => [0, Math.sin((deg * Math.PI) / 180), Math.cos((deg * Math.PI) / 180)];
  for (const [k, deg] of [[0, 10], [1, 30]]) {
    const a = v.at[k];
    near(a.pathAxis, axisOf(deg), 1e-6, `the path's axis at ${a.t} s`);
    near(a.axis, a.pathAxis, 1e-6, `the tool on the axis of its point at ${a.t} s`);
    near(a.tip, [5 + (10 * a.index) / 20, 10, 8], 1e-5, `the tip at its point at ${a.t} s`);
  }
  assert.ok(Math.hypot(...v.at[0].axis.map((c, k) => c - v.at[1].axis[k])) > 0.3, 'the tool turned between the two times');
  near(v.axis, axisOf(20), 1e-6, 'and at the last time, 20°');
  near(v.top, axisOf(20).map((c, k) => [10, 10, 8][k] + v.topLocalZ * c), 1e-5, 'the cutter up its axis');
  assert.ok(v.ticks >= 10, `strokes along the path: ${v.ticks}`);
  assert.ok(v.midHeights, 'the stock is the final stock at every time (no sweep for a turning tool)');
  assert.deepEqual(errors, []);
  await page.close();
});
