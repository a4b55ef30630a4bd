// Bad uploads: each problem is shown next to the field it concerns, and nothing is created.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { skipWithoutChromium, startServer, launchBrowser, openPage, screenshot, tempFile } from './harness.mjs';

skipWithoutChromium();

let server;
let browser;
let page;
let errors;

const SPEC = {
  tool: { shape: 'flat', diameter_mm: 8, flutes: 2, helix_deg: 30, corner_radius_mm: 0, flute_length_mm: 20, stickout_mm: 30 },
  material: { name: 'Al 7075-T6', Ktc_N_mm2: 767, Krc_N_mm2: 168.8, Kac_N_mm2: 222, Kte_N_mm: 27.7, Kre_N_mm: 26.6, Kae_N_mm: 0.7 },
  stock: { box_mm: { min: [0, 0, 0], max: [50, 50, 20] } },
};

before(async () => {
  server = await startServer();
  browser = await launchBrowser();
  ({ page, errors } = await openPage(browser, server));
  await page.goto(`${server.url}/#/new`);
  await page.getByRole('button', { name: 'Upload and compute' }).waitFor();
});

after(async () => {
  await browser?.close();
  await server?.stop();
});

const errorOf = (selector) => page.locator(selector).evaluate((el) => document.getElementById(`${el.id}-err`).textContent);
const submit = () => page.getByRole('button', { name: 'Upload and compute' }).click();

test('missing inputs are named before anything is sent', async () => {
  await submit();
  assert.match(await errorOf('#log-file'), /choose the dry-run log file/);
  assert.match(await errorOf('input[name="tool-diameter_mm"]'), /^Required: enter the diameter in mm\.$/);
  assert.match(await errorOf('#stock-box_mm-min-group'), /^Required: enter x, y and z \(mm\)\.$/);
  assert.equal(await page.locator('input[name="tool-diameter_mm"]').getAttribute('aria-invalid'), 'true');
  await screenshot(page, 'bad-upload-1-missing-fields');
});

test('a log the server cannot read: its error sits by the log field', async () => {
  await page.getByLabel('Run spec file (RUN.json)').setInputFiles(tempFile(server, 'spec.json', JSON.stringify(SPEC)));
  await page.setInputFiles('#log-file', tempFile(server, 'garbage.csv', 'this is,not a\ndry run,log\n1,2\n'));
  await submit();
  await page.waitForFunction(() => document.getElementById('log-file-err').textContent.length > 0);
  const message = await errorOf('#log-file');
  console.log(`log field error: ${message}`);
  assert.match(message, /garbage\.csv/, 'the message names the uploaded file');
  assert.equal(await page.locator('#log-file').getAttribute('aria-invalid'), 'true');
  assert.match(page.url(), /#\/new$/, 'the page stays on the form');
  await screenshot(page, 'bad-upload-2-bad-log');
});

test('a spec value the engine rejects: its error sits by that field', async () => {
  await page.setInputFiles('#log-file', tempFile(server, 'ok.csv',
    't_spindle [s],spindle [rpm],t_feed [s],feed [mm/min],t_pos [s],x [mm],y [mm],z [mm],block\n'
    + Array.from({ length: 50 }, (_, i) => {
      const t = 0.006 * i;
      return `${t.toFixed(6)},8000,${(t + 0.002).toFixed(6)},1200,${(t + 0.004).toFixed(6)},${(0.12 * i).toFixed(3)},10,-2,N10`;
    }).join('\n')));
  await page.locator('input[name="tool-diameter_mm"]').fill('-8');
  await submit();
  await page.waitForFunction(() => document.querySelector('input[name="tool-diameter_mm"]').getAttribute('aria-invalid') === 'true');
  const message = await errorOf('input[name="tool-diameter_mm"]');
  console.log(`diameter field error: ${message}`);
  assert.match(message, /^Diameter \(mm\): /, 'the server\'s key is said as the field\'s label');
  assert.equal(await errorOf('#log-file'), '', 'the log error from before is cleared');
  await screenshot(page, 'bad-upload-3-bad-spec');
});

test('nothing was created', async () => {
  const runs = await server.api('GET', 'runs');
  assert.deepEqual(runs.items, []);
  assert.deepEqual(errors, []);
});
