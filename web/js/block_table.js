// The block table: one row per NC block with its peaks and flags; sortable by any column, flagged
// rows highlighted; a click or Enter on a row selects the block.
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

export class BlockTable {
  constructor(container, blocks, { onSelect }) {
    this.blocks = blocks;
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
    this.headRow.replaceChildren(...COLUMNS.map((c) => {
      const active = this.sort.key === c.key;
      const arrow = active ? (this.sort.dir > 0 ? ' ▲' : ' ▼') : '';
      return h('th', { scope: 'col', 'aria-sort': active ? (this.sort.dir > 0 ? 'ascending' : 'descending') : 'none' },
        h('button', { type: 'button', class: 'sort', onclick: () => this.sortBy(c.key) }, c.label + arrow));
    }));
    const col = COLUMNS.find((c) => c.key === this.sort.key);
    const value = col.sortValue || ((b) => b[col.key]);
    const rows = this.blocks.filter((b) => !this.flaggedOnly || b.flags.length).sort((a, b) => {
      const va = value(a);
      const vb = value(b);
      return (typeof va === 'string' ? va.localeCompare(vb, undefined, { numeric: true }) : va - vb) * this.sort.dir || a.idx - b.idx;
    });
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
    for (const c of COLUMNS) {
      if (c.key === 'flags') {
        tr.append(h('td', {}, b.flags.map((f) => h('span', { class: 'flag', title: `at ${f.t_s.toFixed(4)} s: ${num(f.value)}` }, f.flag))));
      } else {
        tr.append(h('td', { class: c.text ? null : 'num' }, c.text ? b[c.key] : num(b[c.key], c.digits || 3)));
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
