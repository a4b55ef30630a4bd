// A run with a tool table through the page: the spec file's table travels with the upload (the
// tool choice says so), the block table names every block's tool from the service, the tool filter
// narrows the table and moves the plot to that tool's stretch, and a tool the table lacks is
// flagged in words.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { skipWithoutChromium, startServer, launchBrowser, openPage, screenshot, tempFile } from './harness.mjs';

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

// A slot along X, 2 mm deep, in the log's layout (6 ms cycle, a time stamp per channel, a tool
// column): N10 cut by T1, N20 by T2, N30 by T7, which the table below does not have.
function toolLog() {
  const dt = 0.006;
  const lines = ['t_spindle [s],spindle [rpm],t_feed [s],feed [mm/min],t_pos [s],x [mm],y [mm],z [mm],tool,block'];
  const v = 1200 / 60;
  for (let i = 0; i < 500; i++) {
    const t = i * dt;
    const part = Math.min(2, Math.floor(i / 167));
    lines.push([t.toFixed(6), 10000, (t + 0.002).toFixed(6), 1200, (t + 0.004).toFixed(6), (-6 + v * t).toFixed(3), '5.000',
      '-2.000', [1, 2, 7][part], `N${10 * (part + 1)}`].join(','));
  }
  return `${lines.join('\n')}\n`;
}

const flat = { shape: 'flat', flutes: 2, helix_deg: 30, corner_radius_mm: 0, flute_length_mm: 20, stickout_mm: 30 };
const SPEC = {
  tools: [{ number: 1, diameter_mm: 8, ...flat }, { number: 2, diameter_mm: 6, ...flat }],
  material: { name: 'A7050', Ktc_N_mm2: 800, Krc_N_mm2: 300, Kac_N_mm2: 100, Kte_N_mm: 20, Kre_N_mm: 20, Kae_N_mm: 5 },
  stock: { box_mm: { min: [0, 0, -10], max: [100, 10, 0] } },
  limits: { force_N: 5000 },
};

test('a tool table: uploaded from the spec file, every block names its tool, the filter narrows table and plot', async () => {
  const { page, errors } = await openPage(browser, server);
  await page.getByRole('navigation', { name: 'Main' }).getByRole('link', { name: 'New run' }).click();
  await page.setInputFiles('#log-file', tempFile(server, 'tools.csv', toolLog()));
  await page.getByLabel('Run spec file (RUN.json)').setInputFiles(tempFile(server, 'tools.json', JSON.stringify(SPEC)));
  const tool = page.locator('select[name="tool_id"]');
  await page.waitForFunction(() => document.querySelector('select[name="tool_id"]').value === 'table');
  assert.equal(await tool.locator('option:checked').innerText(), 'Tool table from the spec file (T1, T2)');
  assert.ok(await page.locator('input[name="tool-diameter_mm"]').isHidden(), 'no inline tool fields for a table');
  await page.getByLabel('Run name').fill('three tools');
  await page.getByRole('button', { name: 'Upload and compute' }).click();

  await page.waitForURL(/#\/runs\/\d+$/);
  const runId = Number(/#\/runs\/(\d+)$/.exec(page.url())[1]);
  await page.locator('#block-table tbody tr').first().waitFor({ timeout: 120000 });
  const run = await server.api('GET', `runs/${runId}`);
  assert.equal(run.state, 'done');
  assert.deepEqual(run.inputs.spec.tools.map((t) => t.number), [1, 2]);
  const blocks = (await server.api('GET', `runs/${runId}/blocks`)).items;
  assert.deepEqual(blocks.map((b) => [b.block, b.tool]), [['N10', 1], ['N20', 2], ['N30', 7]]);

  // The tool column says each block's tool; the unknown one is flagged in words.
  const heads = await page.locator('#block-table thead th').allInnerTexts();
  const toolCol = heads.findIndex((t) => t.startsWith('Tool'));
  assert.ok(toolCol >= 0, `tool column: ${heads}`);
  const cells = await page.locator(`#block-table tbody tr > :nth-child(${toolCol + 1})`).allInnerTexts();
  assert.deepEqual(cells.map((t) => t.trim()), ['T1', 'T2', 'T7']);
  const n30 = page.locator('#block-table tbody tr[data-block="N30"] .flag');
  assert.equal((await n30.first().innerText()).trim(), 'Unknown tool');

  // Filter T2: the table keeps N20, the plot shows N20's stretch.
  await page.locator('#tool-filter').selectOption('2');
  assert.deepEqual(await page.locator('#block-table tbody tr').evaluateAll((rows) => rows.map((r) => r.dataset.block)), ['N20']);
  const n20 = blocks.find((b) => b.block === 'N20');
  await page.waitForFunction(([a, b]) => {
    const m = /([\d.]+) – ([\d.]+) s/.exec(document.getElementById('plot-range')?.textContent || '');
    return m && Math.abs(Number(m[1]) - a) < 0.01 && Math.abs(Number(m[2]) - b) < 0.01;
  }, [n20.t_start_s, n20.t_end_s]);
  await screenshot(page, 'tools-1-filtered');
  // The unknown tool is no limit: the alerts box says so in words.
  await page.locator('#no-alerts').waitFor();
  assert.match(await page.locator('#no-alerts').innerText(), /ran with a tool the run spec's tool table does not have/);
  assert.ok(!/null/.test(await page.locator('main').innerText()), 'no stray null on the page');
  // The 3-D view draws the tool of each stretch: T1 (D 8) and T2 (D 6); T7's stretch shows the
  // table's first tool, as a run without tools would.
  await page.locator('#view3d').scrollIntoViewIfNeeded();
  await page.locator('#view3d[data-ready="true"]').waitFor({ timeout: 60000 });
  assert.deepEqual(await page.evaluate(() => document.getElementById('view3d').view3d.tools.map((t) => t.tool.diameter_mm)), [8, 6]);
  // All tools again: the whole run.
  await page.locator('#tool-filter').selectOption('');
  assert.equal(await page.locator('#block-table tbody tr').count(), 3);
  assert.deepEqual(errors, []);
  await page.context().close();
});
