// "Worst blocks first": the run's problems ranked by severity, at the top of the run page. A
// collision (a rapid move in material, the holder touching the stock) comes before any load over
// its limit; loads over their limit by how far over; then blocks close to a limit (90 % or more).
// Each line says block, tool, NC text, what, its value against the limit and the margin.
import { h, num } from './dom.js';
import { FLAGS, QUANTITIES, flagLabel } from './labels.js';

const NEAR_FRACTION = 0.9;

// The highest load / limit of a block over the limited quantities: {quantity, ratio} or null.
export function worstLoad(block, limits) {
  let worst = null;
  for (const [key, q] of Object.entries(QUANTITIES)) {
    const limit = limits[q.limit];
    if (!(limit > 0)) continue;
    const ratio = block[q.peak] / limit;
    if (!worst || ratio > worst.ratio) worst = { quantity: key, ratio, value: block[q.peak], limit };
  }
  return worst;
}

// Problems, worst first: [{block, kind: 'collision'|'over'|'clearance'|'near', rank, ...}].
export function rankProblems(blocks, limits) {
  const out = [];
  for (const b of blocks) {
    const collision = b.flags.find((f) => FLAGS[f.flag]?.collision);
    const load = worstLoad(b, limits);
    const overFlags = b.flags.filter((f) => FLAGS[f.flag]?.quantity);
    const nearMiss = b.flags.find((f) => f.flag === 'holder_near_miss');
    if (collision) {
      out.push({ block: b, kind: 'collision', flag: collision.flag, t_s: collision.t_s, value: collision.value, load, order: [0, b.t_start_s] });
    } else if (overFlags.length) {
      // The flagged quantity furthest over its limit.
      let over = null;
      for (const f of overFlags) {
        const q = QUANTITIES[FLAGS[f.flag].quantity];
        const limit = limits[q.limit];
        const ratio = limit > 0 ? b[q.peak] / limit : 0;
        if (!over || ratio > over.ratio) over = { quantity: FLAGS[f.flag].quantity, ratio, value: b[q.peak], limit };
      }
      out.push({ block: b, kind: 'over', load: over, order: [1, -over.ratio] });
    } else if (nearMiss) {
      // The holder within its clearance shell: after overloads, the nearest first.
      out.push({ block: b, kind: 'clearance', flag: nearMiss.flag, t_s: nearMiss.t_s, value: nearMiss.value, load, order: [1.5, nearMiss.value] });
    } else if (load && load.ratio >= NEAR_FRACTION) {
      out.push({ block: b, kind: 'near', load, order: [2, -load.ratio] });
    }
  }
  out.sort((p, q) => p.order[0] - q.order[0] || p.order[1] - q.order[1]);
  return out;
}

function what(p, limits) {
  if (p.kind === 'collision') {
    if (p.flag === 'rapid_in_material') {
      return [flagLabel(p.flag), `${num(p.value)} mm/min at or above the rapid threshold of ${num(limits.rapid_feed_mm_min || 20000)} mm/min`];
    }
    return [flagLabel(p.flag), `at ${p.t_s.toFixed(3)} s`];
  }
  if (p.kind === 'clearance') {
    return [flagLabel(p.flag), `${num(p.value)} mm from the stock at ${p.t_s.toFixed(3)} s, inside the ${num(limits.holder_clearance_mm)} mm clearance shell`];
  }
  const q = QUANTITIES[p.load.quantity];
  return [`${q.label} ${p.kind === 'over' ? 'over its limit' : 'close to its limit'}`,
    `${num(p.load.value)} ${q.unit} against ${num(p.load.limit)} ${q.unit}`];
}

function margin(p) {
  if (p.kind === 'collision') return 'collision';
  if (p.kind === 'clearance') return `${num(p.value)} mm clearance`;
  const pct = 100 * (p.load.ratio - 1);
  return pct > 0 ? `${num(pct, 2)} % over` : `${num(-pct, 2)} % below`;
}

// The panel; ncText(blockName) gives the block's NC text when a program is attached.
export function problemsPanel(blocks, limits, { ncText, onSelect, max = 8 }) {
  const problems = rankProblems(blocks, limits);
  const hasTool = blocks.some((b) => b.tool !== undefined && b.tool !== null);
  const section = h('section', { class: 'problems', id: 'problems', 'aria-labelledby': 'problems-title' });
  const head = h('h2', { id: 'problems-title' }, 'Worst blocks first');
  if (!problems.length) {
    const anyLimit = Object.values(QUANTITIES).some((q) => limits[q.limit] > 0);
    section.append(head, h('p', { class: 'ok-line', id: 'problems-none' }, anyLimit
      ? 'No block exceeds a limit or comes within 10 % of one, and no collision was found.'
      : 'No collision was found. The run sets no load limits, so loads are not checked.'));
    return { section, problems };
  }
  const counts = {
    collision: problems.filter((p) => p.kind === 'collision').length,
    over: problems.filter((p) => p.kind === 'over').length,
    clearance: problems.filter((p) => p.kind === 'clearance').length,
    near: problems.filter((p) => p.kind === 'near').length,
  };
  const parts = [];
  if (counts.collision) parts.push(`${counts.collision} with a collision`);
  if (counts.over) parts.push(`${counts.over} over a limit`);
  if (counts.clearance) parts.push(`${counts.clearance} with the holder inside its clearance shell`);
  if (counts.near) parts.push(`${counts.near} within 10 % of a limit`);
  const list = h('ol', { class: 'problem-list', id: 'problem-list' });
  let expanded = false;
  const more = h('button', { type: 'button', class: 'link-button', hidden: problems.length <= max }, `Show all ${problems.length}`);
  const render = () => {
    const shown = expanded ? problems : problems.slice(0, max);
    list.replaceChildren(...shown.map((p, i) => {
      const [title, detail] = what(p, limits);
      const nc = ncText?.(p.block.block);
      return h('li', { class: `problem problem-${p.kind}`, dataset: { block: p.block.block, kind: p.kind } },
        h('button', {
          type: 'button',
          class: 'problem-line',
          'aria-label': `${i + 1}. Block ${p.block.block}: ${title}, ${detail}, ${margin(p)}. Show it on the plot, the path and the program.`,
          onclick: () => onSelect(p.block),
        },
        h('span', { class: 'rank' }, String(i + 1)),
        h('span', { class: 'blk' }, p.block.block),
        h('span', { class: 'tool' }, hasTool && p.block.tool != null ? `T${p.block.tool}` : ''),
        h('span', { class: 'what' }, title),
        h('span', { class: 'value' }, detail),
        h('span', { class: `margin margin-${p.kind}` }, margin(p)),
        h('code', { class: 'nc' }, nc ?? '')));
    }));
    more.textContent = expanded ? `Show the worst ${max}` : `Show all ${problems.length}`;
  };
  more.addEventListener('click', () => {
    expanded = !expanded;
    render();
  });
  render();
  section.append(head, h('p', { class: 'problems-summary' }, `${parts.join(', ')}. Click a line to see the block on the plot, the path and the program.`), list, more);
  return { section, problems };
}
