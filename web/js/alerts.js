// Alerts: raised by thresholds when a run finishes; list, filter and acknowledge. The same table
// appears on a run's page, filtered to that run.
import { api } from './api.js';
import { h, clear, field, when, num, statusLine, errorText } from './dom.js';
import { flagLabel, metricLabel } from './labels.js';

// An alert in plain words, from its fields (the server's message names metrics by key).
export function alertMessage(a) {
  const n = a.block_count ?? a.blocks?.length ?? 0;
  const where = `${n} block${n === 1 ? '' : 's'}${a.blocks?.length ? `, first ${a.blocks[0].block}` : ''}`;
  if (a.threshold_id == null && a.threshold_name === 'run limits') return `Over the run's own limits in ${where}`;
  if (a.metric === 'flag') return `${a.flag && a.flag !== 'any' ? flagLabel(a.flag) : 'A flag'} in ${where}`;
  if (a.metric) return `${metricLabel(a.metric)} reached ${num(a.value)}, over the limit ${num(a.limit)}, in ${where}`;
  return a.message;
}

function ruleName(a) {
  if (a.threshold_id == null && a.threshold_name === 'run limits') return 'The run\'s own limits';
  return a.threshold_name || '–';
}

// onAcked(updated alert): the row is redrawn in place, so it stays visible under an "open" filter.
function ackCell(alert, onAcked) {
  if (alert.acked_at) {
    return h('span', { class: 'acked' }, `acknowledged by ${alert.acked_by || '?'} ${when(alert.acked_at)}`,
      alert.ack_note ? ` – ${alert.ack_note}` : '');
  }
  const note = h('input', { type: 'text', placeholder: 'note (optional)', 'aria-label': `Note for alert ${alert.id}` });
  const err = h('span', { class: 'field-error', role: 'alert' });
  const btn = h('button', { type: 'submit' }, 'Acknowledge');
  return h('form', {
    class: 'ack',
    onsubmit: async (e) => {
      e.preventDefault();
      btn.disabled = true;
      try {
        onAcked(await api.ackAlert(alert.id, note.value.trim()));
      } catch (ex) {
        err.textContent = errorText(ex);
        btn.disabled = false;
      }
    },
  }, note, btn, err);
}

// Fills container with the alerts matching filters; returns a function that reloads them.
export function alertTable(container, filters, { showRun = true } = {}) {
  const tbody = h('tbody');
  const status = statusLine();
  const more = h('button', { type: 'button', hidden: true }, 'Load more');
  let cursor = null;
  const table = h('table', { class: 'grid alerts-table' },
    h('caption', { class: 'sr-only' }, 'Alerts, newest first'),
    h('thead', {}, h('tr', {}, ['Alert', 'Raised', 'Severity', showRun ? 'Run' : null, 'Rule', 'Message', 'Acknowledgement']
      .filter(Boolean).map((c) => h('th', { scope: 'col' }, c)))),
    tbody);
  container.append(table, more, status);

  const row = (a) => {
    const tr = h('tr', { class: `sev-${a.severity}${a.acked_at ? ' is-acked' : ''}`, dataset: { alertId: a.id } });
    tr.append(...rowCells(a, (updated) => tr.replaceWith(row(updated))));
    return tr;
  };
  const rowCells = (a, onAcked) => [
    h('td', {}, `#${a.id}`),
    h('td', {}, when(a.created_at)),
    h('td', {}, h('span', { class: `sev sev-${a.severity}` }, a.severity)),
    showRun ? h('td', {}, h('a', { href: `#/runs/${a.run_id}` }, `#${a.run_id}`), a.run?.name ? ` ${a.run.name}` : '') : null,
    h('td', {}, ruleName(a)),
    h('td', { title: a.message }, alertMessage(a)),
    h('td', {}, ackCell(a, onAcked))].filter(Boolean);

  async function load(append) {
    status.textContent = 'Loading…';
    try {
      const page = await api.alerts(filters(), append ? cursor : undefined);
      if (!append) tbody.replaceChildren();
      tbody.append(...page.items.map(row));
      cursor = page.next_cursor;
      more.hidden = !cursor;
      status.textContent = tbody.children.length ? '' : 'No alerts.';
    } catch (e) {
      status.textContent = errorText(e);
    }
  }
  more.addEventListener('click', () => load(true));
  load(false);
  return () => load(false);
}

export async function renderAlerts(main) {
  const severity = h('select', { name: 'severity' }, ['', 'info', 'warning', 'critical'].map((s) => h('option', { value: s }, s || 'any')));
  const acked = h('select', { name: 'acked' }, h('option', { value: 'false' }, 'open'),
    h('option', { value: 'true' }, 'acknowledged'), h('option', { value: '' }, 'all'));
  const runId = h('input', { name: 'run_id', type: 'text', inputmode: 'numeric', placeholder: 'any' });
  const form = h('form', { class: 'filters', 'aria-label': 'Filter alerts' },
    field('Severity', severity), field('State', acked), field('Run', runId),
    h('div', { class: 'field actions' }, h('button', { type: 'submit' }, 'Apply')));
  const holder = h('div');
  clear(main, h('h1', {}, 'Alerts'), form, holder);
  const reload = alertTable(holder, () => ({ severity: severity.value, acked: acked.value, run_id: runId.value.trim() }));
  form.addEventListener('submit', (e) => {
    e.preventDefault();
    reload();
  });
  return null;
}
