// The run page as a shop engineer reads it (issue 17): worst blocks first, the program beside the
// plot, the 3-D view, an honest plot, alerts without set-up, the optimizer's shop options and
// plain words, at 1400 and 1024 px. The demo run (log, spec, program) is computed through the API.
// Timings are not asserted here (bench/bench_web_run_page.mjs prints them).
//
// With CUTLOAD_UPDATE_DOCS_IMG=1 the screenshots named for the documentation are also written to
// docs/img (otherwise only to the test artifacts).
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import {
  env, skipWithoutChromium, startServer, launchBrowser, openPage, screenshot, dataFile, tempFile,
} from './harness.mjs';

skipWithoutChromium();

let server;
let browser;
let demo;          // {id, run, blocks, program, source}
let headroom;      // a run whose peaks stay under generous limits

const WIDTHS = [1400, 1024];

function docsImage(file, name) {
  if (!process.env.CUTLOAD_UPDATE_DOCS_IMG) return;
  const dir = path.join(path.dirname(env('CUTLOAD_DATA_DIR')), 'docs', 'img');
  fs.copyFileSync(file, path.join(dir, `${name}.png`));
}

async function shot(page, name, { docs = false, fullPage = false } = {}) {
  const file = fullPage ? await screenshot(page, name) : path.join(env('CUTLOAD_WEB_ARTIFACTS'), `${name}.png`);
  if (!fullPage) {
    fs.mkdirSync(path.dirname(file), { recursive: true });
    await page.screenshot({ path: file });
  }
  if (docs) docsImage(file, name);
}

async function waitDone(id) {
  for (;;) {
    const run = await server.api('GET', `runs/${id}`);
    if (run.state !== 'queued' && run.state !== 'running') return run;
    await new Promise((r) => setTimeout(r, 200));
  }
}

async function submit(spec, { program = true, name } = {}) {
  const fd = new FormData();
  fd.append('log', new Blob([fs.readFileSync(dataFile('demo_dryrun.csv'))]), 'demo_dryrun.csv');
  fd.append('spec', JSON.stringify(spec));
  if (name) fd.append('name', name);
  if (program) fd.append('nc_program', new Blob([fs.readFileSync(dataFile('demo_program.nc'))]), 'demo_program.nc');
  const { id } = await server.api('POST', 'runs', fd);
  const run = await waitDone(id);
  assert.equal(run.state, 'done', run.error);
  return run;
}

const demoSpec = () => JSON.parse(fs.readFileSync(dataFile('demo_run.json'), 'utf8'));

before(async () => {
  if (!dataFile('demo_dryrun.csv')) return;
  server = await startServer({ workers: 1 });
  browser = await launchBrowser();
  const run = await submit(demoSpec(), { name: 'demo pocket' });
  demo = {
    id: run.id,
    run,
    blocks: (await server.api('GET', `runs/${run.id}/blocks?limit=10000`)).items,
    program: await server.api('GET', `runs/${run.id}/program`),
  };
  const res = await fetch(`${server.url}/api/v1/runs/${run.id}/program/source`, { headers: { Authorization: `Bearer ${server.key}` } });
  demo.source = (await res.text()).replace(/\r/g, '').split('\n');
  const spec = demoSpec();
  spec.limits = { force_N: 2000, torque_Nm: 6, power_kW: 6 };
  headroom = await submit(spec, { program: false, name: 'headroom' });
});

after(async () => {
  await browser?.close();
  await server?.stop();
});

async function runPage(width, id = demo.id) {
  const { page, context, errors } = await openPage(browser, server);
  await page.setViewportSize({ width, height: 900 });
  await page.goto(`${server.url}/#/runs/${id}`);
  await page.locator('#block-table tbody tr').first().waitFor({ timeout: 60000 });
  // The 3-D view loads once it is scrolled into view.
  await page.locator('#path-title').scrollIntoViewIfNeeded();
  await page.locator('#view3d[data-ready="true"]').waitFor({ timeout: 30000 });
  await page.evaluate(() => window.scrollTo(0, 0));
  return { page, context, errors };
}

const plotRange = (page) => page.locator('#force-plot').evaluate((el) => [Number(el.dataset.xMin), Number(el.dataset.xMax)]);

async function waitRange(page, a, b) {
  await page.waitForFunction(([x0, x1]) => {
    const d = document.getElementById('force-plot').dataset;
    return Math.abs(d.xMin - x0) < 1e-6 && Math.abs(d.xMax - x1) < 1e-6;
  }, [a, b], { timeout: 15000 });
}

// The limit of each flag's quantity in the run's spec.
const QUANTITY = {
  force_limit: ['peak_force_N', 'force_N'], torque_limit: ['peak_torque_Nm', 'torque_Nm'], power_limit: ['peak_power_kW', 'power_kW'],
  chip_load_limit: ['max_chip_mm', 'chip_mm'], bending_limit: ['max_bending_MPa', 'bending_MPa'],
};

test('worst blocks first: collisions, then overruns by margin, each with block, NC text and value against the limit', { skip: !dataFile('demo_dryrun.csv') }, async () => {
  for (const width of WIDTHS) {
    const { page, errors } = await runPage(width);
    const limits = demo.run.inputs.spec.limits;
    // The expected order, from the blocks as the API gives them.
    const collisions = demo.blocks.filter((b) => b.flags.some((f) => f.flag === 'rapid_in_material' || f.flag === 'holder_contact'));
    const over = demo.blocks.filter((b) => !collisions.includes(b) && b.flags.some((f) => QUANTITY[f.flag]))
      .map((b) => ({ b, ratio: Math.max(...b.flags.filter((f) => QUANTITY[f.flag]).map((f) => b[QUANTITY[f.flag][0]] / limits[QUANTITY[f.flag][1]])) }))
      .sort((p, q) => q.ratio - p.ratio);
    assert.ok(over.length + collisions.length > 0, 'the demo run has flagged blocks');
    const items = page.locator('#problem-list li');
    const shown = await items.evaluateAll((lis) => lis.map((li) => ({ block: li.dataset.block, kind: li.dataset.kind, text: li.innerText })));
    const expected = [...collisions.sort((a, b) => a.t_start_s - b.t_start_s).map((b) => b.block), ...over.map((o) => o.b.block)];
    assert.deepEqual(shown.filter((s) => s.kind !== 'near').map((s) => s.block), expected.slice(0, shown.filter((s) => s.kind !== 'near').length));
    const kinds = shown.map((s) => s.kind);
    assert.deepEqual(kinds, [...kinds].sort((a, b) => ['collision', 'over', 'near'].indexOf(a) - ['collision', 'over', 'near'].indexOf(b)), 'collisions before overruns before near misses');
    // The top overrun: its NC text is the program's line, its value and limit are the API's.
    const top = shown.find((s) => s.kind === 'over');
    const o = over.find((x) => x.b.block === top.block);
    const line = demo.program.blocks.find((p) => p.block === top.block).line;
    assert.ok(top.text.includes(demo.source[line - 1].trim()), `NC text of ${top.block} (line ${line}) in "${top.text}"`);
    const flag = o.b.flags.find((f) => QUANTITY[f.flag]);
    const [peakKey, limitKey] = QUANTITY[flag.flag];
    assert.match(top.text, new RegExp(`against ${limits[limitKey]}`));
    assert.match(top.text, new RegExp(`${(100 * (o.b[peakKey] / limits[limitKey] - 1)).toPrecision(2).replace('.', '\\.')} % over`));
    await shot(page, `run-page-top-${width}`, { docs: true });

    // A click zooms the plot to the block, highlights it on the path and in the program.
    await items.filter({ hasText: top.block }).first().getByRole('button').click();
    await waitRange(page, o.b.t_start_s, o.b.t_end_s);
    assert.equal(await page.locator('#nc-listing').getAttribute('data-selected'), top.block);
    const selectedRow = page.locator(`#nc-listing .listing-row.selected[data-block="${top.block}"]`);
    await selectedRow.waitFor();
    assert.ok(Number(await page.locator('#view3d').getAttribute('data-selected-segments')) > 0, 'the path of the block is highlighted');
    assert.equal(await page.locator(`#block-table tbody tr[data-block="${top.block}"]`).first().getAttribute('aria-selected'), 'true');
    assert.match(await page.locator(`#problem-list li[data-block="${top.block}"]`).first().getAttribute('class'), /selected/);
    await shot(page, `run-page-problem-selected-${width}`);
    // The plot beside the listing and the 3-D view, with that block selected, for the documentation.
    await page.evaluate(() => window.scrollBy(0, document.getElementById('forces-title').getBoundingClientRect().top - 10));
    await shot(page, `run-page-plot-listing-${width}`, { docs: true });
    await page.evaluate(() => window.scrollBy(0, document.getElementById('path-title').getBoundingClientRect().top - 10));
    await shot(page, `run-page-3d-${width}`, { docs: true });

    // The layout fits the window: no page-wide sideways scrolling; the wide block table scrolls
    // in its own box.
    const overflow = await page.evaluate(() => document.documentElement.scrollWidth - window.innerWidth);
    assert.ok(overflow <= 0, `page ${overflow} px wider than the ${width} px window`);
    const table = await page.locator('#block-table').boundingBox();
    const scroller = await page.locator('.blocks .table-scroll').boundingBox();
    assert.ok(scroller.x >= 0 && scroller.x + scroller.width <= width, 'the table box fits the window');
    console.log(`${width} px: block table ${table.width.toFixed(0)} px wide in a ${scroller.width.toFixed(0)} px box`);
    assert.deepEqual(errors, []);
    await page.context().close();
  }
});

test('the program beside the plot: the listing follows the cursor, block names on the zoomed axis, NC text, F and S in the table', { skip: !dataFile('demo_dryrun.csv') }, async () => {
  const { page, errors } = await runPage(1400);
  // Beside: the listing's box to the right of the plot, at the same height.
  const [plotBox, listBox] = [await page.locator('#force-plot').boundingBox(), await page.locator('#nc-listing').boundingBox()];
  assert.ok(listBox.x > plotBox.x + plotBox.width - 1 && Math.abs(listBox.y - plotBox.y) < 60, 'listing beside the plot');
  // The cursor over a cutting block marks that block's line.
  const cut = demo.blocks.filter((b) => b.peak_force_N > 0).sort((a, b) => (b.t_end_s - b.t_start_s) - (a.t_end_s - a.t_start_s))[0];
  const [x0, x1] = await plotRange(page);
  await page.locator('#force-plot').scrollIntoViewIfNeeded();
  const over = await page.locator('#force-plot .u-over').boundingBox();
  const tMid = (cut.t_start_s + cut.t_end_s) / 2;
  await page.mouse.move(over.x + ((tMid - x0) / (x1 - x0)) * over.width, over.y + over.height / 2);
  await page.waitForFunction((b) => document.getElementById('nc-listing').dataset.current === b, cut.block, { timeout: 5000 });
  const line = demo.program.blocks.find((p) => p.block === cut.block).line;
  const current = await page.locator('#nc-listing .listing-row.current').first().innerText();
  assert.ok(current.includes(demo.source[line - 1].trim()), `the marked line ${current} is line ${line} of the program`);
  // The tool in the 3-D view follows the cursor.
  const t3 = Number(await page.locator('#view3d').getAttribute('data-time'));
  assert.ok(t3 >= cut.t_start_s && t3 <= cut.t_end_s, `3-D time ${t3} in the block`);

  // Zoomed to a few blocks, their names are on the time axis.
  await page.locator(`#block-table tbody tr[data-block="${cut.block}"]`).first().click();
  await page.waitForFunction((b) => (document.getElementById('force-plot').dataset.blockLabels || '').split(' ').includes(b), cut.block, { timeout: 5000 });

  // The block table: NC text, programmed F and S, and a first column that stays put.
  const heads = await page.locator('#block-table thead th').allInnerTexts();
  for (const h of ['NC text', 'F programmed (mm/min)', 'S (rpm)']) assert.ok(heads.some((t) => t.startsWith(h)), `column ${h} in ${heads}`);
  const row = page.locator(`#block-table tbody tr[data-block="${cut.block}"]`).first();
  const cmp = demo.program.blocks.find((p) => p.block === cut.block);
  assert.equal((await row.locator('td.nc').innerText()).trim(), demo.source[line - 1].trim());
  assert.equal(Number((await row.locator('td[data-col="spindle_rpm"]').innerText()).replace(/,/g, '')), cmp.spindle_rpm);
  assert.equal(await page.locator('#block-table tbody th.sticky').first().evaluate((el) => getComputedStyle(el).position), 'sticky');
  const scroller = page.locator('.blocks .table-scroll');
  await scroller.evaluate((el) => { el.scrollLeft = 400; });
  const firstCell = await page.locator('#block-table tbody th.sticky').first().boundingBox();
  const scrollerBox = await scroller.boundingBox();
  assert.ok(Math.abs(firstCell.x - scrollerBox.x) < 3, 'the block column stays at the left edge while the table scrolls');
  // Multi-tool runs: blocks that name their tool get a tool column and filter, and the worst
  // blocks say the tool; blocks without one show neither (the demo's table above has no Tool).
  assert.ok(!heads.some((t) => t.startsWith('Tool')), 'no tool column without tools');
  const withTools = await page.evaluate(async () => {
    const { BlockTable } = await import('/js/block_table.js');
    const { problemsPanel } = await import('/js/problems.js');
    const base = { t_start_s: 0, t_end_s: 1, peak_force_N: 900, flags: [{ flag: 'force_limit', t_s: 0.5, value: 900 }] };
    const blocks = [{ ...base, idx: 0, block: 'N1', tool: 1 }, { ...base, idx: 1, block: 'N2', tool: 2, peak_force_N: 100, flags: [] }, { ...base, idx: 2, block: 'N3', tool: 2 }];
    const box = document.createElement('div');
    document.body.append(box);
    new BlockTable(box, blocks, { onSelect: () => {} });
    const head = [...box.querySelectorAll('thead th')].map((th) => th.textContent);
    const filter = box.querySelector('#tool-filter');
    const options = [...filter.options].map((o) => o.textContent);
    filter.value = '2';
    filter.dispatchEvent(new Event('change'));
    const rows = [...box.querySelectorAll('tbody tr')].map((tr) => tr.dataset.block);
    box.remove();
    const panel = problemsPanel(blocks, { force_N: 860 }, { onSelect: () => {} }).section;
    return { head, options, rows, tools: [...panel.querySelectorAll('.tool')].map((t) => t.textContent) };
  });
  assert.ok(withTools.head.includes('Tool'), `tool column: ${withTools.head}`);
  assert.deepEqual(withTools.options, ['All tools', 'T1', 'T2']);
  assert.deepEqual(withTools.rows, ['N2', 'N3']);
  assert.deepEqual(withTools.tools, ['T1', 'T2']);
  assert.deepEqual(errors, []);
  await page.context().close();
});

test('3-D view: the final stock and the path, the tool at the cursor, orbit, preset views, measure', { skip: !dataFile('demo_dryrun.csv') }, async () => {
  const { page, errors } = await runPage(1400);
  const canvas = page.locator('#view3d canvas');
  await canvas.scrollIntoViewIfNeeded();
  // Drawn: the picture holds stock grey and the path's load colours.
  const colours = () => canvas.evaluate((c) => {
    const ctx = document.createElement('canvas');
    ctx.width = c.width;
    ctx.height = c.height;
    const g = ctx.getContext('2d');
    g.drawImage(c, 0, 0);
    const d = g.getImageData(0, 0, c.width, c.height).data;
    const seen = { stock: 0, low: 0, over: 0, total: d.length / 4 };
    for (let i = 0; i < d.length; i += 4) {
      const [r, gg, b] = [d[i], d[i + 1], d[i + 2]];
      if (Math.abs(r - gg) < 12 && Math.abs(gg - b) < 16 && r > 120 && r < 235) seen.stock += 1;
      if (r < 40 && gg > 60 && gg < 120 && b > 110) seen.low += 1;
      if (r > 130 && gg < 40 && b < 50) seen.over += 1;
    }
    return seen;
  });
  const before = await colours();
  assert.ok(before.stock > before.total * 0.05, `stock visible: ${JSON.stringify(before)}`);
  assert.ok(before.low > 50, `path under 80 % drawn: ${JSON.stringify(before)}`);
  assert.ok(before.over > 5, `path over the limit drawn: ${JSON.stringify(before)}`);
  const firstDraw = Number(await page.locator('#view3d').getAttribute('data-first-draw-ms'));
  console.log(`3-D view: first draw ${firstDraw.toFixed(0)} ms after its data arrived`);
  // The stock is the API's height field: its cells and the box.
  const field = await server.api('GET', `runs/${demo.id}/stock?max_cells=40000`);
  assert.ok(field.top_mm.some((v) => v !== null && v < field.box_mm.max[2] - 1), 'the final stock has cuts below the box top');
  // The drawn top (flat rectangles merged, the rest two triangles per cell) is that height field:
  // every vertex of the final stock's top lies on a cell centre at that cell's height, and the
  // triangles cover exactly the cells whose four corners hold material, once.
  const drawn = await page.evaluate((f) => {
    const view = document.getElementById('view3d').view3d;
    view.setTime(null);
    const pos = view.stockGeometry.attributes.position.array;
    const count = Number(view.container.dataset.stockTriangles);
    let area = 0;
    let worst = 0;
    for (let t = 0; t < count; t++) {
      const p = pos.subarray(9 * t, 9 * t + 9);
      area += Math.abs((p[3] - p[0]) * (p[7] - p[1]) - (p[6] - p[0]) * (p[4] - p[1])) / 2;
      for (let k = 0; k < 3; k++) {
        const i = Math.round((p[3 * k] - f.x0_mm) / f.cell_mm - 0.5);
        const j = Math.round((p[3 * k + 1] - f.y0_mm) / f.cell_mm - 0.5);
        const v = f.top_mm[j * f.nx + i];
        worst = Math.max(worst, v == null ? Infinity : Math.abs(v - p[3 * k + 2]));
      }
    }
    return { count, area, worst };
  }, field);
  let quads = 0;
  const has = (i, j) => field.top_mm[j * field.nx + i] !== null;
  for (let j = 0; j + 1 < field.ny; j++) {
    for (let i = 0; i + 1 < field.nx; i++) if (has(i, j) && has(i + 1, j) && has(i, j + 1) && has(i + 1, j + 1)) quads += 1;
  }
  const cellArea = field.cell_mm ** 2;
  assert.ok(Math.abs(drawn.area - quads * cellArea) < 1e-4 * quads * cellArea, `top area ${drawn.area} mm² = ${quads} cells × ${cellArea} mm²`);
  assert.ok(drawn.worst < 1e-3, `top vertices at the field's heights (worst ${drawn.worst} mm)`);
  assert.ok(drawn.count < quads, `flat cells merged: ${drawn.count} triangles for ${quads} cells`);
  console.log(`3-D stock top: ${drawn.count} triangles for ${quads} cells`);

  // Orbit: dragging turns the view.
  const box = await canvas.boundingBox();
  const snapshot = () => canvas.evaluate((c) => c.toDataURL());
  const a = await snapshot();
  await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  await page.mouse.down();
  await page.mouse.move(box.x + box.width / 2 + 120, box.y + box.height / 2 + 20, { steps: 6 });
  await page.mouse.up();
  await page.waitForTimeout(100);
  assert.notEqual(await snapshot(), a, 'the picture changed after orbiting');
  await page.getByRole('button', { name: 'Top (X-Y)' }).click();
  await page.waitForTimeout(100);

  // Measure: two clicks along the screen's horizontal in the top view: the distance is mostly X.
  const measure = page.getByRole('button', { name: 'Measure', exact: true });
  await measure.click();
  assert.equal(await measure.getAttribute('aria-pressed'), 'true');
  const cx = box.x + box.width / 2;
  const cy = box.y + box.height * 0.3;
  await page.mouse.click(cx - 120, cy);
  await page.mouse.click(cx + 120, cy);
  const text = await page.locator('#measure-result').innerText();
  console.log(`measured: ${text}`);
  const m = /Distance ([\d.,]+) mm \(ΔX (-?[\d.,]+), ΔY (-?[\d.,]+), ΔZ (-?[\d.,]+) mm\)/.exec(text.replace(/−/g, '-'));
  assert.ok(m, `a distance: ${text}`);
  const [d, dx, dy, dz] = m.slice(1).map((s) => Number(s.replace(/,/g, '')));
  assert.ok(Math.abs(Math.hypot(dx, dy, dz) - d) < 0.01 * d + 0.01, 'distance is the length of its components');
  assert.ok(Math.abs(dx) > 3 * Math.abs(dy), `a horizontal drag in the top view is along X (${dx}, ${dy})`);
  await page.getByRole('button', { name: 'Iso' }).click();
  await measure.click();

  // The plot cursor places the tool: its time is set, and the in-process stock differs from the final.
  await page.locator('#force-plot').scrollIntoViewIfNeeded();
  const ov = await page.locator('#force-plot .u-over').boundingBox();
  await page.mouse.move(ov.x + ov.width * 0.3, ov.y + ov.height / 2);
  await page.waitForFunction(() => document.getElementById('view3d').dataset.time > 0);
  await canvas.scrollIntoViewIfNeeded();
  await page.waitForTimeout(100);
  await shot(page, 'run-page-3d-cursor');
  await page.selectOption('#path-colour', 'continuous');
  assert.match(await page.locator('#path-legend').innerText(), /120 %/);
  assert.deepEqual(errors, []);
  await page.context().close();
});

// Contrast ratio of two #rrggbb colours (WCAG 2).
function contrast(a, b) {
  const lum = (hex) => {
    const c = [1, 3, 5].map((i) => parseInt(hex.slice(i, i + 2), 16) / 255).map((v) => (v <= 0.04045 ? v / 12.92 : ((v + 0.055) / 1.055) ** 2.4));
    return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
  };
  const [x, y] = [lum(a), lum(b)].sort((p, q) => q - p);
  return (x + 0.05) / (y + 0.05);
}

test('an honest plot: limits in view, bucket values under the cursor, labels apart, shading under the axes, 3:1 colours with dashes', { skip: !dataFile('demo_dryrun.csv') }, async () => {
  const { page, errors } = await runPage(1400, headroom.id);
  // Every peak under its limit, yet each limit line is in view, with headroom above the data.
  assert.ok(headroom.summary.peak_force_N < 2000);
  await page.locator('#show-torque_Nm').check();
  await page.locator('#show-power_kW').check();
  await page.waitForFunction(() => JSON.parse(document.getElementById('force-plot').dataset.limitLabels || '[]').length === 3);
  const labels = JSON.parse(await page.locator('#force-plot').getAttribute('data-limit-labels'));
  const bbox = await page.locator('#force-plot .u-over').evaluate((el) => ({ h: el.clientHeight }));
  for (const l of labels) assert.ok(l.line >= 0 && l.line <= bbox.h + 60, `${l.text} in view`);
  const ys = labels.map((l) => l.y).sort((p, q) => p - q);
  for (let i = 1; i < ys.length; i++) assert.ok(ys[i] - ys[i - 1] >= 14, `limit labels apart: ${JSON.stringify(labels)}`);
  await shot(page, 'plot-limits-headroom-1400', { docs: true });
  await page.context().close();

  // The demo: under the cursor the legend gives each channel's bucket (min to max) from the data;
  // |F| is at least as large as any single axis in the same bucket, and no value is missing.
  const demoPage = await runPage(1400);
  const p = demoPage.page;
  await p.locator('#force-plot').scrollIntoViewIfNeeded();
  const over = await p.locator('#force-plot .u-over').boundingBox();
  let checked = 0;
  for (let k = 1; k < 24; k++) {
    await p.mouse.move(over.x + (over.width * k) / 24, over.y + over.height / 2);
    await p.evaluate(() => new Promise((r) => requestAnimationFrame(() => setTimeout(r, 0))));
    const values = await p.locator('#force-plot .u-legend .u-series').evaluateAll((rows) => rows.map((r) => [r.querySelector('.u-label')?.textContent, r.querySelector('.u-value')?.textContent]));
    const get = (label) => values.find(([l]) => l && l.startsWith(label))?.[1];
    const F = get('F actual') || get('F (resultant)');
    assert.ok(F && F !== '–', `a resultant value at position ${k}: ${JSON.stringify(values)}`);
    const nums = (s) => s.replace(/,/g, '').match(/-?[\d.]+(e[-+]?\d+)?/g).map(Number);
    const fmax = Math.max(...nums(F).slice(0, 2));
    for (const axis of ['Fx', 'Fy', 'Fz']) {
      const v = get(axis);
      assert.ok(v && v !== '–', `${axis} at position ${k}`);
      const amax = Math.max(...nums(v).slice(0, 2).map(Math.abs));
      assert.ok(amax <= fmax * 1.001 + 0.05, `${axis} ${v} above the resultant ${F} at position ${k}`);
    }
    checked += 1;
  }
  assert.equal(checked, 23);

  // Zoomed into a flagged block: the flag shading stays inside the plot area (nothing red over
  // the y axis and its labels).
  const flagged = demo.blocks.find((b) => b.flags.length);
  await p.locator(`#block-table tbody tr[data-block="${flagged.block}"]`).first().click();
  await waitRange(p, flagged.t_start_s, flagged.t_end_s);
  const redLeftOfPlot = await p.locator('#force-plot').evaluate((el) => {
    const c = el.querySelector('canvas');
    const left = Math.floor(el.querySelector('.u-over').offsetLeft * devicePixelRatio) - 2;
    const d = c.getContext('2d').getImageData(0, 0, Math.max(1, left), c.height).data;
    let red = 0;
    for (let i = 0; i < d.length; i += 4) if (d[i] > 150 && d[i + 1] < 90 && d[i + 2] < 90 && d[i + 3] > 0) red += 1;
    return red;
  });
  assert.equal(redLeftOfPlot, 0, 'no flag shading over the y axis');

  // Colours: 3:1 against the white plot for every line, the flag strip and the path classes
  // against the stock; no two series share both colour and dash.
  const palette = await p.evaluate(async () => {
    const plot = await import('/js/force_plot.js');
    const view = await import('/js/view3d.js');
    return { channels: [...plot.CHANNELS, plot.COMMANDED], classes: view.LOAD_CLASSES, stops: view.CONTINUOUS_STOPS };
  });
  for (const c of palette.channels) assert.ok(contrast(c.stroke, '#ffffff') >= 3, `${c.label} ${c.stroke}: ${contrast(c.stroke, '#ffffff').toFixed(2)}:1`);
  const signatures = palette.channels.map((c) => `${JSON.stringify(c.dash || [])}/${c.width}`);
  assert.equal(new Set(signatures).size, signatures.length, `each series has its own dash or width: ${signatures}`);
  for (const c of palette.classes.filter((k) => k.key !== 'air')) assert.ok(contrast(c.colour, '#c8cdd4') >= 3, `${c.label} against the stock`);
  const classSig = palette.classes.map((c) => `${c.dashed}/${c.marker}/${c.key === 'air'}`);
  assert.equal(new Set(classSig.filter((x) => !x.endsWith('true'))).size, classSig.length - 1, 'loaded path classes differ in dash or markers, not only colour');
  for (const s of palette.stops) assert.ok(contrast(s, '#c8cdd4') >= 3, `continuous stop ${s} against the stock`);
  assert.ok(contrast('#b91c1c', '#ffffff') >= 3, 'flag strip');
  await p.locator('#forces-title').scrollIntoViewIfNeeded();
  await p.evaluate(() => window.scrollBy(0, document.getElementById('forces-title').getBoundingClientRect().top - 10));
  await shot(p, 'plot-block-zoomed-1400', { docs: true });
  assert.deepEqual(demoPage.errors, []);
  assert.deepEqual(errors, []);
  await p.context().close();
});

test('alerts without set-up, and the log\'s warnings in plain words', { skip: !dataFile('demo_dryrun.csv') }, async () => {
  const { page, errors } = await runPage(1400);
  const alerts = (await server.api('GET', `alerts?run_id=${demo.id}`)).items;
  assert.equal(alerts.length, 1, 'the run\'s own limits raised one alert with no threshold set up');
  assert.equal(alerts[0].threshold_id, null);
  const row = page.locator('.run-alerts tbody tr').first();
  await row.waitFor();
  assert.match(await row.innerText(), /The run's own limits/);
  assert.match(await row.innerText(), new RegExp(`${alerts[0].block_count} blocks?, first ${alerts[0].blocks[0].block}`));
  const warnings = demo.run.inputs.ingest.warnings;
  assert.ok(warnings.some((w) => w.code === 'stale_repeat'), 'the demo log has a stale repeat');
  const box = page.locator('#log-warnings');
  await box.waitFor();
  const text = await box.innerText();
  assert.match(text, /Repeated position readings were dropped/);
  assert.ok(text.includes(warnings[0].message), 'the server\'s detail (file and line) is shown too');
  // No raw flag or warning names anywhere on the page.
  const body = await page.locator('main').innerText();
  for (const raw of ['rapid_in_material', 'holder_contact', 'force_limit', 'chip_load_limit', 'bending_limit', 'stale_repeat', 'power_limit', 'torque_limit']) {
    assert.ok(!body.includes(raw), `"${raw}" shown raw`);
  }
  assert.deepEqual(errors, []);
  await page.context().close();
});

test('optimization a shop can load: only flagged blocks, never faster, feeds to 50 mm/min, flags cleared, cycle change', { skip: !dataFile('demo_dryrun.csv') }, async () => {
  const { page, errors } = await runPage(1400);
  await page.locator('#optimize').scrollIntoViewIfNeeded();
  await page.getByLabel('Only flagged blocks').check();
  await page.getByLabel('Never raise the feed').check();
  assert.equal(await page.getByLabel('Round feeds to (mm/min)').inputValue(), '50');
  await page.getByRole('button', { name: 'Optimize feeds' }).click();
  await page.locator('#optimize-summary').waitFor({ timeout: 180000 });
  const opt = (await server.api('GET', `runs/${demo.id}/optimizations`)).items[0];
  assert.equal(opt.state, 'done');
  assert.equal(opt.params.only_flagged, true);
  assert.equal(opt.params.never_raise, true);
  assert.equal(opt.params.feed_step_mm_min, 50);
  const flaggedNames = new Set(demo.blocks.filter((b) => b.flags.length).map((b) => b.block));
  // Changed blocks only at first; all of them on request.
  assert.equal(await page.locator('#optimize-table tbody tr:visible').count(), opt.result.changed_blocks);
  await page.getByLabel('Changed blocks only').uncheck();
  const rows = await page.locator('#optimize-table tbody tr').evaluateAll((trs) => trs.map((tr) => ({
    block: tr.dataset.block, changed: tr.dataset.changed === 'true', tinted: tr.classList.contains('changed'), text: tr.innerText,
  })));
  await page.getByLabel('Changed blocks only').check();
  assert.equal(rows.length, opt.result.blocks.length);
  for (const b of opt.result.blocks) {
    const r = rows.find((x) => x.block === b.block);
    const changed = b.recommended_feed_mm_min !== b.programmed_feed_mm_min;
    assert.equal(r.tinted, changed, `${b.block}: only changed rows are tinted`);
    assert.ok(b.recommended_feed_mm_min <= b.programmed_feed_mm_min, `${b.block} not raised`);
    if (changed) {
      assert.equal(b.recommended_feed_mm_min % 50, 0, `${b.block}: ${b.recommended_feed_mm_min} is a multiple of 50`);
      assert.ok(flaggedNames.has(b.block), `${b.block} changed but was not flagged`);
    }
    for (const f of b.flags_cleared) assert.match(r.text, /clears: /, `${b.block} says what it clears (${f})`);
  }
  const summary = await page.locator('#optimize-summary').innerText();
  console.log(summary);
  const change = (100 * (opt.result.cycle_after_s - opt.result.cycle_before_s)) / opt.result.cycle_before_s;
  assert.match(summary, new RegExp(`\\(${change >= 0 ? '\\+' : '−'}${Math.abs(change).toFixed(1)} %\\)`), 'the net cycle change in %');
  await page.locator('#optimize').scrollIntoViewIfNeeded();
  await shot(page, 'run-page-optimize-1400', { docs: true });
  assert.deepEqual(errors, []);
  await page.context().close();
});

test('words: all form errors at once in plain words, a decimal comma hint, required marks, page titles', { skip: !dataFile('demo_dryrun.csv') }, async () => {
  for (const width of WIDTHS) {
    const { page, errors } = await openPage(browser, server);
    await page.setViewportSize({ width, height: 900 });
    if (width === 1400) {
      for (const [hash, want] of [['#/runs', /^Runs – cutload$/], ['#/alerts', /^Alerts – cutload$/], ['#/libraries', /^Libraries – cutload$/]]) {
        await page.goto(`${server.url}/${hash}`);
        await page.waitForFunction((re) => new RegExp(re).test(document.title), want.source);
      }
      await page.goto(`${server.url}/#/runs/${demo.id}`);
      await page.waitForFunction(() => /^Run #\d+ demo pocket \(\d+ flagged\) – cutload$/.test(document.title));
    }
    await page.goto(`${server.url}/#/new`);
    await page.waitForFunction(() => document.title === 'New run – cutload');
    await page.locator('input[name="tool-diameter_mm"]').waitFor();
    assert.ok(await page.locator('.field .req').count() >= 10, 'required fields are marked');
    assert.equal(await page.locator('input[name="tool-diameter_mm"]').getAttribute('aria-required'), 'true');
    await page.locator('input[name="tool-diameter_mm"]').fill('8,5');
    await page.locator('input[name="tool-flutes"]').fill('2.5');
    await page.getByRole('button', { name: 'Upload and compute' }).click();
    const errorOf = (sel) => page.locator(sel).evaluate((el) => document.getElementById(`${el.id}-err`).textContent);
    assert.match(await errorOf('input[name="tool-diameter_mm"]'), /decimal comma: write 8\.5 with a decimal point/);
    assert.match(await errorOf('input[name="tool-flutes"]'), /whole number/);
    assert.match(await errorOf('input[name="tool-helix_deg"]'), /^Required: enter the helix in deg\.$/);
    assert.match(await errorOf('input[name="material-Ktc_N_mm2"]'), /^Required: enter the Ktc in N\/mm²\.$/);
    assert.match(await errorOf('#log-file'), /Required: choose the dry-run log file/);
    const summary = await page.locator('#error-summary').innerText();
    const invalid = await page.locator('[aria-invalid="true"]').count();
    assert.ok(invalid >= 8, `every problem at once (${invalid} fields)`);
    assert.match(summary, new RegExp(`${await page.locator('#error-summary li').count()} fields need attention`));
    assert.match(summary, /Diameter \(mm\): /);
    assert.doesNotMatch(summary, /tool\.|_mm\b|stock\.box/, 'no internal key names');
    await page.locator('#error-summary').scrollIntoViewIfNeeded();
    await shot(page, `form-errors-${width}`, { docs: true });
    assert.deepEqual(errors, []);
    await page.context().close();
  }
});

test('a five-axis run names its machine file, tool length and how the tool stood', { skip: !dataFile('demo3_dryrun.csv') }, async () => {
  const fd = new FormData();
  fd.append('log', new Blob([fs.readFileSync(dataFile('demo3_dryrun.csv'))]), 'demo3_dryrun.csv');
  fd.append('spec', fs.readFileSync(dataFile('demo3_run.json'), 'utf8'));
  fd.append('kinematics', new Blob([fs.readFileSync(dataFile('machines/ac_table_table.json'))]), 'ac_table_table.json');
  fd.append('tool_length_mm', '0');
  const { id } = await server.api('POST', 'runs', fd);
  const run = await waitDone(id);
  assert.equal(run.state, 'done', run.error);
  assert.equal(run.summary.kinematics.fixed_tilt, false);
  assert.equal(run.summary.kinematics.turning, false);
  const { page, errors } = await runPage(1400, id);
  const meta = page.locator('dl.meta');
  assert.match(await meta.innerText(), /Kinematics\s+ac_table_table\.json, tool length 0 mm; tool vertical to the stock/);
  await page.goto(`${server.url}/#/runs/${demo.id}`);
  await page.locator('#block-table tbody tr').first().waitFor({ timeout: 60000 });
  assert.match(await page.locator('dl.meta').innerText(), /Kinematics\s+–/);
  assert.deepEqual(errors, []);
  await page.context().close();
});

test('a 3+2 run (demo 4) names its tilt and tool axis on the Kinematics row', { skip: !dataFile('demo4_dryrun.csv') }, async () => {
  const fd = new FormData();
  fd.append('log', new Blob([fs.readFileSync(dataFile('demo4_dryrun.csv'))]), 'demo4_dryrun.csv');
  fd.append('spec', fs.readFileSync(dataFile('demo4_run.json'), 'utf8'));
  fd.append('kinematics', new Blob([fs.readFileSync(dataFile('machines/ac_table_table.json'))]), 'ac_table_table.json');
  const { id } = await server.api('POST', 'runs', fd);
  const run = await waitDone(id);
  assert.equal(run.state, 'done', run.error);
  assert.equal(run.summary.kinematics.fixed_tilt, true);
  assert.equal(run.summary.kinematics.turning, false);
  const { page, errors } = await runPage(1400, id);
  const text = await page.locator('dl.meta').innerText();
  assert.match(text, /Kinematics\s+ac_table_table\.json, tool length 0 mm; tool tilted 20° from the stock's \+Z, axis \(0, 0\.342, 0\.94\), fixed while it cuts \(3\+2\)/);
  assert.doesNotMatch(text, /e-\d/, 'no float noise');
  assert.deepEqual(errors, []);
  await page.context().close();
});
