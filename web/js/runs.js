// Runs: the list with filters (machine, program, state, flagged, created since/until); rows of
// queued or running runs refresh themselves.
import { api, LIBRARY_KINDS } from './api.js';
import { h, clear, field, when, statusLine, errorText } from './dom.js';

export async function loadLibraries() {
  const lib = {};
  await Promise.all(
    LIBRARY_KINDS.map(async (k) => {
      try {
        lib[k] = await api.library(k);
      } catch {
        lib[k] = [];   // shown as ids; the banner already names an auth problem
      }
    }),
  );
  lib.byId = (kind, id) => lib[kind].find((x) => x.id === id);
  return lib;
}

export function toolLabel(run, lib) {
  const t = run.tool_id && lib.byId('tools', run.tool_id);
  if (t) return t.name;
  const spec = run.inputs?.spec?.tool;
  if (spec) return `${spec.shape} Ø${spec.diameter_mm} ×${spec.flutes}`;
  const table = run.inputs?.spec?.tools;
  return table?.length ? `${table.length} tools (${table.map((t) => `T${t.number}`).join(', ')})` : '–';
}

export function stateBadge(run) {
  const pct = run.state === 'running' ? ` ${Math.round(100 * run.progress)}%` : '';
  return h('span', { class: `state state-${run.state}` }, run.state + pct);
}

function runRow(run, lib) {
  const machine = run.machine_id ? lib.byId('machines', run.machine_id)?.name ?? `#${run.machine_id}` : '–';
  const flagged = run.summary?.flagged_blocks;
  return h(
    'tr',
    { dataset: { runId: run.id }, class: run.flagged ? 'flagged' : null },
    h('td', {}, h('a', { href: `#/runs/${run.id}` }, `#${run.id}`)),
    h('td', {}, run.name || h('span', { class: 'muted' }, run.inputs?.log?.filename || '–')),
    h('td', {}, run.program || '–'),
    h('td', {}, stateBadge(run)),
    h('td', {}, machine),
    h('td', {}, toolLabel(run, lib)),
    h('td', { class: 'num' }, flagged === undefined ? '–' : String(flagged)),
    h('td', {}, when(run.created_at)),
  );
}

export async function renderRuns(main) {
  const lib = await loadLibraries();
  const machine = h('select', { name: 'machine_id' }, h('option', { value: '' }, 'any'),
    lib.machines.map((m) => h('option', { value: m.id }, m.name)));
  const program = h('input', { name: 'program', type: 'search', placeholder: 'exact name' });
  const state = h('select', { name: 'state' }, ['', 'queued', 'running', 'done', 'failed', 'cancelled'].map(
    (s) => h('option', { value: s }, s || 'any')));
  const flagged = h('select', { name: 'flagged' }, h('option', { value: '' }, 'any'),
    h('option', { value: 'true' }, 'flagged'), h('option', { value: 'false' }, 'not flagged'));
  const since = h('input', { name: 'created_since', type: 'date' });
  const until = h('input', { name: 'created_until', type: 'date' });
  const form = h('form', { class: 'filters', 'aria-label': 'Filter runs' },
    field('Machine', machine), field('Program', program), field('State', state), field('Flags', flagged),
    field('Created since', since), field('Created until', until),
    h('div', { class: 'field actions' }, h('button', { type: 'submit' }, 'Apply')));
  const tbody = h('tbody');
  const status = statusLine();
  const more = h('button', { type: 'button', hidden: true }, 'Load more');
  clear(main,
    h('div', { class: 'page-head' }, h('h1', {}, 'Runs'), h('a', { class: 'button', href: '#/new' }, 'New run')),
    form,
    h('table', { class: 'grid', id: 'runs-table' },
      h('caption', { class: 'sr-only' }, 'Runs, newest first'),
      h('thead', {}, h('tr', {}, ['Run', 'Name', 'Program', 'State', 'Machine', 'Tool', 'Flagged blocks', 'Created'].map(
        (c) => h('th', { scope: 'col' }, c)))),
      tbody),
    more, status);

  let cursor = null;
  const filters = () => ({
    machine_id: machine.value, program: program.value.trim(), state: state.value, flagged: flagged.value,
    created_since: since.value ? `${since.value}T00:00:00Z` : '',
    created_until: until.value ? `${until.value}T23:59:59Z` : '',
  });
  async function load(append) {
    status.textContent = 'Loading…';
    try {
      const page = await api.listRuns(filters(), append ? cursor : undefined);
      if (!append) tbody.replaceChildren();
      for (const run of page.items) tbody.append(runRow(run, lib));
      cursor = page.next_cursor;
      more.hidden = !cursor;
      status.textContent = tbody.children.length ? '' : 'No runs match.';
    } catch (e) {
      status.textContent = errorText(e);
    }
  }
  form.addEventListener('submit', (e) => {
    e.preventDefault();
    load(false);
  });
  more.addEventListener('click', () => load(true));
  await load(false);

  // Active runs change state on their own: refresh just those rows.
  const timer = setInterval(async () => {
    for (const tr of tbody.querySelectorAll('tr')) {
      const badge = tr.querySelector('.state');
      if (!badge || !/queued|running/.test(badge.className)) continue;
      try {
        tr.replaceWith(runRow(await api.getRun(Number(tr.dataset.runId)), lib));
      } catch {
        // Deleted meanwhile: keep the row until the next full load.
      }
    }
  }, 1500);
  return () => clearInterval(timer);
}
