// The page shell: hash routes, the API key field and the banner for authorisation problems.
import { apiKey, setApiKey, onApiError } from './api.js';
import { renderRuns } from './runs.js';
import { renderNewRun } from './new_run.js';
import { renderRun } from './run_page.js';
import { renderAlerts } from './alerts.js';
import { renderLibraries } from './libraries.js';
import { setTitle } from './title.js';

// [hash pattern, nav entry, page title, render]; a page may refine its title once loaded.
const routes = [
  [/^#\/runs\/(\d+)$/, 'runs', (m) => `Run #${m[1]}`, (main, m) => renderRun(main, Number(m[1]))],
  [/^#\/runs$/, 'runs', () => 'Runs', (main) => renderRuns(main)],
  [/^#\/new$/, 'new', () => 'New run', (main) => renderNewRun(main)],
  [/^#\/alerts$/, 'alerts', () => 'Alerts', (main) => renderAlerts(main)],
  [/^#\/libraries$/, 'libraries', () => 'Libraries', (main) => renderLibraries(main)],
];

let cleanup = null;
// Bumped by every route(): a page whose render finishes after another route() has started is
// stale (its awaits were slower than the user's next click).
let generation = 0;

function showBanner(text) {
  const b = document.getElementById('banner');
  b.textContent = text;
  b.hidden = !text;
}

async function route() {
  const hash = location.hash || '#/runs';
  const found = routes.find(([re]) => re.test(hash));
  if (!found) {
    location.hash = '#/runs';
    return;
  }
  const [re, nav, pageTitle, render] = found;
  setTitle(pageTitle(hash.match(re)));
  if (cleanup) cleanup();
  cleanup = null;
  showBanner('');
  for (const a of document.querySelectorAll('[data-nav]')) {
    if (a.dataset.nav === nav) a.setAttribute('aria-current', 'page');
    else a.removeAttribute('aria-current');
  }
  // Each route renders into a container of its own: a page still rendering when the next
  // route() starts (a runs list waiting for its answer when the user opens a run) fills its
  // container, now detached, and is disposed of as soon as its render returns, instead of
  // writing over the page that replaced it.
  const mine = ++generation;
  const main = document.getElementById('main');
  const page = document.createElement('div');
  page.className = 'page';
  main.replaceChildren(page);
  main.focus({ preventScroll: true });
  const dispose = (await render(page, hash.match(re))) || null;
  if (mine !== generation) {
    if (dispose) dispose();
    return;
  }
  cleanup = dispose;
}

function showKeyState() {
  document.getElementById('key-state').textContent = apiKey() ? 'key saved' : 'no key';
}

function setupKeyForm() {
  const form = document.getElementById('key-form');
  const input = document.getElementById('api-key');
  input.value = apiKey();
  showKeyState();
  form.addEventListener('submit', (e) => {
    e.preventDefault();
    setApiKey(input.value.trim());
    showKeyState();
    route();
  });
  document.getElementById('key-clear').addEventListener('click', () => {
    input.value = '';
    setApiKey('');
    showKeyState();
    route();
  });
}

onApiError((e) => {
  if (e.status === 401) showBanner(`${e.message}. Enter an API key above (cutload keys create --role write).`);
  else if (e.status === 403) showBanner(e.message);
});

setupKeyForm();
window.addEventListener('hashchange', route);
route();
