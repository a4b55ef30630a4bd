// Libraries: create a machine, tool, material and threshold through their forms (a bad value is
// shown by its field), run the demo with them picked from the libraries, then filter and
// acknowledge the alert on the alerts page.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import { skipWithoutChromium, startServer, launchBrowser, openPage, screenshot, dataFile, tempFile, straightCutLog } from './harness.mjs';

skipWithoutChromium();

let server;
let browser;
let page;
let errors;

before(async () => {
  server = await startServer({ workers: 1 });
  browser = await launchBrowser();
  ({ page, errors } = await openPage(browser, server));
});

after(async () => {
  await browser?.close();
  await server?.stop();
});

async function fill(section, values) {
  for (const [label, value] of Object.entries(values)) {
    const control = section.getByLabel(label, { exact: true });
    if (await control.evaluate((el) => el.tagName === 'SELECT')) await control.selectOption({ label: value });
    else await control.fill(value);
  }
}

const demoSpec = () => {
  const p = dataFile('demo_run.json');
  return p ? JSON.parse(fs.readFileSync(p, 'utf8')) : {
    material: { Ktc_N_mm2: 767, Krc_N_mm2: 168.8, Kac_N_mm2: 222, Kte_N_mm: 27.7, Kre_N_mm: 26.6, Kae_N_mm: 0.7 },
    stock: { box_mm: { min: [0, -5, -10], max: [20, 10, 0] } },
    setup: { offset_mm: [0, 0, 0] },
  };
};

test('create library items; a bad value is shown by its field', async () => {
  await page.goto(`${server.url}/#/libraries`);
  const machines = page.locator('#lib-machines');
  await fill(machines, { 'Machine name': 'ROBODRILL', 'Spindle power (kW)': '-3', 'Spindle torque (N·m)': '35', 'Max feed (mm/min)': '30000' });
  await machines.getByRole('button', { name: 'Create' }).click();
  const power = machines.getByLabel('Spindle power (kW)');
  await page.waitForFunction(() => document.querySelector('#lib-machines [aria-invalid="true"]'));
  assert.equal(await power.getAttribute('aria-invalid'), 'true');
  const message = await power.evaluate((el) => document.getElementById(`${el.id}-err`).textContent);
  console.log(`machine form error: ${message}`);
  assert.match(message, /^Spindle power \(kW\): /, 'the server\'s key is said as the field\'s label');
  await screenshot(page, 'libraries-1-bad-machine');
  await power.fill('11');
  await machines.getByRole('button', { name: 'Create' }).click();
  await machines.locator('tbody tr', { hasText: 'ROBODRILL' }).waitFor();

  const tools = page.locator('#lib-tools');
  await fill(tools, { 'Tool name': 'flat D8 z2', Shape: 'flat', 'Diameter (mm)': '8', Flutes: '2', 'Helix (deg)': '30',
    'Flute length (mm)': '20', 'Stick-out (mm)': '30', 'Force limit (N)': '860' });
  await tools.getByRole('button', { name: 'Create' }).click();
  await tools.locator('tbody tr', { hasText: 'flat D8 z2' }).waitFor();

  const m = demoSpec().material;
  const materials = page.locator('#lib-materials');
  await fill(materials, { 'Material name': 'A7075', 'Ktc (N/mm²)': String(m.Ktc_N_mm2), 'Krc (N/mm²)': String(m.Krc_N_mm2),
    'Kac (N/mm²)': String(m.Kac_N_mm2), 'Kte (N/mm)': String(m.Kte_N_mm), 'Kre (N/mm)': String(m.Kre_N_mm), 'Kae (N/mm)': String(m.Kae_N_mm) });
  await materials.getByRole('button', { name: 'Create' }).click();
  await materials.locator('tbody tr', { hasText: 'A7075' }).waitFor();

  // The page lists machines for the threshold's scope: reload to pick up the new one.
  await page.reload();
  const thresholds = page.locator('#lib-thresholds');
  await fill(thresholds, { 'Threshold name': 'force over 300 N', 'Applies to': 'ROBODRILL', Metric: 'Peak force (N)', Limit: '300', Severity: 'critical' });
  await thresholds.getByRole('button', { name: 'Create' }).click();
  await thresholds.locator('tbody tr', { hasText: 'force over 300 N' }).waitFor();
  assert.match(await thresholds.locator('tbody tr').first().innerText(), /machine ROBODRILL/);
  await screenshot(page, 'libraries-2-created');

  const all = await server.api('GET', 'tools');
  assert.deepEqual(all.items.map((t) => [t.name, t.tool.diameter_mm, t.limits.force_N]), [['flat D8 z2', 8, 860]]);
});

test('a run with machine, tool and material from the libraries raises an alert to acknowledge', async () => {
  await page.goto(`${server.url}/#/new`);
  const spec = demoSpec();
  const log = dataFile('demo_dryrun.csv') || tempFile(server, 'cut.csv', straightCutLog({ passes: 3 }));
  await page.setInputFiles('#log-file', log);
  await page.getByLabel('Machine', { exact: true }).selectOption({ label: 'ROBODRILL' });
  await page.getByLabel('Tool', { exact: true }).selectOption({ label: 'flat D8 z2' });
  await page.getByLabel('Material', { exact: true }).selectOption({ label: 'A7075' });
  assert.ok(await page.locator('input[name="tool-diameter_mm"]').isHidden(), 'inline tool fields hide when a library tool is chosen');
  for (const [group, values] of [['stock-box_mm-min', spec.stock.box_mm.min], ['stock-box_mm-max', spec.stock.box_mm.max],
    ['setup-offset_mm', spec.setup?.offset_mm || [0, 0, 0]]]) {
    for (const [i, axis] of ['x', 'y', 'z'].entries()) await page.locator(`input[name="${group}-${axis}"]`).fill(String(values[i]));
  }
  await page.getByRole('button', { name: 'Upload and compute' }).click();
  await page.waitForURL(/#\/runs\/\d+$/);
  const runId = Number(/#\/runs\/(\d+)$/.exec(page.url())[1]);
  const run = await server.api('GET', `runs/${runId}`);
  const machines = await server.api('GET', 'machines');
  assert.equal(run.machine_id, machines.items[0].id);
  assert.equal(run.inputs.spec.limits.force_N, 860, 'the force limit comes from the library tool');
  await page.locator('#block-table').waitFor({ timeout: 60000 });

  await page.getByRole('navigation', { name: 'Main' }).getByRole('link', { name: 'Alerts' }).click();
  await page.getByLabel('Severity').selectOption('critical');
  await page.getByRole('button', { name: 'Apply' }).click();
  const row = page.locator('.alerts-table tbody tr', { hasText: 'force over 300 N' });
  await row.waitFor();
  // The threshold's alert; the run's own limits raise one too (a rapid move in material: critical).
  assert.equal(await page.locator('.alerts-table tbody tr', { hasText: 'force over 300 N' }).count(), 1);
  assert.equal(await page.locator('.alerts-table tbody tr', { hasText: 'The run\'s own limits' }).count(), 1);
  await row.getByRole('button', { name: 'Acknowledge' }).click();
  // The default filter shows open alerts only; once acknowledged the row says so in place.
  await page.locator('.alerts-table tbody tr', { hasText: 'force over 300 N' }).locator('.acked').waitFor();
  await screenshot(page, 'libraries-3-alert-acknowledged');
  // The threshold's alert, beside the one the run's own limits raise (the demo exceeds its force limit).
  const alerts = (await server.api('GET', `alerts?run_id=${runId}`)).items.filter((a) => a.threshold_name === 'force over 300 N');
  assert.equal(alerts.length, 1);
  assert.ok(alerts[0].acked_at);
  assert.deepEqual(errors, []);
});

// The tool form is built from the run-spec schema the service publishes (derived from its parser):
// the cone shapes' keys appear for those shapes only, and one a shape requires is asked for.
test('the tool form follows the published schema: a drill asks for its point angle', async () => {
  await page.goto(`${server.url}/#/libraries`);
  const tools = page.locator('#lib-tools');
  const pointAngle = tools.getByLabel('Point angle (deg)', { exact: true });
  const tipDiameter = tools.getByLabel('Tip diameter (mm)', { exact: true });
  await fill(tools, { Shape: 'flat' });
  assert.equal(await pointAngle.isVisible(), false, 'a flat end mill has no point angle');
  await fill(tools, { Shape: 'chamfer' });
  assert.equal(await pointAngle.isVisible(), true);
  assert.equal(await tipDiameter.isVisible(), true);
  await fill(tools, { 'Tool name': 'drill D6.8', Shape: 'drill', 'Diameter (mm)': '6.8', Flutes: '2', 'Helix (deg)': '30',
    'Flute length (mm)': '40', 'Stick-out (mm)': '55' });
  assert.equal(await tipDiameter.isVisible(), false, 'a drill\'s point is sharp');
  await tools.getByRole('button', { name: 'Create' }).click();
  await page.waitForFunction(() => document.querySelector('#lib-tools [aria-invalid="true"]'));
  const message = await pointAngle.evaluate((el) => document.getElementById(`${el.id}-err`).textContent);
  console.log(`drill without point angle: ${message}`);
  assert.match(message, /point angle/i);
  await fill(tools, { 'Point angle (deg)': '118' });
  await tools.getByRole('button', { name: 'Create' }).click();
  await tools.locator('tbody tr', { hasText: 'drill D6.8' }).waitFor();
  const all = await server.api('GET', 'tools');
  const drill = all.items.find((t) => t.name === 'drill D6.8');
  assert.equal(drill.tool.shape, 'drill');
  assert.equal(drill.tool.point_angle_deg, 118);
  assert.equal(drill.tool.tip_diameter_mm, undefined);
  assert.deepEqual(errors, []);
});
