// The page shell's routes: a page whose render is still waiting for the server when the user
// moves on must not write over the page that replaced it. Under load (CI's two cores shared with
// the fuzz test) a runs page whose libraries arrived late could replace the run page the user had
// opened (web: measurement waited 30 s for a button of the run page, then failed).
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { skipWithoutChromium, startServer, launchBrowser, openPage, screenshot } from './harness.mjs';

skipWithoutChromium();

let server;
let browser;
let page;
let errors;

before(async () => {
  server = await startServer();
  browser = await launchBrowser();
  ({ page, errors } = await openPage(browser, server));
  await page.getByRole('heading', { name: 'Runs' }).waitFor();
});

after(async () => {
  await browser?.close();
  await server?.stop();
});

test('a runs page whose libraries arrive after the user opened a run leaves the run page in place', async () => {
  const delayMs = 2500;
  // The runs page first loads the libraries (machines, tools, materials), then fills the page.
  // Its requests are held back as a slow server would; the run page's own, made later, pass.
  let hold = true;
  let held = 0;
  let released = null;
  const allReleased = new Promise((resolve) => {
    released = resolve;
  });
  const libraries = /\/api\/v1\/(machines|tools|materials)(\?|$)/;
  await page.route(libraries, async (route) => {
    if (!hold) {
      await route.continue();
      return;
    }
    held += 1;
    await new Promise((r) => setTimeout(r, delayMs));
    await route.continue();
    held -= 1;
    if (held === 0) released();
  });
  await page.evaluate(() => {
    location.hash = '#/alerts';
  });
  await page.getByRole('heading', { name: 'Alerts' }).first().waitFor();
  await page.evaluate(() => {
    location.hash = '#/runs';
  });
  while (held === 0) await new Promise((r) => setTimeout(r, 20));
  hold = false;
  await page.evaluate(() => {
    location.hash = '#/runs/1';
  });
  await page.getByRole('heading', { name: /^Run #1/ }).waitFor();
  await allReleased;
  // Time for the late runs page to render, were it still attached.
  await new Promise((r) => setTimeout(r, 500));
  const headings = await page.locator('main h1').allTextContents();
  console.log(`headings after the late runs page: ${JSON.stringify(headings)}`);
  assert.equal(headings.length, 1, 'one page in main');
  assert.match(headings[0], /^Run #1/);
  await screenshot(page, 'routing-late-runs-page');
  await page.unroute(libraries);
  assert.deepEqual(errors.filter((e) => !/404|does not exist/.test(e)), []);
});
