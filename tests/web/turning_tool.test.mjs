// A tool that turns while it cuts (simultaneous five-axis, docs/five_axis.md §3.4) in the run
// page's 3-D view, through the service: a dry run of the AC table-table machine whose A axis swings
// the part under a flat end mill as the tip runs 1 mm deep along the part's X (the tip stays on the
// A line, so only the axis turns, by 20°), uploaded with the machine. The tool drawn at two times
// picked on the path stands on the axis that `cutload predict --machine` writes for those times in
// FORCES.csv (tool_axis_x, _y, _z), and strokes along the path show the axis.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import {
  env, skipWithoutChromium, startServer, launchBrowser, openPage, screenshot, dataFile, tempFile,
} from './harness.mjs';

skipWithoutChromium();

let server;
let browser;

// Readings every 4 ms for 3 s: the tip (tool length 0) at machine X -390 to -310 on the A line
// (Y -275, Z -560), A from -5 to -25°, C 0, spindle 6000 rpm (a tooth every 5 ms).
function turningLog() {
  const lines = ['t,x,y,z,a,c,spindle,block'];
  const n = 750;
  for (let k = 0; k <= n; k++) {
    const u = k / n;
    lines.push([(0.004 * k).toFixed(3), (-390 + 80 * u).toFixed(3), '-275.000', '-560.000', (-5 - 20 * u).toFixed(3), '0.000', 6000,
      u < 0.5 ? 'N10' : 'N20'].join(','));
  }
  return `${lines.join('\n')}\n`;
}

// The part's X along the A line through the box, its top 1 mm above the tip; coarse steps keep
// the multi-direction stock quick.
const SPEC = {
  tool: { shape: 'flat', diameter_mm: 8, flutes: 2, helix_deg: 30, corner_radius_mm: 0, flute_length_mm: 20, stickout_mm: 30,
    holder: { diameter_mm: 20, length_mm: 40 } },
  material: { name: 'test', Ktc_N_mm2: 700, Krc_N_mm2: 210, Kac_N_mm2: 120, Kte_N_mm: 20, Kre_N_mm: 28, Kae_N_mm: 2 },
  stock: { box_mm: { min: [-30, -20, -20], max: [30, 20, 1] } },
  setup: { offset_mm: [350, 275, 560] },
  resolution: { angle_step_deg: 6, axial_step_mm: 0.25, grid_mm: 0.5 },
};

let run;        // the done run
let rows;       // FORCES.csv of the same log: {t, axis: [[x, y, z]]}

async function waitDone(id) {
  for (;;) {
    const r = await server.api('GET', `runs/${id}`);
    if (r.state !== 'queued' && r.state !== 'running') return r;
    await new Promise((res) => setTimeout(res, 200));
  }
}

before(async () => {
  if (!dataFile('machines/ac_table_table.json')) return;
  server = await startServer({ workers: 1 });
  browser = await launchBrowser();
  const machine = dataFile('machines/ac_table_table.json');
  const log = tempFile(server, 'turning.csv', turningLog());
  const spec = tempFile(server, 'turning.json', JSON.stringify(SPEC));
  const fd = new FormData();
  fd.append('log', new Blob([fs.readFileSync(log)]), 'turning.csv');
  fd.append('spec', JSON.stringify(SPEC));
  fd.append('kinematics', new Blob([fs.readFileSync(machine)]), 'ac_table_table.json');
  fd.append('tool_length_mm', '0');
  fd.append('name', 'turning tool');
  const { id } = await server.api('POST', 'runs', fd);
  run = await waitDone(id);
  // The reference: the CLI's rows of the same log, each with the axis by forward kinematics at its time.
  const out = path.join(server.dir, 'forces.csv');
  execFileSync(env('CUTLOAD_BIN'), ['predict', log, '--spec', spec, '--machine', machine, '--tool-length-mm', '0',
    '--device', 'cpu', '-q', '--out', out]);
  const [head, ...body] = fs.readFileSync(out, 'utf8').trim().split('\n');
  const cols = head.split(',');
  const [ct, cx, cy, cz] = ['t_s', 'tool_axis_x', 'tool_axis_y', 'tool_axis_z'].map((c) => cols.indexOf(c));
  assert.ok(cx > 0 && cy > 0 && cz > 0, `FORCES.csv has the tool axis: ${head}`);
  const cells = body.map((l) => l.split(','));
  rows = { t: cells.map((c) => Number(c[ct])), axis: cells.map((c) => [cx, cy, cz].map((k) => Number(c[k]))) };
});

after(async () => {
  await browser?.close();
  await server?.stop();
});

// The FORCES row nearest in time to t.
function rowAxis(t) {
  let best = 0;
  for (let i = 1; i < rows.t.length; i++) if (Math.abs(rows.t[i] - t) < Math.abs(rows.t[best] - t)) best = i;
  return { t: rows.t[best], axis: rows.axis[best] };
}

test('a turning tool stands on its axis at the picked time, its axis stroked along the path', { skip: !dataFile('machines/ac_table_table.json') }, async () => {
  assert.equal(run.state, 'done', run.error);
  assert.equal(run.summary.kinematics.turning, true, 'the tool turns while it cuts');
  assert.ok(run.summary.removed_mm3 > 10, `it cuts: ${run.summary.removed_mm3} mm³`);
  const { page, errors } = await openPage(browser, server);
  await page.goto(`${server.url}/#/runs/${run.id}`);
  await page.locator('#view3d').scrollIntoViewIfNeeded({ timeout: 60000 });
  await page.locator('#view3d[data-ready="true"]').waitFor({ timeout: 60000 });
  assert.match(await page.locator('#tool-axis').innerText(), /Tool turning while it cuts .*drawn on its axis at the cursor/);
  assert.match(await page.locator('#path-legend').innerText(), /tool axis along the path/);
  assert.ok(Number(await page.locator('#view3d').getAttribute('data-axis-ticks')) > 10, 'strokes along the path');

  // Two times picked by clicking the path where a quarter and three quarters of it lie.
  const canvas = page.locator('#view3d canvas');
  await canvas.scrollIntoViewIfNeeded();
  const box = await canvas.boundingBox();
  const picked = [];
  for (const share of [0.25, 0.75]) {
    const at = await page.evaluate(async (f) => {
      const THREE = await import('three');
      const view = document.getElementById('view3d').view3d;
      const i = Math.round(f * (view.path.t.length - 1));
      const [sx, sy] = view.project(new THREE.Vector3(view.path.x[i], view.path.y[i], view.path.z[i]));
      return { sx, sy };
    }, share);
    await page.mouse.click(box.x + at.sx, box.y + at.sy);
    await page.waitForFunction((t0) => document.getElementById('view3d').dataset.time !== t0, picked.at(-1)?.time ?? '');
    picked.push(await page.evaluate(() => {
      const view = document.getElementById('view3d').view3d;
      view.toolGroup.updateMatrixWorld(true);
      const e = view.toolGroup.matrixWorld.elements;
      const i = view.toolIndex;
      return {
        time: view.container.dataset.time, t: view.path.t[i], axis: [e[8], e[9], e[10]], tip: [e[12], e[13], e[14]],
        point: [view.path.x[i], view.path.y[i], view.path.z[i]],
      };
    }));
  }
  await screenshot(page, 'turning-tool-3d');
  for (const p of picked) {
    const ref = rowAxis(p.t);
    console.log(`picked ${p.t.toFixed(4)} s: the tool on (${p.axis.map((v) => v.toFixed(5))}), FORCES.csv at ${ref.t} s (${ref.axis})`);
    assert.ok(Math.abs(ref.t - p.t) < 0.002, `a FORCES row near ${p.t} s`);
    for (let k = 0; k < 3; k++) assert.ok(Math.abs(p.axis[k] - ref.axis[k]) < 1e-3, `axis at ${p.t} s: [${p.axis}] against FORCES.csv [${ref.axis}]`);
    for (let k = 0; k < 3; k++) assert.ok(Math.abs(p.tip[k] - p.point[k]) < 1e-4, 'the tip at the path point');
  }
  const turned = Math.acos(Math.min(1, picked[0].axis.reduce((s, v, k) => s + v * picked[1].axis[k], 0))) * 180 / Math.PI;
  assert.ok(turned > 5, `the tool turned between the picked times: ${turned.toFixed(2)}°`);
  assert.deepEqual(errors, []);
  await page.context().close();
});
