// Upload the demo dry run through the page, watch the progress bar advance, read the plot and the
// flagged blocks, zoom to a block from the table, acknowledge the alert the run raised.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import {
  env, skipWithoutChromium, startServer, launchBrowser, openPage, screenshot, dataFile, tempFile, straightCutLog,
} from './harness.mjs';

skipWithoutChromium();

let server;
let browser;

before(async () => {
  server = await startServer({ workers: 1 });
  browser = await launchBrowser();
});

after(async () => {
  await browser?.close();
  await server?.stop();
});

// The demo log and spec; a generated straight cut until they exist.
function demoInputs() {
  const log = dataFile('demo_dryrun.csv');
  const spec = dataFile('demo_run.json');
  if (log && spec) return { log, spec };
  return {
    log: tempFile(server, 'cut.csv', straightCutLog({ passes: 3, length_mm: 40 })),
    spec: tempFile(server, 'cut.json', JSON.stringify({
      tool: { shape: 'flat', diameter_mm: 8, flutes: 2, helix_deg: 30, corner_radius_mm: 0, flute_length_mm: 20, stickout_mm: 30 },
      material: { name: 'Al 7075-T6', Ktc_N_mm2: 767, Krc_N_mm2: 168.8, Kac_N_mm2: 222, Kte_N_mm: 27.7, Kre_N_mm: 26.6, Kae_N_mm: 0.7 },
      stock: { box_mm: { min: [0, -5, -10], max: [20, 10, 0] } },
      limits: { force_N: 100 },
    })),
  };
}

test('upload, progress, plot, block zoom and alert acknowledgement', async () => {
  // Every flag raises an alert, so the run has one to acknowledge.
  await server.api('POST', 'thresholds', { name: 'any flag', metric: 'flag', flag: 'any', severity: 'warning' });
  const { page, errors } = await openPage(browser, server);

  await page.getByRole('navigation', { name: 'Main' }).getByRole('link', { name: 'New run' }).click();
  const inputs = demoInputs();
  await page.setInputFiles('#log-file', inputs.log);
  await page.getByLabel('Run spec file (RUN.json)').setInputFiles(inputs.spec);
  await page.getByLabel('Run name').fill('demo from the browser test');
  await page.getByLabel('Program', { exact: true }).fill('O1001');
  assert.equal(await page.locator('input[name="tool-diameter_mm"]').inputValue(), String(JSON.parse(fs.readFileSync(inputs.spec, 'utf8')).tool.diameter_mm));
  await screenshot(page, 'upload-1-new-run-form');
  await page.getByRole('button', { name: 'Upload and compute' }).click();

  await page.waitForURL(/#\/runs\/\d+$/);
  const runId = Number(/#\/runs\/(\d+)$/.exec(page.url())[1]);

  // Sample the progress bar until the results replace it.
  const seen = [];
  let shot = false;
  const deadline = Date.now() + 60000;
  while (Date.now() < deadline) {
    const s = await page.evaluate(() => {
      const bar = document.getElementById('run-progress');
      return { visible: Boolean(bar && bar.offsetParent), value: bar?.hasAttribute('value') ? bar.value : null,
        done: Boolean(document.querySelector('#block-table tbody tr')) };
    });
    if (s.done) break;
    if (s.visible && s.value !== null) {
      seen.push(s.value);
      if (!shot && s.value > 0) {
        shot = true;
        await screenshot(page, 'upload-2-progress');
      }
    }
    await page.waitForTimeout(40);
  }
  console.log(`progress values seen (%): ${seen.join(', ')}`);
  assert.ok(seen.some((v) => v > 0 && v < 100), `the progress bar showed no value between 0 and 100: ${seen}`);
  for (let i = 1; i < seen.length; i++) assert.ok(seen[i] >= seen[i - 1], `progress went back: ${seen}`);

  const run = await server.api('GET', `runs/${runId}`);
  assert.equal(run.state, 'done');
  assert.ok(run.summary.flagged_blocks > 0, 'the demo run should have flagged blocks');

  // The plot: a uPlot canvas, shaded flagged blocks, showing the whole run.
  await page.locator('#force-plot canvas').first().waitFor();
  const full = await page.locator('#force-plot').evaluate((el) => [Number(el.dataset.xMin), Number(el.dataset.xMax)]);
  assert.ok(full[1] > full[0], `plot range ${full}`);
  const flaggedRows = page.locator('#block-table tbody tr.flagged');
  assert.equal(await flaggedRows.count(), run.summary.flagged_blocks);
  await page.locator('#flagged-count').filter({ hasText: `${run.summary.flagged_blocks} of ${run.summary.blocks}` }).waitFor();
  await screenshot(page, 'upload-3-run-done');

  // Clicking a flagged block zooms the plot to exactly that block.
  const blocks = (await server.api('GET', `runs/${runId}/blocks?flagged=true`)).items;
  const row = flaggedRows.nth(1 % blocks.length);
  const idx = Number(await row.getAttribute('data-idx'));
  const block = blocks.find((b) => b.idx === idx);
  await row.click();
  await assert.doesNotReject(page.waitForFunction(([a, b]) => {
    const el = document.getElementById('force-plot');
    return Math.abs(el.dataset.xMin - a) < 1e-6 && Math.abs(el.dataset.xMax - b) < 1e-6;
  }, [block.t_start_s, block.t_end_s], { timeout: 15000 }));
  assert.equal(await row.getAttribute('aria-selected'), 'true');
  await page.locator('#selection').filter({ hasText: `block ${block.block}` }).waitFor();
  // Finer data fetched for exactly this window replaces the overview there.
  await page.waitForFunction(() => {
    const d = document.getElementById('force-plot').dataset;
    return d.windowFrom === d.xMin && d.windowTo === d.xMax;
  }, null, { timeout: 15000 });
  await screenshot(page, 'upload-4-block-zoomed');

  // Exports of the zoomed window: CSV from the server, PNG of the plot canvas.
  const [csv] = await Promise.all([page.waitForEvent('download'), page.getByRole('button', { name: 'Export CSV' }).click()]);
  const csvText = fs.readFileSync(await csv.path(), 'utf8');
  assert.match(csvText.split('\n')[0], /^t_s,/);
  assert.ok(csvText.split('\n').length > 10, 'the CSV has rows');
  const [png] = await Promise.all([page.waitForEvent('download'), page.getByRole('button', { name: 'Export PNG' }).click()]);
  const pngPath = path.join(env('CUTLOAD_WEB_ARTIFACTS'), 'upload-export-plot.png');
  await png.saveAs(pngPath);
  assert.deepEqual([...fs.readFileSync(pngPath).subarray(0, 4)], [0x89, 0x50, 0x4e, 0x47], 'a PNG file');

  // The keyboard does the same as the mouse: Enter on a focused row zooms to its block.
  const first = flaggedRows.first();
  const firstIdx = Number(await first.getAttribute('data-idx'));
  const firstBlock = blocks.find((b) => b.idx === firstIdx);
  await first.focus();
  await page.keyboard.press('Enter');
  await page.waitForFunction(([a, b]) => {
    const el = document.getElementById('force-plot');
    return Math.abs(el.dataset.xMin - a) < 1e-6 && Math.abs(el.dataset.xMax - b) < 1e-6;
  }, [firstBlock.t_start_s, firstBlock.t_end_s], { timeout: 15000 });

  // The run raised an alert; acknowledge it from the run page.
  const alertRow = page.locator('.run-alerts tbody tr').first();
  await alertRow.getByLabel(/Note for alert/).fill('checked by the browser test');
  await alertRow.getByRole('button', { name: 'Acknowledge' }).click();
  await page.locator('.run-alerts .acked').first().waitFor();
  const alerts = (await server.api('GET', `alerts?run_id=${runId}`)).items;
  assert.ok(alerts.length > 0);
  assert.ok(alerts[0].acked_at, 'the alert should be acknowledged');
  assert.equal(alerts[0].ack_note, 'checked by the browser test');
  await screenshot(page, 'upload-5-alert-acknowledged');

  // The runs list shows the run with its flagged block count.
  await page.getByRole('navigation', { name: 'Main' }).getByRole('link', { name: 'Runs' }).click();
  const listRow = page.locator(`#runs-table tr[data-run-id="${runId}"]`);
  await listRow.waitFor();
  assert.match(await listRow.innerText(), new RegExp(`\\b${run.summary.flagged_blocks}\\b`));
  await screenshot(page, 'upload-6-runs-list');

  assert.deepEqual(errors, []);
});
