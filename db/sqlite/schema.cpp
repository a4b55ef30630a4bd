// cutload's schema in SQLite's dialect, as numbered migrations. A migration is never edited once released: changes
// go into a new entry, so any older database upgrades in place at startup.
#include "schema.hpp"
#include "sqlite/connection.hpp"

#include <fmt/format.h>

#include <array>

namespace cutload::db::sqlite {
namespace {

// Timestamps are ISO 8601 UTC text (see now_iso), so they sort and compare as strings.
constexpr const char* kV1 = R"SQL(
CREATE TABLE machines (
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL UNIQUE,
  body TEXT NOT NULL,              -- JSON: spindle_power_kW, spindle_torque_Nm, max_feed_mm_min
  created_at TEXT NOT NULL,
  updated_at TEXT NOT NULL
);
CREATE TABLE tools (
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL UNIQUE,
  body TEXT NOT NULL,              -- JSON: {"tool": <run spec tool>, "limits": {...}}
  created_at TEXT NOT NULL,
  updated_at TEXT NOT NULL
);
CREATE TABLE materials (
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL UNIQUE,
  body TEXT NOT NULL,              -- JSON: the run spec's material coefficients
  created_at TEXT NOT NULL,
  updated_at TEXT NOT NULL
);

CREATE TABLE runs (
  id INTEGER PRIMARY KEY,
  name TEXT,
  program TEXT,
  machine_id INTEGER REFERENCES machines(id) ON DELETE SET NULL,
  tool_id INTEGER REFERENCES tools(id) ON DELETE SET NULL,
  material_id INTEGER REFERENCES materials(id) ON DELETE SET NULL,
  base_run INTEGER,                -- no foreign key: a finished base may be deleted later
  state TEXT NOT NULL CHECK (state IN ('queued','running','done','failed','cancelled')),
  progress REAL NOT NULL DEFAULT 0,
  error TEXT,
  attempts INTEGER NOT NULL DEFAULT 0,
  upload_dir TEXT NOT NULL,        -- relative to the data dir
  inputs TEXT NOT NULL,            -- JSON: log, resolved spec, ingest report
  summary TEXT,                    -- JSON, set with state 'done' in the same transaction
  block_names TEXT,                -- JSON array: names of the block indices in the series
  flagged INTEGER NOT NULL DEFAULT 0,
  created_at TEXT NOT NULL,
  started_at TEXT,
  finished_at TEXT
);
CREATE INDEX runs_by_state ON runs(state, id);
CREATE INDEX runs_by_created ON runs(created_at);
CREATE INDEX runs_by_machine ON runs(machine_id, id);
CREATE INDEX runs_by_program ON runs(program, id);

CREATE TABLE run_blocks (
  run_id INTEGER NOT NULL REFERENCES runs(id) ON DELETE CASCADE,
  idx INTEGER NOT NULL,
  body TEXT NOT NULL,              -- JSON block summary with flags
  flagged INTEGER NOT NULL,
  PRIMARY KEY (run_id, idx)
) WITHOUT ROWID;

-- Time series (forces, motion) in chunks: level 0 holds raw rows, level L > 0 holds min/max
-- envelopes of 8^L raw rows (server/series.hpp), so any window at any zoom reads a bounded number of chunks.
CREATE TABLE series_chunks (
  run_id INTEGER NOT NULL REFERENCES runs(id) ON DELETE CASCADE,
  series INTEGER NOT NULL,         -- 0 forces, 1 motion
  level INTEGER NOT NULL,
  chunk INTEGER NOT NULL,
  t0_s REAL NOT NULL,
  t1_s REAL NOT NULL,
  n INTEGER NOT NULL,              -- elements in this chunk
  data BLOB NOT NULL
);
CREATE UNIQUE INDEX series_chunks_key ON series_chunks(run_id, series, level, chunk, t0_s, t1_s, n);

CREATE TABLE run_stock (
  run_id INTEGER PRIMARY KEY REFERENCES runs(id) ON DELETE CASCADE,
  data BLOB NOT NULL               -- force_model::save_stock bytes
);

CREATE TABLE thresholds (
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL,
  scope TEXT NOT NULL CHECK (scope IN ('any','machine','tool','material')),
  machine_id INTEGER REFERENCES machines(id) ON DELETE CASCADE,
  tool_id INTEGER REFERENCES tools(id) ON DELETE CASCADE,
  material_id INTEGER REFERENCES materials(id) ON DELETE CASCADE,
  metric TEXT NOT NULL,
  flag TEXT,
  limit_value REAL,
  severity TEXT NOT NULL,
  enabled INTEGER NOT NULL DEFAULT 1,
  created_at TEXT NOT NULL
);

CREATE TABLE alerts (
  id INTEGER PRIMARY KEY,
  run_id INTEGER NOT NULL REFERENCES runs(id) ON DELETE CASCADE,
  threshold_id INTEGER REFERENCES thresholds(id) ON DELETE SET NULL,
  severity TEXT NOT NULL,
  body TEXT NOT NULL,              -- JSON: metric, value, limit, blocks, message
  created_at TEXT NOT NULL,
  acked_at TEXT,
  acked_by TEXT,
  ack_note TEXT
);
CREATE INDEX alerts_by_run ON alerts(run_id);
CREATE INDEX alerts_by_ack ON alerts(acked_at, id);

CREATE TABLE webhooks (
  id INTEGER PRIMARY KEY,
  url TEXT NOT NULL,
  secret TEXT,
  enabled INTEGER NOT NULL DEFAULT 1,
  created_at TEXT NOT NULL
);
CREATE TABLE webhook_deliveries (
  id INTEGER PRIMARY KEY,
  webhook_id INTEGER NOT NULL REFERENCES webhooks(id) ON DELETE CASCADE,
  alert_id INTEGER,
  payload TEXT NOT NULL,
  state TEXT NOT NULL CHECK (state IN ('pending','delivered','failed')),
  attempts INTEGER NOT NULL DEFAULT 0,
  next_attempt_unix REAL NOT NULL,
  created_at TEXT NOT NULL,
  delivered_at TEXT
);
CREATE INDEX deliveries_pending ON webhook_deliveries(state, next_attempt_unix);
CREATE INDEX deliveries_by_hook ON webhook_deliveries(webhook_id, id);
CREATE TABLE webhook_attempts (
  delivery_id INTEGER NOT NULL REFERENCES webhook_deliveries(id) ON DELETE CASCADE,
  attempt INTEGER NOT NULL,
  at TEXT NOT NULL,
  status INTEGER,                  -- HTTP status, NULL when no response
  error TEXT,
  duration_ms REAL NOT NULL,
  PRIMARY KEY (delivery_id, attempt)
) WITHOUT ROWID;

CREATE TABLE api_keys (
  id INTEGER PRIMARY KEY,
  hash TEXT NOT NULL UNIQUE,       -- hex SHA-256 of the whole key; the key itself is never stored
  prefix TEXT NOT NULL,            -- first characters, to tell keys apart in listings
  role TEXT NOT NULL CHECK (role IN ('read','write','admin')),
  name TEXT,
  created_at TEXT NOT NULL,
  revoked_at TEXT
);
)SQL";

// When each key last authenticated a request, for `cutload keys list`; written at most once a
// minute per key so reads stay free of writes.
constexpr const char* kV2 = R"SQL(
ALTER TABLE api_keys ADD COLUMN last_used_at TEXT;
)SQL";

// NC programs (issue 7): a run's commanded-vs-actual comparison (its commanded forces are series 2
// in series_chunks) and feed optimizations, which are jobs like runs.
constexpr const char* kV3 = R"SQL(
CREATE TABLE run_program (
  run_id INTEGER PRIMARY KEY REFERENCES runs(id) ON DELETE CASCADE,
  body TEXT NOT NULL               -- JSON: mapping quality, commanded summary, per-block comparison
);
CREATE TABLE optimizations (
  id INTEGER PRIMARY KEY AUTOINCREMENT,   -- never reused: a job outliving its row must not write into another
  run_id INTEGER NOT NULL REFERENCES runs(id) ON DELETE CASCADE,
  state TEXT NOT NULL CHECK (state IN ('queued','running','done','failed','cancelled')),
  progress REAL NOT NULL DEFAULT 0,
  params TEXT NOT NULL,            -- JSON: target, feed range, basis, max_predictions
  result TEXT,                     -- JSON, set with state 'done' in the same transaction
  program TEXT,                    -- the optimized NC program
  error TEXT,
  attempts INTEGER NOT NULL DEFAULT 0,
  created_at TEXT NOT NULL,
  started_at TEXT,
  finished_at TEXT
);
CREATE INDEX optimizations_by_state ON optimizations(state, id);
CREATE INDEX optimizations_by_run ON optimizations(run_id, id);
)SQL";

// Live runs (issue 16): what the run page follows while the machine runs. The run's results are
// written as any run's when it closes, and these rows go in the same transaction.
constexpr const char* kV4 = R"SQL(
CREATE TABLE live_runs (
  run_id INTEGER PRIMARY KEY REFERENCES runs(id) ON DELETE CASCADE,
  source TEXT NOT NULL,            -- JSON: source address, key map, options
  open INTEGER NOT NULL DEFAULT 1,
  connection TEXT NOT NULL DEFAULT 'connecting',
  lag_ms REAL NOT NULL DEFAULT 0,
  machine_t_s REAL NOT NULL DEFAULT 0,
  rows INTEGER NOT NULL DEFAULT 0,
  gaps TEXT NOT NULL DEFAULT '[]', -- JSON: [{t_s, gap_s, message}]
  block_names TEXT NOT NULL DEFAULT '[]',   -- JSON: names of the block indices in the chunks
  alerts INTEGER NOT NULL DEFAULT 0,
  end_reason TEXT,
  updated_at TEXT NOT NULL
);
CREATE INDEX live_runs_open ON live_runs(open, run_id);
CREATE TABLE live_chunks (
  run_id INTEGER NOT NULL REFERENCES runs(id) ON DELETE CASCADE,
  seq INTEGER NOT NULL,
  t0_s REAL NOT NULL,
  t1_s REAL NOT NULL,
  n INTEGER NOT NULL,
  data BLOB NOT NULL,
  PRIMARY KEY (run_id, seq)
);
CREATE TABLE live_blocks (
  run_id INTEGER NOT NULL REFERENCES runs(id) ON DELETE CASCADE,
  idx INTEGER NOT NULL,
  body TEXT NOT NULL,
  flagged INTEGER NOT NULL,
  PRIMARY KEY (run_id, idx)
);
)SQL";

// Job leases (issue 18): a claim names itself (claim_token) and holds the job until lease_until
// unless renewed, so a job whose worker died is re-queued once its lease ends, and only the claim
// that holds a job stores its results.
constexpr const char* kV5 = R"SQL(
ALTER TABLE runs ADD COLUMN claim_token TEXT;
ALTER TABLE runs ADD COLUMN lease_until TEXT;
ALTER TABLE optimizations ADD COLUMN claim_token TEXT;
ALTER TABLE optimizations ADD COLUMN lease_until TEXT;
)SQL";

constexpr std::array<const char*, 5> kMigrations{kV1, kV2, kV3, kV4, kV5};

int user_version(Connection& c) {
    auto st = c.prepare("PRAGMA user_version");
    st.step();
    return static_cast<int>(st.i64(0));
}

}  // namespace

int migrate(Connection& c) {
    static_assert(kMigrations.size() == kSchemaVersion, "one SQLite migration per schema version");
    ImmediateTransaction tx(c);
    int v = user_version(c);
    if (v > schema_version())
        throw Error(fmt::format("database schema version {} is newer than this cutload ({})", v, schema_version()),
                    Error::Kind::Other);
    for (; v < schema_version(); ++v) c.exec(kMigrations[static_cast<std::size_t>(v)]);
    c.exec(fmt::format("PRAGMA user_version={}", v));
    tx.commit();
    return v;
}

}  // namespace cutload::db::sqlite
