// A live run on the run page: `cutload replay` plays the demo log as an MTConnect adapter, the
// service follows it (POST /api/v1/live), and the page updates while the run is live: the banner
// says connected with the lag, the force plot follows the machine time, completed blocks appear
// (flagged ones highlighted); Stop closes the run and the page shows the stored results.
// With CUTLOAD_UPDATE_DOCS_IMG=1 the screenshot is also written to docs/img/live-run.png.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import {
  env, skipWithoutChromium, startServer, launchBrowser, openPage, screenshot, dataFile,
} from './harness.mjs';

skipWithoutChromium();

let server;
let browser;
let replay;

// `cutload replay` on a free port; resolves with the port its first line names.
function startReplay(log, speed) {
  return new Promise((resolve, reject) => {
    const proc = spawn(env('CUTLOAD_BIN'), ['replay', log, '--listen', '127.0.0.1:0', '--speed', String(speed), '--loop'],
      { stdio: ['ignore', 'pipe', 'pipe'] });
    let out = '';
    const timer = setTimeout(() => reject(new Error(`cutload replay did not start: ${out}`)), 20000);
    proc.stdout.on('data', (d) => {
      out += d;
      const m = /SHDR adapter on [\d.]+:(\d+)/.exec(out);
      if (m) {
        clearTimeout(timer);
        resolve({ proc, port: Number(m[1]) });
      }
    });
    proc.on('exit', (code) => reject(new Error(`cutload replay exited with ${code}: ${out}`)));
  });
}

before(async () => {
  server = await startServer({ workers: 1 });
  browser = await launchBrowser();
});

after(async () => {
  replay?.proc.kill('SIGTERM');
  await browser?.close();
  await server?.stop();
});

test('the run page follows a live run: banner, plot, blocks, stop', async () => {
  const log = dataFile('demo_dryrun.csv');
  const specFile = dataFile('demo_run.json');
  assert.ok(log && specFile, 'data/demo_dryrun.csv and data/demo_run.json are part of the repository');
  replay = await startReplay(log, 2);
  const run = await server.api('POST', 'live', {
    source: { adapter: `127.0.0.1:${replay.port}` },
    spec: JSON.parse(fs.readFileSync(specFile, 'utf8')),
    sampling: 'polled',
    name: 'live from the browser test',
  });
  assert.equal(run.state, 'live');

  const { page, errors } = await openPage(browser, server);
  await page.goto(`${server.url}/#/runs/${run.id}`);
  const banner = page.locator('.live-banner');
  await banner.waitFor();
  await page.waitForFunction(() => document.querySelector('.live-banner')?.dataset.connection === 'connected', null, { timeout: 20000 });
  assert.match(await banner.textContent(), /Connected · lag \d+ ms · machine time/);
  await page.locator('.state-live').waitFor();

  // The plot follows: its x range moves on with the machine time.
  await page.locator('.live-plot canvas').waitFor({ timeout: 20000 });
  const xMax = () => page.evaluate(() => {
    const m = /machine time ([\d.]+) s/.exec(document.querySelector('.live-banner').textContent);
    return m ? Number(m[1]) : 0;
  });
  const first = await xMax();
  await page.waitForTimeout(1500);
  const later = await xMax();
  assert.ok(later > first + 1, `machine time moved on: ${first} -> ${later}`);

  // Blocks appear as they complete; the demo's overloads show as flagged rows.
  await page.waitForFunction(() => document.querySelectorAll('.live-blocks tbody tr').length >= 20, null, { timeout: 30000 });
  await page.waitForFunction(() => document.querySelectorAll('.live-blocks tbody tr.flagged').length >= 1, null, { timeout: 30000 });
  // The table shows the stored summaries to three significant figures.
  const row = page.locator('.live-blocks tbody tr.flagged').first();
  const [name, , peakText] = await row.locator('td').allTextContents();
  const view = await server.api('GET', `live/${run.id}`);
  const stored = view.blocks.find((b) => b.block === name);
  assert.ok(stored, `block ${name} is in the live view`);
  const shown = Number(peakText.replaceAll(',', ''));
  assert.ok(Math.abs(shown - stored.peak_force_N) <= 0.005 * stored.peak_force_N, `${name}: shown ${peakText} N, stored ${stored.peak_force_N} N`);
  const file = await screenshot(page, 'live-run');
  if (process.env.CUTLOAD_UPDATE_DOCS_IMG) {
    const docs = path.join(path.dirname(fileURLToPath(import.meta.url)), '..', '..', 'docs', 'img');
    fs.copyFileSync(file, path.join(docs, 'live-run.png'));
  }

  // Stop: the run closes and the page turns into the stored run's page.
  await page.getByRole('button', { name: 'Stop' }).click();
  await page.locator('.state-done').waitFor({ timeout: 30000 });
  assert.equal(await page.locator('.live-banner').count(), 0);
  const done = await server.api('GET', `runs/${run.id}`);
  assert.equal(done.state, 'done');
  assert.equal(done.summary.live.end, 'stopped');
  assert.ok(done.summary.blocks >= 20);
  assert.deepEqual(errors, []);
});
