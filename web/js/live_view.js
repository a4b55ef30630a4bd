// The live part of a run page while the run is live (docs/live.md): a banner with the connection
// state, the lag and the machine time; the resultant force following the machine (the last
// WINDOW_S seconds of machine time); the blocks as they complete, flagged ones highlighted. It
// polls GET /api/v1/live/{id} with the cursors the previous answer gave, so each row and block
// comes once.
import uPlot from '../vendor/uPlot.esm.js';
import { api } from './api.js';
import { h, clear, num } from './dom.js';
import { flagLabel } from './labels.js';

const WINDOW_S = 10;       // machine time the plot shows
const KEEP_POINTS = 20000; // points kept for the plot (older ones dropped)
const POLL_MS = 250;

const CONNECTION_TEXT = {
  connecting: 'Connecting to the machine',
  connected: 'Connected',
  disconnected: 'Connection lost: reconnecting',
  closed: 'Closed',
};

export class LiveView {
  constructor(id) {
    this.id = id;
    this.after = 0;
    this.fromBlock = 0;
    this.t = [];
    this.f = [];
    this.stopped = false;
    this.banner = h('div', { class: 'live-banner', role: 'status', 'aria-live': 'polite' });
    this.plotBox = h('div', { class: 'live-plot' });
    this.blockRows = h('tbody');
    this.el = h('section', { class: 'live', 'aria-label': 'Live run' },
      h('h2', {}, 'Live'),
      this.banner,
      this.plotBox,
      h('h3', {}, 'Blocks completed'),
      h('table', { class: 'live-blocks' },
        h('thead', {}, h('tr', {}, ['Block', 'Time (s)', 'Peak force (N)', 'Mean force (N)', 'Flags'].map((c) => h('th', {}, c)))),
        this.blockRows));
    this.plot = null;
  }

  ensurePlot() {
    if (this.plot) return;
    const width = Math.max(320, this.plotBox.clientWidth || 800);
    this.plot = new uPlot({
      width, height: 260,
      scales: { x: { time: false } },
      axes: [{ label: 'Machine time (s)' }, { label: 'F (N)' }],
      series: [{ label: 't (s)' }, { label: 'F (resultant)', stroke: '#111111', width: 1.4, value: (u, v) => (v == null ? '' : `${num(v, 1)} N`) }],
    }, [[], []], this.plotBox);
  }

  showState(v) {
    const gaps = v.gaps.length ? ` · ${v.gaps.length} gap${v.gaps.length > 1 ? 's' : ''} in the data` : '';
    clear(this.banner,
      h('span', { class: `live-conn live-conn-${v.connection}` }, CONNECTION_TEXT[v.connection] || v.connection),
      h('span', { class: 'live-lag' }, ` · lag ${Math.round(v.lag_ms)} ms`),
      h('span', {}, ` · machine time ${v.machine_t_s.toFixed(1)} s · ${v.rows} force rows · ${v.alerts} alert${v.alerts === 1 ? '' : 's'}${gaps}`));
    this.banner.dataset.connection = v.connection;
  }

  addRows(forces) {
    for (let i = 0; i < forces.t_s.length; i++) {
      this.t.push(forces.t_s[i]);
      this.f.push(forces.force_N[i]);
    }
    if (this.t.length > KEEP_POINTS) {
      this.t.splice(0, this.t.length - KEEP_POINTS);
      this.f.splice(0, this.f.length - KEEP_POINTS);
    }
    if (!this.t.length) return;
    this.ensurePlot();
    const last = this.t[this.t.length - 1];
    this.plot.setData([this.t, this.f], false);
    this.plot.setScale('x', { min: Math.max(this.t[0], last - WINDOW_S), max: last });
  }

  addBlocks(blocks) {
    for (const b of blocks) {
      const flags = b.flags.map((f) => flagLabel(f.flag)).join(', ');
      this.blockRows.append(h('tr', { class: b.flags.length ? 'flagged' : '' },
        h('td', {}, b.block),
        h('td', {}, `${b.t_start_s.toFixed(3)}–${b.t_end_s.toFixed(3)}`),
        h('td', {}, num(b.peak_force_N)),
        h('td', {}, num(b.mean_force_N)),
        h('td', {}, flags)));
    }
  }

  // One poll; returns the live view's answer (state 'closed' once the run is stored).
  async poll() {
    const v = await api.live(this.id, { after: this.after, from_block: this.fromBlock, max_points: 4000 });
    this.after = v.next_after;
    this.fromBlock = v.next_block;
    this.showState(v);
    this.addRows(v.forces);
    this.addBlocks(v.blocks);
    return v;
  }

  dispose() {
    this.stopped = true;
    if (this.plot) this.plot.destroy();
  }
}

export { POLL_MS as LIVE_POLL_MS };
