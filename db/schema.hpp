// Private to db: the version of cutload's logical schema, which every backend's migrations reach.
//   1  libraries, runs and their results, thresholds, alerts, webhooks and deliveries, API keys
//   2  api_keys.last_used_at
//   3  run_program (a run's NC program comparison) and optimizations (feed optimization jobs)
//   4  live_runs, live_chunks, live_blocks (live runs, issue 16)
//   5  claim_token and lease_until of the job tables (leases, issue 18)
#pragma once

#include "db/jobs.hpp"

#include <string_view>

namespace cutload::db {

// The table of a job queue, for any backend's SQL text: the queue's name, checked to be a plain
// identifier (queues are constants of the code; the check keeps anything else out of the SQL).
std::string_view job_table(const JobQueue& q);

inline constexpr int kSchemaVersion = 5;

}  // namespace cutload::db
