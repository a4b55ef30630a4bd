// Shared by the browser tests: a real `cutload serve` on a random loopback port with a temporary
// database, an admin API key, headless Chromium through playwright-core, screenshots as artifacts.
//
// Environment (set by tests/web/CMakeLists.txt): CUTLOAD_BIN, CUTLOAD_WEB_SITE,
// CUTLOAD_WEB_NODE_DIR (holds node_modules/playwright-core), CUTLOAD_WEB_ARTIFACTS, CUTLOAD_DATA_DIR.
import { spawn, execFileSync } from 'node:child_process';
import { createRequire } from 'node:module';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';

export const CHROMIUM = '/usr/bin/chromium';
export const SKIP_CODE = 77;

export function env(name) {
  const v = process.env[name];
  if (!v) throw new Error(`${name} is not set: run the browser tests through ctest`);
  return v;
}

// CTest counts exit code 77 as skipped (SKIP_RETURN_CODE); only a missing browser skips.
export function skipWithoutChromium() {
  if (!fs.existsSync(CHROMIUM)) {
    console.log(`SKIP: ${CHROMIUM} is not installed (apt-get install chromium)`);
    process.exit(SKIP_CODE);
  }
}

export function dataFile(name) {
  const p = path.join(env('CUTLOAD_DATA_DIR'), name);
  return fs.existsSync(p) ? p : null;
}

function waitForListening(proc, stderr) {
  return new Promise((resolve, reject) => {
    let out = '';
    const timer = setTimeout(() => reject(new Error(`cutload serve did not start within 20 s: ${stderr.join('')}`)), 20000);
    proc.stdout.on('data', (d) => {
      out += d;
      const m = /listening on (http:\/\/[\d.]+:\d+)/.exec(out);
      if (m) {
        clearTimeout(timer);
        resolve(m[1]);
      }
    });
    proc.on('exit', (code) => {
      clearTimeout(timer);
      reject(new Error(`cutload serve exited with ${code}: ${stderr.join('')}`));
    });
  });
}

export async function startServer({ workers = 1, args = [] } = {}) {
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'cutload-web-'));
  const db = path.join(dir, 'cutload.db');
  const bin = env('CUTLOAD_BIN');
  // `keys create` prints the key on its last line.
  const key = execFileSync(bin, ['keys', 'create', '--role', 'admin', '--db', db], { encoding: 'utf8' }).trim().split('\n').at(-1).trim();
  const proc = spawn(bin, ['serve', '--listen', '127.0.0.1:0', '--db', db, '--web', env('CUTLOAD_WEB_SITE'),
    '--workers', String(workers), ...args], { stdio: ['ignore', 'pipe', 'pipe'] });
  const stderr = [];
  proc.stderr.on('data', (d) => {
    stderr.push(String(d));
    if (stderr.length > 200) stderr.shift();
  });
  const url = await waitForListening(proc, stderr);
  const exited = new Promise((resolve) => proc.on('exit', resolve));

  async function api(method, p, body) {
    const headers = { Authorization: `Bearer ${key}` };
    let payload = body;
    if (body !== undefined && !(body instanceof FormData)) {
      headers['Content-Type'] = 'application/json';
      payload = JSON.stringify(body);
    }
    const res = await fetch(`${url}/api/v1/${p}`, { method, headers, body: payload });
    const text = await res.text();
    if (!res.ok) throw new Error(`${method} ${p}: ${res.status} ${text}`);
    return text ? JSON.parse(text) : null;
  }

  return {
    url,
    key,
    dir,
    db,
    api,
    log: () => stderr.join(''),
    async stop() {
      proc.kill('SIGTERM');
      const killer = setTimeout(() => proc.kill('SIGKILL'), 10000);
      await exited;
      clearTimeout(killer);
      fs.rmSync(dir, { recursive: true, force: true });
    },
  };
}

// Polls a run until it is neither queued nor running; returns it.
export async function finishedRun(server, id) {
  let run;
  do {
    await new Promise((r) => setTimeout(r, 200));
    run = await server.api('GET', `runs/${id}`);
  } while (run.state === 'queued' || run.state === 'running');
  return run;
}

export async function launchBrowser() {
  const require = createRequire(path.join(env('CUTLOAD_WEB_NODE_DIR'), 'package.json'));
  const { chromium } = require('playwright-core');
  return chromium.launch({
    executablePath: CHROMIUM,
    headless: true,
    args: ['--no-sandbox', '--disable-gpu', '--disable-background-networking', '--disable-component-update',
      '--disable-sync', '--no-first-run'],
  });
}

// A page at a laptop's size whose console errors fail the test.
export async function openPage(browser, server, { withKey = true } = {}) {
  const context = await browser.newContext({ viewport: { width: 1366, height: 900 }, acceptDownloads: true });
  const page = await context.newPage();
  const errors = [];
  page.on('pageerror', (e) => errors.push(`page error: ${e.message}`));
  page.on('console', (m) => {
    // Rejected API calls are logged by the browser as failed resources; the page shows them itself.
    if (m.type() === 'error' && !/Failed to load resource/.test(m.text())) errors.push(`console: ${m.text()}`);
  });
  await page.goto(`${server.url}/`);
  if (withKey) {
    await page.getByLabel('API key').fill(server.key);
    await page.getByRole('button', { name: 'Save' }).click();
  }
  return { page, context, errors };
}

export async function screenshot(page, name) {
  const dir = env('CUTLOAD_WEB_ARTIFACTS');
  fs.mkdirSync(dir, { recursive: true });
  const file = path.join(dir, `${name}.png`);
  await page.screenshot({ path: file, fullPage: true });
  return file;
}

export function tempFile(server, name, content) {
  const p = path.join(server.dir, name);
  fs.writeFileSync(p, content);
  return p;
}

// A dry-run CSV of straight zigzag cuts along X in the log's column layout: 6 ms client cycle, each
// channel with its own time stamp, block names per cut. Used when data/demo_dryrun.csv is absent
// and for the long run of the performance test.
export function straightCutLog({ passes = 2, length_mm = 40, feed_mm_min = 1200, rpm = 8000, y_step_mm = 3, z_mm = -2 }) {
  const dt = 0.006;
  const lines = ['t_spindle [s],spindle [rpm],t_feed [s],feed [mm/min],t_pos [s],x [mm],y [mm],z [mm],block'];
  let t = 0;
  const v = feed_mm_min / 60;
  for (let p = 0; p < passes; p++) {
    const y = p * y_step_mm;
    const steps = Math.ceil(length_mm / v / dt);
    for (let i = 0; i <= steps; i++) {
      const along = Math.min(length_mm, i * v * dt);
      const x = -10 + (p % 2 ? length_mm - along : along);   // zigzag: no jump back between passes
      lines.push([t.toFixed(6), rpm, (t + 0.002).toFixed(6), feed_mm_min, (t + 0.004).toFixed(6),
        x.toFixed(3), y.toFixed(3), z_mm.toFixed(3), `N${10 * (p + 1)}`].join(','));
      t += dt;
    }
  }
  return `${lines.join('\n')}\n`;
}
