// Client of cutload's REST API (/api/v1). The API key lives in localStorage and is sent as a
// Bearer token; without one, reads still work where the server allows anonymous loopback reads.

const KEY_STORAGE = 'cutload.apiKey';

export function apiKey() {
  return localStorage.getItem(KEY_STORAGE) || '';
}

export function setApiKey(key) {
  if (key) localStorage.setItem(KEY_STORAGE, key);
  else localStorage.removeItem(KEY_STORAGE);
}

// A rejected request: status, the server's error code and its message naming the problem.
export class ApiError extends Error {
  constructor(status, code, message) {
    super(message);
    this.status = status;
    this.code = code;
  }
}

const listeners = new Set();
// Called with every ApiError, so the shell can say "enter an API key" on 401.
export function onApiError(fn) {
  listeners.add(fn);
}

function buildUrl(path, query) {
  const url = new URL(path.startsWith('/') ? path : `/api/v1/${path}`, location.origin);
  for (const [k, v] of Object.entries(query || {})) {
    if (v !== undefined && v !== null && v !== '') url.searchParams.set(k, String(v));
  }
  return url;
}

// accept: a text type (text/csv, text/plain) answers the body as text; otherwise JSON.
async function request(method, path, { query, json, form, accept, signal } = {}) {
  const headers = {};
  const key = apiKey();
  if (key) headers.Authorization = `Bearer ${key}`;
  if (accept) headers.Accept = accept;
  let body;
  if (json !== undefined) {
    headers['Content-Type'] = 'application/json';
    body = JSON.stringify(json);
  } else if (form) {
    body = form;
  }
  let res;
  try {
    res = await fetch(buildUrl(path, query), { method, headers, body, signal });
  } catch (e) {
    if (e.name === 'AbortError') throw e;
    throw new ApiError(0, 'network', `cannot reach the server: ${e.message}`);
  }
  if (!res.ok) {
    let err = null;
    try {
      err = (await res.json()).error;
    } catch {
      // Not JSON (a proxy's page): the status line is all there is.
    }
    const e = new ApiError(res.status, err?.code || `http_${res.status}`, err?.message || `HTTP ${res.status} ${res.statusText}`);
    for (const fn of listeners) fn(e);
    throw e;
  }
  if (res.status === 204) return null;
  return accept ? res.text() : res.json();
}

// Follows next_cursor until the list is complete (libraries, blocks: small enough to hold).
async function all(path, query, limit) {
  const items = [];
  let cursor;
  do {
    const page = await request('GET', path, { query: { ...query, limit, cursor } });
    items.push(...page.items);
    cursor = page.next_cursor;
  } while (cursor);
  return items;
}

export const LIBRARY_KINDS = ['machines', 'tools', 'materials'];

export const api = {
  health: () => request('GET', '/healthz'),

  listRuns: (filters, cursor) => request('GET', 'runs', { query: { ...filters, cursor, limit: 50 } }),
  getRun: (id, signal) => request('GET', `runs/${id}`, { signal }),
  createRun: (form) => request('POST', 'runs', { form }),
  deleteRun: (id) => request('DELETE', `runs/${id}`),
  cancelRun: (id) => request('POST', `runs/${id}/cancel`),
  // A live run (docs/live.md): state, force rows after `after`, blocks from `from_block`.
  live: (id, query, signal) => request('GET', `live/${id}`, { query, signal }),
  stopLive: (id) => request('POST', `live/${id}/stop`),
  blocks: (id) => all(`runs/${id}/blocks`, {}, 10000),
  // window: {from_s, to_s, max_points}; decimated answers carry min/max per bucket.
  forces: (id, window, signal) => request('GET', `runs/${id}/forces`, { query: window, signal }),
  forcesCsv: (id, window) => request('GET', `runs/${id}/forces`, { query: window, accept: 'text/csv' }),
  motion: (id, window, signal) => request('GET', `runs/${id}/motion`, { query: window, signal }),
  // The final stock as a height field ({max_cells}), for the 3-D view.
  stock: (id, query) => request('GET', `runs/${id}/stock`, { query }),
  // Dynamometer comparison: {report, series}; 404 when no measurement is attached.
  measurement: (id, window, signal) => request('GET', `runs/${id}/measurement`, { query: window, signal }),
  attachMeasurement: (id, form) => request('POST', `runs/${id}/measurement`, { form }),

  // NC program of a run (404 no_program without one): mapping quality, commanded summary, per-block comparison.
  program: (id) => request('GET', `runs/${id}/program`),
  // The commanded-motion resultant, windowed and decimated like forces().
  commandedForces: (id, window, signal) => request('GET', `runs/${id}/forces`,
    { query: { ...window, source: 'commanded', channels: 'f_N' }, signal }),
  createOptimization: (id, params) => request('POST', `runs/${id}/optimizations`, { json: params }),
  optimizations: (id) => request('GET', `runs/${id}/optimizations`).then((r) => r.items),
  optimization: (oid, signal) => request('GET', `optimizations/${oid}`, { signal }),
  cancelOptimization: (oid) => request('POST', `optimizations/${oid}/cancel`),
  // Any API path (as the server's links give them) as text, for downloads that need the key.
  text: (path, accept = 'text/plain') => request('GET', path, { accept }),

  library: (kind) => all(kind, {}, 1000),
  createItem: (kind, body) => request('POST', kind, { json: body }),
  updateItem: (kind, id, body) => request('PUT', `${kind}/${id}`, { json: body }),
  deleteItem: (kind, id) => request('DELETE', `${kind}/${id}`),

  thresholds: () => request('GET', 'thresholds').then((r) => r.items),

  alerts: (filters, cursor) => request('GET', 'alerts', { query: { ...filters, cursor, limit: 100 } }),
  ackAlert: (id, note) => request('POST', `alerts/${id}/ack`, { json: note ? { note } : {} }),
};
