// A long run stores envelopes only (here forced with --max-raw-rows): zoomed into a window of at
// most 10 s, the run page offers "Full resolution", which has the service predict that window
// again (/forces?resolution=full) and draws every row in place of the envelopes.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import { skipWithoutChromium, finishedRun, startServer, launchBrowser, openPage, screenshot, straightCutLog } from './harness.mjs';

skipWithoutChromium();

let server;
let browser;

before(async () => {
  server = await startServer({ workers: 1, args: ['--max-raw-rows', '2000'] });
  browser = await launchBrowser();
});

after(async () => {
  await browser?.close();
  await server?.stop();
});

test('zoomed into an envelope-only run, Full resolution draws the recomputed rows', async () => {
  const fd = new FormData();
  fd.append('log', new Blob([straightCutLog({ passes: 1, length_mm: 70, rpm: 10000 })]), 'cut.csv');
  fd.append('spec', JSON.stringify({
    tool: { shape: 'flat', diameter_mm: 8, flutes: 2, helix_deg: 30, corner_radius_mm: 0, flute_length_mm: 20, stickout_mm: 30 },
    material: { Ktc_N_mm2: 767, Krc_N_mm2: 168.8, Kac_N_mm2: 222, Kte_N_mm: 27.7, Kre_N_mm: 26.6, Kae_N_mm: 0.7 },
    stock: { box_mm: { min: [0, 2, -10], max: [60, 20, 0] } },
    resolution: { angle_step_deg: 2, axial_step_mm: 0.2, grid_mm: 0.2 },
  }));
  fd.append('name', 'envelopes only');
  const { id } = await server.api('POST', 'runs', fd);
  const run = await finishedRun(server, id);
  assert.equal(run.state, 'done', run.error);

  const { page, errors } = await openPage(browser, server);
  await page.goto(`${server.url}/#/runs/${id}`);
  const plot = page.locator('#force-plot');
  await page.locator('#force-plot .u-over').waitFor();
  await page.waitForFunction(() => document.getElementById('force-plot').dataset.windowTo);
  const full = page.locator('#plot-full');
  assert.equal(await full.isDisabled(), true, 'the whole run is not recomputed');

  // Zoom in (the + key halves the window) until the stored answer for the window is envelopes.
  await plot.focus();
  for (let i = 0; i < 4; i++) await page.keyboard.press('+');
  await page.waitForFunction(() => document.getElementById('force-plot').dataset.recomputable === 'true', null, { timeout: 15000 });
  const before = await page.evaluate(() => ({ ...document.getElementById('force-plot').dataset }));
  assert.equal(before.resolution, 'envelope');
  await full.click();
  await page.waitForFunction(() => document.getElementById('force-plot').dataset.resolution === 'recomputed', null, { timeout: 60000 });
  const after = await page.evaluate(() => ({ ...document.getElementById('force-plot').dataset }));
  assert.equal(after.windowFrom, before.windowFrom);
  assert.equal(after.windowTo, before.windowTo);
  assert.equal(await full.isDisabled(), true, 'nothing more to recompute');

  // The service's answer for that window, recomputed: every row, more than the stored envelopes.
  const from = Number(after.windowFrom);
  const to = Number(after.windowTo);
  const stored = await server.api('GET', `runs/${id}/forces?from_s=${from}&to_s=${to}&max_points=4000`);
  const again = await server.api('GET', `runs/${id}/forces?from_s=${from}&to_s=${to}&max_points=4000&resolution=full`);
  assert.ok(stored.level > 0, `stored level ${stored.level}`);
  assert.equal(again.recomputed, true);
  assert.ok(again.count > stored.count, `recomputed ${again.count} rows, stored ${stored.count} envelopes`);
  // Export CSV exports what the plot shows: the recomputed rows, one line each, after the header.
  const [download] = await Promise.all([page.waitForEvent('download'), page.getByRole('button', { name: 'Export CSV' }).click()]);
  const csvLines = fs.readFileSync(await download.path(), 'utf8').trim().split('\n');
  const rows = await server.api('GET', `runs/${id}/forces?from_s=${from}&to_s=${to}&max_points=20000&resolution=full`);
  assert.equal(rows.decimated, false);
  assert.equal(csvLines.length - 1, rows.count);
  await screenshot(page, 'plot-full-resolution');
  assert.deepEqual(errors, []);
});
