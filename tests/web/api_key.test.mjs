// The API key flow: without a key the page says how to get one; with anonymous loopback reads
// enabled it reads without one; a saved key is kept in localStorage and sent as a Bearer token.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { skipWithoutChromium, startServer, launchBrowser, openPage, screenshot } from './harness.mjs';

skipWithoutChromium();

let browser;
before(async () => {
  browser = await launchBrowser();
});
after(async () => {
  await browser?.close();
});

test('no key on a server that needs one: the banner says so; saving a key fixes it', async () => {
  const server = await startServer();
  try {
    const { page, context, errors } = await openPage(browser, server, { withKey: false });
    const banner = page.locator('#banner');
    await banner.filter({ hasText: 'missing API key' }).waitFor();
    assert.match(await banner.innerText(), /Enter an API key above/);
    await screenshot(page, 'api-key-1-missing');

    const sent = [];
    page.on('request', (r) => {
      if (r.url().includes('/api/v1/runs')) sent.push(r.headers().authorization);
    });
    await page.getByLabel('API key').fill(server.key);
    await page.getByRole('button', { name: 'Save' }).click();
    await page.locator('#runs-table').waitFor();
    await page.locator('.status', { hasText: 'No runs match.' }).waitFor();
    assert.ok(await banner.isHidden());
    assert.ok(sent.includes(`Bearer ${server.key}`), 'the key is sent as a Bearer token');
    assert.equal(await page.evaluate(() => localStorage.getItem('cutload.apiKey')), server.key);

    // A new page of the same origin finds the key again.
    const again = await context.newPage();
    await again.goto(`${server.url}/`);
    assert.equal(await again.getByLabel('API key').inputValue(), server.key);
    await again.locator('.status', { hasText: 'No runs match.' }).waitFor();
    assert.deepEqual(errors, []);
    await context.close();
  } finally {
    await server.stop();
  }
});

test('anonymous loopback reads: the page reads without a key', async () => {
  const server = await startServer({ args: ['--anonymous-loopback-reads'] });
  try {
    const { page, context, errors } = await openPage(browser, server, { withKey: false });
    await page.locator('.status', { hasText: 'No runs match.' }).waitFor();
    await page.getByRole('navigation', { name: 'Main' }).getByRole('link', { name: 'Alerts' }).click();
    await page.locator('.status', { hasText: 'No alerts.' }).waitFor();
    assert.ok(await page.locator('#banner').isHidden());
    assert.equal(await page.locator('#key-state').innerText(), 'no key');
    assert.deepEqual(errors, []);
    await context.close();
  } finally {
    await server.stop();
  }
});
