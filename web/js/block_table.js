// The block table: one row per NC block with its peaks and flags, and for a run with an NC program
// the comparison with the commanded motion; sortable by any column (blanks last), flagged rows
// highlighted; a click or Enter on a row selects the block.
import { h, num } from './dom.js';

const COLUMNS = [
  { key: 'block', label: 'Block', text: true },
  { key: 't_start_s', label: 'Start (s)', digits: 4 },
  { key: 't_end_s', label: 'End (s)', digits: 4 },
  { key: 'peak_force_N', label: 'Peak F (N)' },
  { key: 'mean_force_N', label: 'Mean F (N)' },
  { key: 'peak_torque_Nm', label: 'Torque (N·m)' },
  { key: 'peak_power_kW', label: 'Power (kW)' },
  { key: 'max_chip_mm', label: 'Chip (mm)' },
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
export function withComparison(blocks, programBlocks) {
  const byName = new Map();
  for (const p of programBlocks) if (!byName.has(p.block)) byName.set(p.block, p);
  return blocks.map((b) => {
    const p = byName.get(b.block);
    const extra = {};
    for (const c of COMPARISON_COLUMNS) extra[c.key] = p ? p[c.key] ?? null : null;
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
  constructor(container, blocks, { onSelect, comparison = false }) {
    this.blocks = blocks;
    this.columns = comparison ? [...COLUMNS, ...COMPARISON_COLUMNS] : COLUMNS;
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
    const flagged = blocks.filter((b) => b.flags.length).length;
    this.el = h('section', { class: 'blocks', 'aria-labelledby': 'blocks-title' },
      h('div', { class: 'section-head' },
        h('h2', { id: 'blocks-title' }, `Blocks (${blocks.length}, ${flagged} flagged)`),
        h('label', { class: 'inline' }, only, ' flagged only')),
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
      return h('th', { scope: 'col', title: c.title, 'aria-sort': active ? (this.sort.dir > 0 ? 'ascending' : 'descending') : 'none' },
        h('button', { type: 'button', class: 'sort', onclick: () => this.sortBy(c.key) }, c.label + arrow));
    }));
    const col = this.columns.find((c) => c.key === this.sort.key);
    const value = col.sortValue || ((b) => b[col.key]);
    const rows = this.blocks.filter((b) => !this.flaggedOnly || b.flags.length)
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
        tr.append(h('td', {}, b.flags.map((f) => h('span', { class: 'flag', title: `at ${f.t_s.toFixed(4)} s: ${num(f.value)}` }, f.flag))));
      } else if (c.text) {
        tr.append(h('td', {}, b[c.key]));
      } else {
        const v = b[c.key];
        tr.append(h('td', { class: 'num', dataset: { col: c.key } }, c.blank && v == null ? '' : num(v, c.digits || 3)));
      }
    }
    return tr;
  }

  // Marks the block selected and scrolls its row into view.
  select(idx) {
    this.selectedIdx = idx;
    for (const tr of this.tbody.children) {
      const on = Number(tr.dataset.idx) === idx;
      tr.classList.toggle('selected', on);
      tr.setAttribute('aria-selected', on ? 'true' : 'false');
      if (on) tr.scrollIntoView({ block: 'nearest' });
    }
  }
}
