// A run with its NC program through the page: the commanded resultant beside the actual one on the
// plot (refetched per window like the actual), the mapping quality, the per-block comparison
// columns, the comparison CSV, a feed optimization with its rewritten program; and a program the
// server cannot read, whose error names the line by the program field.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import { skipWithoutChromium, startServer, launchBrowser, openPage, screenshot, dataFile, tempFile } from './harness.mjs';

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

const DEMO = ['demo_dryrun.csv', 'demo_run.json', 'demo_program.nc'].map((f) => {
  const p = dataFile(f);
  if (!p) throw new Error(`data/${f} is missing`);
  return p;
});

// The page's rendering of num(): significant figures with thousands separators.
const cellNumber = (text) => Number(text.replace(/,/g, ''));
const close = (shown, exact) => Math.abs(shown - exact) <= 0.006 * Math.max(Math.abs(exact), 1e-9) + 1e-9;

async function downloadText(page, locator) {
  const [d] = await Promise.all([page.waitForEvent('download'), locator.click()]);
  return { name: d.suggestedFilename(), text: fs.readFileSync(await d.path(), 'utf8') };
}

test('commanded overlay, mapping quality, comparison columns and a feed optimization', async () => {
  const [log, spec, program] = DEMO;
  const { page, errors } = await openPage(browser, server);
  await page.getByRole('navigation', { name: 'Main' }).getByRole('link', { name: 'New run' }).click();
  await page.setInputFiles('#log-file', log);
  await page.getByLabel('Run spec file (RUN.json)').setInputFiles(spec);
  await page.getByLabel('Run name').fill('demo with its program');
  await page.getByLabel('NC program file (optional)').setInputFiles(program);
  await page.locator('.nc-options summary').click();
  await page.getByLabel('Map blocks from the program').check();
  await page.getByLabel('Ignore words').fill('G28,H');
  await page.getByLabel('G00 rapid feed (mm/min)').fill('30000');
  await screenshot(page, 'program-1-new-run-form');
  await page.getByRole('button', { name: 'Upload and compute' }).click();

  await page.waitForURL(/#\/runs\/\d+$/);
  const runId = Number(/#\/runs\/(\d+)$/.exec(page.url())[1]);
  await page.locator('#block-table tbody tr').first().waitFor({ timeout: 120000 });
  const run = await server.api('GET', `runs/${runId}`);
  assert.equal(run.state, 'done');
  assert.equal(run.inputs.nc_program.filename, 'demo_program.nc');
  assert.equal(run.inputs.nc_program.options.map_blocks, true);
  assert.deepEqual(run.inputs.nc_program.options.ignore_words, ['G28', 'H']);
  assert.equal(run.inputs.nc_program.options.rapid_feed_mm_min, 30000);
  assert.equal(run.links.program, `/api/v1/runs/${runId}/program`);
  const cmp = await server.api('GET', `runs/${runId}/program`);

  // The commanded resultant is a series of its own, with exactly the server's overview in it.
  const plot = page.locator('#force-plot');
  await page.waitForFunction(() => Number(document.getElementById('force-plot').dataset.commandedPoints) > 0);
  const overview = await server.api('GET', `runs/${runId}/forces?source=commanded&channels=f_N&max_points=2000`);
  assert.ok(overview.t_s.length > 10, 'the commanded forces have samples');
  assert.equal(Number(await plot.getAttribute('data-commanded-points')), (overview.decimated ? 2 : 1) * overview.t_s.length);
  const legend = await plot.locator('.u-legend').innerText();
  assert.match(legend, /F actual \(dry run\)/);
  assert.match(legend, /F commanded \(program\)/);
  const commandedLegend = plot.locator('.u-legend .u-series').filter({ hasText: 'F commanded (program)' });
  await page.locator('#show-commanded').uncheck();
  assert.match(await commandedLegend.getAttribute('class'), /\bu-off\b/, 'unticking hides the commanded series');
  await commandedLegend.locator('.u-label').click();
  assert.equal(await page.locator('#show-commanded').isChecked(), true, 'the legend click shows it again and ticks the box');
  assert.doesNotMatch(await commandedLegend.getAttribute('class'), /\bu-off\b/);

  // Mapping quality as the server reports it.
  const mapping = await page.locator('#mapping-quality').innerText();
  console.log(mapping);
  assert.match(mapping, cmp.mapping.source === 'log' ? /block channel/ : /mapped from the program path/);
  assert.match(mapping, new RegExp(`${cmp.mapping.matched} of ${cmp.mapping.samples} samples matched`));
  assert.match(mapping, /mean [\d.]+ mm, p95 [\d.]+ mm, max [\d.]+ mm/);
  if (cmp.mapping.agreement != null) assert.match(mapping, /agreement with the logged blocks [\d.]+ %/);

  // Comparison columns: the cutting block with the highest commanded peak shows the server's numbers.
  const heads = await page.locator('#block-table thead th').allInnerTexts();
  for (const h of ['Max deviation (mm)', 'Feed deficit (%)', 'Commanded peak F (N)', 'Difference (%)']) {
    assert.ok(heads.some((t) => t.startsWith(h)), `column ${h} in ${heads}`);
  }
  const runBlocks = new Set((await server.api('GET', `runs/${runId}/blocks?limit=10000`)).items.map((b) => b.block));
  const cutting = cmp.blocks.filter((b) => !b.rapid && runBlocks.has(b.block) && b.commanded_peak_force_N > 0)
    .sort((a, b) => b.commanded_peak_force_N - a.commanded_peak_force_N)[0];
  assert.ok(cutting, 'a cutting block in both the run and the comparison');
  const row = page.locator(`#block-table tbody tr[data-block="${cutting.block}"]`).first();
  for (const key of ['max_deviation_mm', 'feed_deficit_pct', 'commanded_peak_force_N', 'force_difference_pct']) {
    const text = await row.locator(`td[data-col="${key}"]`).innerText();
    assert.ok(close(cellNumber(text), cutting[key]), `${cutting.block} ${key}: shown ${text}, server ${cutting[key]}`);
  }
  // A block the comparison does not list stays blank (the demo's comparison lists every block, so
  // the page's own table is given one without).
  const blankRows = await page.evaluate(async () => {
    const { BlockTable, withComparison } = await import('/js/block_table.js');
    const base = { t_start_s: 0, t_end_s: 1, peak_force_N: 1, flags: [] };
    const compared = { block: 'N1', max_deviation_mm: 0.5, feed_deficit_pct: 10, commanded_peak_force_N: 100, force_difference_pct: -5 };
    const box = document.createElement('div');
    new BlockTable(box, withComparison([{ ...base, idx: 0, block: 'N1' }, { ...base, idx: 1, block: 'N2' }], [compared]),
      { onSelect: () => {}, comparison: true });
    return [...box.querySelectorAll('tbody tr')].map((tr) => [tr.dataset.block,
      ...['max_deviation_mm', 'feed_deficit_pct', 'commanded_peak_force_N', 'force_difference_pct'].map((k) => tr.querySelector(`td[data-col="${k}"]`).textContent)]);
  });
  assert.deepEqual(blankRows, [['N1', '0.5', '10', '100', '-5'], ['N2', '', '', '', '']]);
  // Sorting by a comparison column puts the largest commanded peak first.
  await page.getByRole('button', { name: /^Commanded peak F \(N\)/ }).click();
  const top = await page.locator('#block-table tbody tr').first().locator('td[data-col="commanded_peak_force_N"]').innerText();
  assert.ok(close(cellNumber(top), cutting.commanded_peak_force_N), `first row after sorting: ${top}`);
  await screenshot(page, 'program-2-run-with-program');

  // Zoomed to that block, the commanded series is fetched for the same window as the actual.
  await row.click();
  await page.waitForFunction(() => {
    const d = document.getElementById('force-plot').dataset;
    return d.windowFrom === d.xMin && d.commandedWindowFrom === d.xMin && d.commandedWindowTo === d.xMax;
  }, null, { timeout: 15000 });
  assert.ok(Number(await plot.getAttribute('data-commanded-points')) > 0);
  await screenshot(page, 'program-3-block-zoomed');

  const csv = await downloadText(page, page.locator('#program-csv'));
  assert.match(csv.text.split('\n')[0], /^block,/);
  assert.ok(csv.text.trim().split('\n').length >= cmp.blocks.length, 'one CSV row per compared block');

  // Feed optimization at 80 % of the limits.
  assert.equal(await page.locator('#optimize-target').inputValue(), '0.8');
  await page.getByLabel('Basis').selectOption('actual');
  await page.getByRole('button', { name: 'Optimize feeds' }).click();
  await page.locator('#optimize-summary').waitFor({ timeout: 120000 });
  const opt = (await server.api('GET', `runs/${runId}/optimizations`)).items[0];
  assert.equal(opt.state, 'done');
  assert.equal(opt.params.target, 0.8);
  assert.equal(await page.locator('#optimize-table tbody tr:visible').count(), opt.result.changed_blocks || opt.result.blocks.length,
    'changed blocks only, by default');
  if (opt.result.changed_blocks) await page.getByLabel('Changed blocks only').uncheck();
  assert.equal(await page.locator('#optimize-table tbody tr:visible').count(), opt.result.blocks.length);
  const changed = opt.result.blocks.find((b) => b.recommended_feed_mm_min !== b.programmed_feed_mm_min) || opt.result.blocks[0];
  const cells = await page.locator(`#optimize-table tbody tr[data-block="${changed.block}"] td`).allInnerTexts();
  // The block's name is the row header; the cells start with the feeds.
  assert.ok(close(cellNumber(cells[0]), changed.programmed_feed_mm_min), `programmed F ${cells[0]}`);
  assert.ok(close(cellNumber(cells[1]), changed.recommended_feed_mm_min), `recommended F ${cells[1]}`);
  const summary = await page.locator('#optimize-summary').innerText();
  console.log(summary);
  assert.match(summary, new RegExp(`^${opt.result.changed_blocks} of ${opt.result.blocks.length} blocks changed`));
  assert.match(summary, opt.result.target_met ? /target 80 % of each limit met/i : /not met/);
  await screenshot(page, 'program-4-optimized');

  const nc = await downloadText(page, page.locator('#optimized-program'));
  assert.equal(nc.name, 'demo_program_opt.nc');
  assert.ok(nc.text.startsWith('%'), 'the optimized program starts with %');
  assert.match(nc.text, /F\d/);
  const res = await fetch(`${server.url}${opt.links.program}`, { headers: { Authorization: `Bearer ${server.key}` } });
  assert.equal(nc.text, await res.text(), 'the page saves the server\'s optimized program');

  assert.deepEqual(errors, []);
});

test('a program the server cannot read: its error names the line by the program field', async () => {
  const [log, spec] = DEMO;
  const { page, errors } = await openPage(browser, server);
  await page.goto(`${server.url}/#/new`);
  await page.setInputFiles('#log-file', log);
  await page.getByLabel('Run spec file (RUN.json)').setInputFiles(spec);
  const programField = page.getByLabel('NC program file (optional)');
  const errorOf = (id) => page.locator(`#${id}-err`).innerText();
  const submit = () => page.getByRole('button', { name: 'Upload and compute' }).click();

  // Options are checked before sending.
  await page.locator('.nc-options summary').click();
  await page.getByLabel('G00 rapid feed (mm/min)').fill('-5');
  await submit();
  assert.match(await errorOf(await page.getByLabel('G00 rapid feed (mm/min)').getAttribute('id')), /Enter a feed above 0 mm\/min/);
  assert.match(await errorOf('nc-program-file'), /Choose the NC program file/);
  await page.getByLabel('G00 rapid feed (mm/min)').fill('');

  await programField.setInputFiles(tempFile(server, 'bad_program.nc', '%\nO0001\nG21 G90\nN10 G41 X1.\nM30\n%\n'));
  await submit();
  await page.waitForFunction(() => document.getElementById('nc-program-file-err').textContent.length > 0);
  const message = await errorOf('nc-program-file');
  console.log(`program field error: ${message}`);
  assert.match(message, /bad_program\.nc:4\b/, 'the message names the file and line');
  assert.match(message, /G41/, 'the message names the word');
  assert.equal(await programField.getAttribute('aria-invalid'), 'true');
  assert.equal(await errorOf('log-file'), '', 'the log is not blamed');
  assert.match(page.url(), /#\/new$/, 'the page stays on the form');
  await screenshot(page, 'program-5-bad-program');

  assert.deepEqual((await server.api('GET', 'runs')).items.length, 1, 'only the first test\'s run exists');
  assert.deepEqual(errors, []);
});
