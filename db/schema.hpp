// Private to db: the version of cutload's logical schema, which every backend's migrations reach.
//   1  libraries, runs and their results, thresholds, alerts, webhooks and deliveries, API keys
//   2  api_keys.last_used_at
//   3  run_program (a run's NC program comparison) and optimizations (feed optimization jobs)
//   4  live_runs, live_chunks, live_blocks (live runs, issue 16)
#pragma once

namespace cutload::db {

inline constexpr int kSchemaVersion = 4;

}  // namespace cutload::db
