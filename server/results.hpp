// Internal to server: turning a finished prediction into rows (blocks, series, stock, summary) and
// evaluating thresholds into alerts and webhook deliveries, all inside the caller's transaction.
#pragma once

#include "app/predict_run.hpp"
#include "common.hpp"
#include "db/alerts.hpp"

namespace cutload::server {

struct ProgramResult;

// Returns the number of alerts raised. The run must be 'running'; it becomes 'done'. `program`:
// the commanded prediction and comparison of a run uploaded with an NC program, or null.
// `cancel`, when set before the commit, rolls everything back and throws force_model::Cancelled
// (a cancel while storing leaves nothing half-written).
// `limit_alerts`: flagged blocks raise an alert without a threshold (ServerOptions::limit_alerts).
int store_result(db::Session& s, std::int64_t run_id, const motion_io::MotionModel& motion,
                 const force_model::Prediction& p, const std::string& stock_bytes, const ProgramResult* program,
                 bool limit_alerts = true, const std::atomic<bool>* cancel = nullptr);

// A live run's close (live_runs.cpp): the same rows as store_result, but its alerts were raised
// block by block while it ran (`alerts_raised` of them, none now), `live` goes into the summary
// as "live", and a run closed after a restart has no final stock (stock_bytes null).
int store_live_result(db::Session& s, std::int64_t run_id, const motion_io::MotionModel& motion,
                      const force_model::Prediction& p, const std::string* stock_bytes, int alerts_raised,
                      const json& live);

// A block summary as the blocks API shows it (idx: its place in the run).
json block_summary_json(std::size_t idx, const force_model::BlockSummary& b);

// Evaluates the enabled thresholds (and with limit_alerts the run's own limits) over p's blocks;
// inserts alerts and webhook deliveries in the caller's transaction. Returns how many it raised.
int raise_alerts(db::Session& s, std::int64_t run_id, const force_model::Prediction& p, bool limit_alerts);

// An alert as the API shows it; load_alert: null when unknown.
json alert_json(const db::AlertRecord& a);
json load_alert(db::Session& s, std::int64_t alert_id);

// Metrics a threshold can test, and how to read each from a block summary.
const std::vector<std::string>& threshold_metrics();
const std::vector<std::string>& known_flags();

}  // namespace cutload::server
