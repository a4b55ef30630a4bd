// The NC listing beside the force plot: the program as uploaded, line by line, with the lines of
// flagged blocks marked; it scrolls to the block under the plot cursor and marks the selected
// one. Without a program it lists the log's blocks in time order instead. Only the rows in view
// are in the DOM, so a program of any length scrolls at once.
import { h } from './dom.js';

const ROW_PX = 19;
const SPARE_ROWS = 12;

export class Listing {
  // rows: [{no, text, block}] (block: the name of the block written on that row, or null);
  // flagged: Set of flagged block names; onSelect(blockName).
  constructor(container, { title, rows, flagged, onSelect, caption }) {
    this.rows = rows;
    this.flagged = flagged;
    this.onSelect = onSelect;
    this.current = null;
    this.selected = null;
    this.rowOf = new Map();
    rows.forEach((r, i) => {
      if (r.block && !this.rowOf.has(r.block)) this.rowOf.set(r.block, i);
    });
    this.spacer = h('div', { class: 'listing-spacer', style: `height: ${rows.length * ROW_PX}px` });
    this.body = h('ol', { class: 'listing-rows', role: 'list' });
    this.scroller = h('div', { class: 'listing-scroll', tabindex: 0, 'aria-label': `${title}; the line of the block under the plot cursor is marked` },
      this.spacer, this.body);
    this.el = h('section', { class: 'listing', id: 'nc-listing', 'aria-labelledby': 'nc-listing-title' },
      h('h3', { id: 'nc-listing-title' }, title),
      caption ? h('p', { class: 'muted listing-caption' }, caption) : null,
      this.scroller);
    container.append(this.el);
    this.scroller.addEventListener('scroll', () => this.renderRows());
    this.renderRows();
  }

  renderRows() {
    const top = this.scroller.scrollTop;
    const height = this.scroller.clientHeight || 400;
    const a = Math.max(0, Math.floor(top / ROW_PX) - SPARE_ROWS);
    const b = Math.min(this.rows.length, Math.ceil((top + height) / ROW_PX) + SPARE_ROWS);
    this.body.style.transform = `translateY(${a * ROW_PX}px)`;
    const items = [];
    for (let i = a; i < b; i++) {
      const r = this.rows[i];
      const cls = ['listing-row'];
      if (r.block && this.flagged.has(r.block)) cls.push('flagged');
      if (r.block && r.block === this.current) cls.push('current');
      if (r.block && r.block === this.selected) cls.push('selected');
      items.push(h('li', {
        class: cls.join(' '),
        dataset: { row: i, block: r.block || '' },
        onclick: r.block ? () => this.onSelect?.(r.block) : null,
      }, h('span', { class: 'no' }, r.no), h('span', { class: 'text' }, r.text || ' ')));
    }
    this.body.replaceChildren(...items);
  }

  // Brings row i into the middle of the box unless it is in view already.
  reveal(i) {
    const y = i * ROW_PX;
    const top = this.scroller.scrollTop;
    const height = this.scroller.clientHeight;
    if (y >= top + ROW_PX && y + 2 * ROW_PX <= top + height) return;
    this.scroller.scrollTop = Math.max(0, y - height / 2);
  }

  // The block under the plot cursor.
  highlight(block) {
    if (block === this.current) return;
    this.current = block;
    this.el.dataset.current = block || '';
    const i = block ? this.rowOf.get(block) : undefined;
    if (i !== undefined) this.reveal(i);
    this.renderRows();
  }

  select(block) {
    this.selected = block;
    this.el.dataset.selected = block || '';
    const i = block ? this.rowOf.get(block) : undefined;
    if (i !== undefined) this.reveal(i);
    this.renderRows();
  }

  textOf(block) {
    const i = this.rowOf.get(block);
    return i === undefined ? null : this.rows[i].text;
  }
}

// Rows of a program's source: its lines, each with the block the comparison places on it.
export function programRows(source, programBlocks) {
  const lines = source.replace(/\r/g, '').split('\n');
  if (lines.length && lines[lines.length - 1] === '') lines.pop();
  const blockAt = new Map();
  for (const b of programBlocks) if (b.line && !blockAt.has(b.line)) blockAt.set(b.line, b.block);
  return lines.map((text, i) => ({ no: String(i + 1), text, block: blockAt.get(i + 1) || null }));
}

// Rows without a program: the log's blocks in time order.
export function blockRows(blocks) {
  return [...blocks].sort((a, b) => a.t_start_s - b.t_start_s)
    .map((b, i) => ({ no: String(i + 1), text: `${b.block}   ${b.t_start_s.toFixed(3)}–${b.t_end_s.toFixed(3)} s`, block: b.block }));
}
