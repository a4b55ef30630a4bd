// Run page timings in headless Chromium (software rendering, as on the development machine and
// in CI), against a real `cutload serve`. Prints medians; asserts nothing.
//
//   node bench/bench_web_run_page.mjs [--build build] [--repeat 5] [--zooms 30] [--orbit-frames 120] [--only-3d]
//
// - first plot: a fresh page load of a run with 10^6 force samples, from navigation start to the
//   first frame painted with the plot drawn (performance.mark 'plot-drawn' + the frame after it);
// - wheel zoom: from the wheel event to the frame painted after the redraw ('plot-paint'), for
//   wheel zooms over the plot of that run;
// - 3-D view: the demo run's final stock and path, from its data arriving to the first frame
//   (data-first-draw-ms) and from the start of its loading once in view (data-load-to-first-draw-ms:
//   three.js and the fetches of stock and path, beside the page's other loads), and orbiting: frames per second over --orbit-frames frames, each a turn
//   of the camera and a render, paced by requestAnimationFrame; with the triangles, lines and
//   draw calls of the first frame (three.js's renderer.info) and the time to build the scene.
//   --only-3d skips the 10^6-sample run.
import { createRequire } from 'node:module';
import { execFileSync, spawn } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');
const args = process.argv.slice(2);
const opt = (name, dflt) => {
  const i = args.indexOf(`--${name}`);
  return i >= 0 ? args[i + 1] : dflt;
};
const build = path.resolve(opt('build', path.join(root, 'build')));
const repeat = Number(opt('repeat', 5));
const zooms = Number(opt('zooms', 30));
const orbitFrames = Number(opt('orbit-frames', 120));
const only3d = args.includes('--only-3d');

const bin = path.join(build, 'cli', 'cutload');
const site = path.join(build, 'web', 'site');
const require = createRequire(path.join(build, 'web', 'package.json'));
const { chromium } = require('playwright-core');

const median = (v) => {
  const s = [...v].sort((a, b) => a - b);
  return s.length ? s[Math.floor(s.length / 2)] : NaN;
};
const fmt = (v) => `median ${median(v).toFixed(1)} ms (n=${v.length}, min ${Math.min(...v).toFixed(1)}, max ${Math.max(...v).toFixed(1)})`;

async function serve() {
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'cutload-bench-web-'));
  const db = path.join(dir, 'b.db');
  const key = execFileSync(bin, ['keys', 'create', '--role', 'admin', '--db', db], { encoding: 'utf8' }).trim().split('\n').at(-1).trim();
  const proc = spawn(bin, ['serve', '--listen', '127.0.0.1:0', '--db', db, '--web', site, '--workers', '1'], { stdio: ['ignore', 'pipe', 'pipe'] });
  const url = await new Promise((resolve, reject) => {
    let out = '';
    proc.stdout.on('data', (d) => {
      out += d;
      const m = /listening on (http:\/\/[\d.]+:\d+)/.exec(out);
      if (m) resolve(m[1]);
    });
    proc.on('exit', (c) => reject(new Error(`cutload serve exited with ${c}`)));
  });
  const api = async (method, p, body) => {
    const res = await fetch(`${url}/api/v1/${p}`, { method, headers: { Authorization: `Bearer ${key}` }, body });
    if (!res.ok) throw new Error(`${method} ${p}: ${res.status} ${await res.text()}`);
    return res.json();
  };
  return { url, key, api, stop: () => { proc.kill('SIGTERM'); fs.rmSync(dir, { recursive: true, force: true }); } };
}

async function submit(server, { fine }) {
  const fd = new FormData();
  fd.append('log', new Blob([fs.readFileSync(path.join(root, 'data', 'demo_dryrun.csv'))]), 'demo_dryrun.csv');
  const spec = JSON.parse(fs.readFileSync(path.join(root, 'data', 'demo_run.json'), 'utf8'));
  if (fine) spec.resolution = { angle_step_deg: 0.8, axial_step_mm: 0.5, grid_mm: 0.5 };
  fd.append('spec', JSON.stringify(spec));
  const { id } = await server.api('POST', 'runs', fd);
  for (;;) {
    const run = await server.api('GET', `runs/${id}`);
    if (run.state === 'done') return run;
    if (run.state !== 'queued' && run.state !== 'running') throw new Error(`run ${id} ${run.state}: ${run.error}`);
    await new Promise((r) => setTimeout(r, 250));
  }
}

const server = await serve();
const browser = await chromium.launch({ executablePath: '/usr/bin/chromium', headless: true,
  args: ['--no-sandbox', '--disable-gpu', '--disable-background-networking', '--disable-component-update', '--disable-sync', '--no-first-run'] });
try {
  const big = only3d ? null : await submit(server, { fine: true });
  const demo = await submit(server, { fine: false });
  console.log(`runs: ${big ? big.summary.samples : '-'} force samples (fine demo), ${demo.summary.samples} (demo); load average ${os.loadavg().map((l) => l.toFixed(2)).join(' ')}`);
  const context = await browser.newContext({ viewport: { width: 1400, height: 900 } });
  await context.addInitScript((k) => localStorage.setItem('cutload.apiKey', k), server.key);

  const firstPlot = [];
  const wheel = [];
  for (let r = 0; r < (big ? repeat : 0); r++) {
    const page = await context.newPage();
    await page.goto(`${server.url}/#/runs/${big.id}`);
    const t = await page.evaluate(() => new Promise((resolve) => {
      const done = () => requestAnimationFrame(() => setTimeout(() => resolve(performance.getEntriesByName('plot-drawn')[0].startTime), 0));
      const check = () => (performance.getEntriesByName('plot-drawn').length ? done() : setTimeout(check, 5));
      check();
    }));
    // Painted: the frame after the mark.
    firstPlot.push(t);
    // The 3-D view loads when scrolled into view; let it settle before timing the plot.
    await page.locator('#path-title').scrollIntoViewIfNeeded();
    await page.locator('#view3d[data-ready="true"]').waitFor({ timeout: 60000 });
    await page.locator('#force-plot').scrollIntoViewIfNeeded();
    await page.locator('#force-plot .u-over').waitFor();
    const box = await page.locator('#force-plot .u-over').boundingBox();
    await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
    await page.evaluate(() => performance.clearMeasures('plot-paint'));
    for (let i = 0; i < zooms; i++) {
      await page.mouse.wheel(0, i % 3 === 2 ? 240 : -240);
      await page.waitForTimeout(60);
    }
    await page.waitForTimeout(200);
    wheel.push(...await page.evaluate(() => performance.getEntriesByName('plot-paint').map((e) => e.duration)));
    await page.close();
  }
  if (big) {
    console.log(`first plot of ${big.summary.samples} samples, navigation to painted: ${fmt(firstPlot)}`);
    console.log(`wheel zoom to the painted frame: ${fmt(wheel)}`);
  }

  const draws = [];
  const loads = [];
  const builds = [];
  const fps = [];
  let scene = null;
  for (let r = 0; r < repeat; r++) {
    const page = await context.newPage();
    await page.goto(`${server.url}/#/runs/${demo.id}`);
    await page.locator('#path-title').waitFor();
    await page.locator('#path-title').scrollIntoViewIfNeeded();   // the view loads once in view
    await page.locator('#view3d[data-ready="true"]').waitFor({ timeout: 60000 });
    draws.push(Number(await page.locator('#view3d').getAttribute('data-first-draw-ms')));
    builds.push(Number(await page.locator('#view3d').getAttribute('data-build-ms')));
    const loaded = await page.locator('#view3d').getAttribute('data-load-to-first-draw-ms');
    if (loaded != null) loads.push(Number(loaded));
    scene = await page.evaluate(() => {
      const view = document.getElementById('view3d').view3d;
      view.render();
      const { render } = view.renderer.info;
      return { triangles: render.triangles, lines: render.lines, points: render.points, calls: render.calls,
        stockTriangles: Number(document.getElementById('view3d').dataset.stockTriangles),
        canvas: `${view.canvas.width}x${view.canvas.height}` };
    });
    await page.locator('#view3d canvas').scrollIntoViewIfNeeded();
    fps.push(await page.evaluate(async (frames) => {
      const view = document.getElementById('view3d').view3d;
      const t0 = performance.now();
      for (let i = 0; i < frames; i++) {
        await new Promise((r) => requestAnimationFrame(r));
        view.orbit(0.03);
        view.render();
      }
      await new Promise((r) => requestAnimationFrame(r));
      return (frames * 1000) / (performance.now() - t0);
    }, orbitFrames));
    await page.close();
  }
  console.log(`3-D view, demo final stock and path, data to first frame: ${fmt(draws)}`);
  console.log(`3-D view, data to scene built: ${fmt(builds)}`);
  if (loads.length) console.log(`3-D view, in view (fetches, three.js) to first frame: ${fmt(loads)}`);
  console.log(`3-D view scene: ${scene.triangles} triangles (stock top ${scene.stockTriangles}), ${scene.lines} line segments, ${scene.points} points, ${scene.calls} draw calls, canvas ${scene.canvas} px`);
  console.log(`3-D view orbit: median ${median(fps).toFixed(1)} frames/s (n=${fps.length}, min ${Math.min(...fps).toFixed(1)}, max ${Math.max(...fps).toFixed(1)})`);
  console.log(`load average after: ${os.loadavg().map((l) => l.toFixed(2)).join(' ')}`);
} finally {
  await browser.close();
  server.stop();
}
