// Issue 5's last item: attach a dynamometer record on the run page, see the measured forces
// overlaid on the plot and the comparison metrics; a bad file shows its error by the file field.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { skipWithoutChromium, startServer, launchBrowser, openPage, screenshot, tempFile, straightCutLog } from './harness.mjs';

skipWithoutChromium();

let server;
let browser;
let page;
let errors;
let runId;

const SPEC = {
  tool: { shape: 'flat', diameter_mm: 8, flutes: 2, helix_deg: 30, corner_radius_mm: 0, flute_length_mm: 20, stickout_mm: 30 },
  material: { Ktc_N_mm2: 767, Krc_N_mm2: 168.8, Kac_N_mm2: 222, Kte_N_mm: 27.7, Kre_N_mm: 26.6, Kae_N_mm: 0.7 },
  stock: { box_mm: { min: [0, -5, -10], max: [20, 20, 0] } },
  // A coarse angle step keeps the whole run under the API's 20000-point window at full resolution.
  resolution: { angle_step_deg: 6, axial_step_mm: 0.5, grid_mm: 0.5 },
};

before(async () => {
  server = await startServer();
  const fd = new FormData();
  fd.append('log', new Blob([straightCutLog({ passes: 1, length_mm: 30 })]), 'cut.csv');
  fd.append('spec', JSON.stringify(SPEC));
  runId = (await server.api('POST', 'runs', fd)).id;
  for (;;) {
    const run = await server.api('GET', `runs/${runId}`);
    if (run.state === 'done') break;
    assert.ok(run.state === 'queued' || run.state === 'running', `run is ${run.state}: ${run.error}`);
    await new Promise((r) => setTimeout(r, 100));
  }
  browser = await launchBrowser();
  ({ page, errors } = await openPage(browser, server));
  await page.goto(`${server.url}/#/runs/${runId}`);
  await page.getByRole('button', { name: 'Attach measurement' }).waitFor();
});

after(async () => {
  await browser?.close();
  await server?.stop();
});

// The run's own predicted forces as a DynoWare export from a dynamometer under the workpiece
// (identity axes; the measured force is minus the tool's), resampled linearly onto the constant
// grid a dynamometer records at: the prediction's own steps, since it skips time in the air.
async function dynoFile() {
  const raw = await server.api('GET', `runs/${runId}/forces?max_points=20000`);
  assert.equal(raw.decimated, false);
  const t = raw.t_s;
  const steps = t.slice(1).map((v, i) => v - t[i]).sort((a, b) => a - b);
  const dt = steps[Math.floor(steps.length / 2)];
  const lines = ['DynoWare,Version 3.2.2.0', `Sampling rate [Hz]:,${(1 / dt).toFixed(6)}`, 'Time,Fx,Fy,Fz', 's,N,N,N'];
  for (let k = 0, j = 0; t[0] + k * dt <= t.at(-1); k++) {
    const tk = t[0] + k * dt;
    while (j + 2 < t.length && t[j + 1] <= tk) j++;
    const w = Math.min(1, Math.max(0, (tk - t[j]) / (t[j + 1] - t[j])));
    const at = (v) => -(v[j] + w * (v[j + 1] - v[j]));
    lines.push([tk.toFixed(9), at(raw.fx_N), at(raw.fy_N), at(raw.fz_N)].join(','));
  }
  return `${lines.join('\n')}\n`;
}

test('a bad file shows its error next to the file field and attaches nothing', async () => {
  await page.setInputFiles('#measurement-file', tempFile(server, 'broken.csv', 'Time,Fx,Fy\n0,1,2\n'));
  await page.getByRole('button', { name: 'Attach measurement' }).click();
  await page.waitForFunction(() => document.getElementById('measurement-file-err').textContent.length > 0);
  const message = await page.locator('#measurement-file-err').textContent();
  console.log(`measurement field error: ${message}`);
  assert.match(message, /broken\.csv/);
  assert.equal(await page.locator('#measurement-file').getAttribute('aria-invalid'), 'true');
  assert.equal(await page.locator('#measurement-metrics').count(), 0);
  await screenshot(page, 'measurement-1-bad-file');
});

test('attaching a measurement overlays it on the plot and shows the metrics', async () => {
  await page.setInputFiles('#measurement-file', tempFile(server, 'dyno.csv', await dynoFile()));
  await page.getByRole('button', { name: 'Attach measurement' }).click();
  await page.locator('#measurement-metrics').waitFor();
  assert.equal(await page.locator('#measurement-file-err').textContent(), '');
  const points = Number(await page.locator('#force-plot').getAttribute('data-measured-points'));
  assert.ok(points > 100, `overlay points: ${points}`);
  const caption = await page.locator('#measurement-metrics caption').textContent();
  console.log(`caption: ${caption}`);
  assert.match(caption, /dyno\.csv/);
  // The record is the prediction itself: the overall Fx row has a near-zero NRMSE and correlation near 1.
  // Columns after the axis: mean error, RMSE, NRMSE, peak error, correlation.
  const fxRow = page.locator('#measurement-metrics tbody tr').first();
  assert.equal(await fxRow.locator('th').textContent(), 'Fx');
  const overallFx = await fxRow.locator('td').allTextContents();
  console.log(`overall Fx row: ${overallFx.join(' | ')}`);
  assert.ok(Math.abs(Number(overallFx[2])) < 0.01, `nrmse ${overallFx[2]}`);
  assert.ok(Number(overallFx[4]) > 0.99, `correlation ${overallFx[4]}`);
  // Per block, folded away below the overall table.
  assert.equal(await page.locator('.per-block-metrics').getAttribute('open'), null);
  await screenshot(page, 'measurement-2-overlay');

  // The overview is an envelope of the whole record; zoomed in, the record is drawn at full resolution.
  const plot = page.locator('#force-plot');
  assert.equal(await plot.getAttribute('data-measured-resolution'), 'envelope');
  await plot.focus();
  for (let i = 0; i < 5; i++) await page.keyboard.press('+');
  // Generous: the suite runs this beside the fuzz targets' clang build on 2 cores. (Its failures
  // there were a late window fetch setting the plot back to an earlier zoom, fixed in
  // force_plot.js, not slowness; bench/bench_web_run_page.mjs measures the speed.)
  await page.waitForFunction(() => document.getElementById('force-plot').dataset.measuredResolution === 'full', null, { timeout: 60000 });
  assert.ok(Number(await plot.getAttribute('data-measured-window-points')) > 10, 'measured samples in the window');
  await screenshot(page, 'measurement-3-zoomed-full-resolution');
  await page.keyboard.press('0');
  await page.waitForFunction(() => document.getElementById('force-plot').dataset.measuredResolution === 'envelope', null, { timeout: 60000 });
  // A reload finds the attached record again.
  await page.reload();
  await page.locator('#measurement-metrics').waitFor();
  assert.ok(Number(await page.locator('#force-plot').getAttribute('data-measured-points')) > 100);
  assert.deepEqual(errors, []);
});
