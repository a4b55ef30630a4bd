// The block table: one row per NC block with its peaks and flags, and for a run with an NC program
// the comparison with the commanded motion; sortable by any column (blanks last), flagged rows
// highlighted; a click or Enter on a row selects the block.
import { h, num } from './dom.js';
import { flagLabel } from './labels.js';

// The block's own columns; `when` leaves a column out unless some block has its data.
const COLUMNS = [
  { key: 'block', label: 'Block', text: true, sticky: true },
  { key: 'tool', label: 'Tool', text: true, when: (bs) => bs.some((b) => b.tool !== undefined && b.tool !== null),
    format: (b) => (b.tool == null ? '' : `T${b.tool}`) },
  { key: 'nc_text', label: 'NC text', text: true, nc: true, when: (bs) => bs.some((b) => b.nc_text) },
  { key: 'programmed_feed_mm_min', label: 'F programmed (mm/min)', when: (bs) => bs.some((b) => b.programmed_feed_mm_min != null), blank: true },
  { key: 'spindle_rpm', label: 'S (rpm)', when: (bs) => bs.some((b) => b.spindle_rpm != null), blank: true },
  { key: 't_start_s', label: 'Time (s)', format: (b) => `${b.t_start_s.toFixed(3)}–${b.t_end_s.toFixed(3)}`, title: 'Start and end of the block; sorts by the start' },
  { key: 'peak_force_N', label: 'Peak force (N)' },
  { key: 'mean_force_N', label: 'Mean force (N)' },
  { key: 'peak_torque_Nm', label: 'Peak torque (N·m)' },
  { key: 'peak_power_kW', label: 'Peak power (kW)' },
  { key: 'max_chip_mm', label: 'Max chip (mm)' },
  { key: 'max_bending_MPa', label: 'Bending (MPa)' },
  { key: 'removed_mm3', label: 'Removed (mm³)' },
  { key: 'flags', label: 'Flags', sortValue: (b) => b.flags.length },
];

// Per-block keys of GET /runs/{id}/program shown beside the run's own; blank for blocks it lacks.
export const COMPARISON_COLUMNS = [
  { key: 'max_deviation_mm', label: 'Max deviation (mm)', title: 'Largest distance of the actual path from the programmed one', blank: true },
  { key: 'feed_deficit_pct', label: 'Feed deficit (%)', title: 'Largest shortfall of the actual feed below the programmed feed', blank: true },
  { key: 'commanded_peak_force_N', label: 'Commanded peak F (N)', title: 'Peak resultant predicted from the programmed motion', blank: true },
  { key: 'force_difference_pct', label: 'Difference (%)', title: 'Actual minus commanded peak force, as a percentage of the commanded peak', blank: true },
];

// The run's blocks with the program comparison's values merged in by block name.
// Besides the comparison columns: the programmed feed (not for rapids), the spindle speed and
// the source line of the block (for the NC text).
export function withComparison(blocks, programBlocks) {
  const byName = new Map();
  for (const p of programBlocks) if (!byName.has(p.block)) byName.set(p.block, p);
  return blocks.map((b) => {
    const p = byName.get(b.block);
    const extra = {};
    for (const c of COMPARISON_COLUMNS) extra[c.key] = p ? p[c.key] ?? null : null;
    extra.programmed_feed_mm_min = p && !p.rapid ? p.programmed_feed_mm_min ?? null : null;
    extra.spindle_rpm = p?.spindle_rpm ?? null;
    extra.line = p?.line ?? null;
    return { ...b, ...extra };
  });
}

// Ascending order with blank (null) values after every number in either direction.
function compareValues(va, vb, dir) {
  if (va == null || vb == null) return (va == null) - (vb == null);
  return (typeof va === 'string' ? va.localeCompare(vb, undefined, { numeric: true }) : va - vb) * dir;
}

export class BlockTable {
  // comparison: the blocks carry the COMPARISON_COLUMNS keys (withComparison) and show them.
  // onToolFilter(tool): the tool filter changed ('' for all tools, else the T number as text).
  constructor(container, blocks, { onSelect, comparison = false, onToolFilter = null }) {
    this.blocks = blocks;
    this.columns = [...COLUMNS, ...(comparison ? COMPARISON_COLUMNS : [])].filter((c) => !c.when || c.when(blocks));
    this.onSelect = onSelect;
    this.sort = { key: 't_start_s', dir: 1 };
    this.flaggedOnly = false;
    this.selectedIdx = null;
    this.tbody = h('tbody');
    this.headRow = h('tr');
    const only = h('input', { type: 'checkbox', id: 'flagged-only' });
    only.addEventListener('change', () => {
      this.flaggedOnly = only.checked;
      this.render();
    });
    // A tool filter once the blocks name their tools (runs with tool changes).
    this.tool = '';
    const tools = [...new Set(blocks.map((b) => b.tool).filter((t) => t !== undefined && t !== null))].sort((a, b) => a - b);
    const toolFilter = tools.length ? h('select', { id: 'tool-filter', 'aria-label': 'Tool' },
      h('option', { value: '' }, 'All tools'), tools.map((t) => h('option', { value: String(t) }, `T${t}`))) : null;
    toolFilter?.addEventListener('change', () => {
      this.tool = toolFilter.value;
      this.render();
      onToolFilter?.(this.tool);
    });
    const flagged = blocks.filter((b) => b.flags.length).length;
    this.el = h('section', { class: 'blocks', 'aria-labelledby': 'blocks-title' },
      h('div', { class: 'section-head' },
        h('h2', { id: 'blocks-title' }, `Blocks (${blocks.length}, ${flagged} flagged)`),
        h('label', { class: 'inline' }, only, ' Flagged blocks only'), toolFilter),
      h('div', { class: 'table-scroll' },
        h('table', { class: 'grid block-table', id: 'block-table' },
          h('caption', { class: 'sr-only' }, 'Per-block results; select a row to zoom the plot to that block'),
          h('thead', {}, this.headRow), this.tbody)));
    container.append(this.el);
    this.render();
  }

  sortBy(key) {
    this.sort = { key, dir: this.sort.key === key ? -this.sort.dir : key === 't_start_s' || key === 'block' ? 1 : -1 };
    this.render();
  }

  render() {
    this.headRow.replaceChildren(...this.columns.map((c) => {
      const active = this.sort.key === c.key;
      const arrow = active ? (this.sort.dir > 0 ? ' ▲' : ' ▼') : '';
      return h('th', { scope: 'col', title: c.title, class: c.sticky ? 'sticky' : null, 'aria-sort': active ? (this.sort.dir > 0 ? 'ascending' : 'descending') : 'none' },
        h('button', { type: 'button', class: 'sort', onclick: () => this.sortBy(c.key) }, c.label + arrow));
    }));
    const col = this.columns.find((c) => c.key === this.sort.key);
    const value = col.sortValue || ((b) => b[col.key]);
    const rows = this.blocks.filter((b) => (!this.flaggedOnly || b.flags.length) && (!this.tool || String(b.tool) === this.tool))
      .sort((a, b) => compareValues(value(a), value(b), this.sort.dir) || a.idx - b.idx);
    this.tbody.replaceChildren(...rows.map((b) => this.row(b)));
  }

  row(b) {
    const tr = h('tr', {
      tabindex: 0,
      class: [b.flags.length ? 'flagged' : '', b.idx === this.selectedIdx ? 'selected' : ''].join(' ').trim() || null,
      'aria-selected': b.idx === this.selectedIdx ? 'true' : 'false',
      dataset: { idx: b.idx, block: b.block },
      onclick: () => this.onSelect(b),
      onkeydown: (e) => {
        if (e.key === 'Enter' || e.key === ' ') {
          e.preventDefault();
          this.onSelect(b);
        }
      },
    });
    for (const c of this.columns) {
      if (c.key === 'flags') {
        tr.append(h('td', {}, b.flags.map((f) => h('span', { class: 'flag', title: `${flagLabel(f.flag)}${f.tool != null ? ` (T${f.tool})` : ''} from ${f.t_s.toFixed(4)} s (${num(f.value)})` },
          flagLabel(f.flag, { short: true })))));
      } else if (c.sticky) {
        tr.append(h('th', { scope: 'row', class: 'sticky' }, b[c.key]));
      } else if (c.nc) {
        tr.append(h('td', { class: 'nc', title: b[c.key] || '' }, h('code', {}, b[c.key] || '')));
      } else if (c.text || c.format) {
        tr.append(h('td', { class: c.text ? null : 'num', dataset: { col: c.key } }, c.format ? c.format(b) : b[c.key]));
      } else {
        const v = b[c.key];
        tr.append(h('td', { class: 'num', dataset: { col: c.key } }, c.blank && v == null ? '' : num(v, c.digits || 3)));
      }
    }
    return tr;
  }

  // Scrolls the table's box (not the page) so the row is in view.
  reveal(tr) {
    const box = this.el.querySelector('.table-scroll');
    const b = box.getBoundingClientRect();
    const r = tr.getBoundingClientRect();
    const head = this.headRow.getBoundingClientRect().height;
    if (r.top < b.top + head || r.bottom > b.bottom) box.scrollTop += r.top - b.top - box.clientHeight / 2;
  }

  // Marks the block selected and scrolls its row into view.
  select(idx) {
    this.selectedIdx = idx;
    for (const tr of this.tbody.children) {
      const on = Number(tr.dataset.idx) === idx;
      tr.classList.toggle('selected', on);
      tr.setAttribute('aria-selected', on ? 'true' : 'false');
      if (on) this.reveal(tr);
    }
  }
}
