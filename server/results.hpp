// Internal to server: turning a finished prediction into rows (blocks, series, stock, summary) and
// evaluating thresholds into alerts and webhook deliveries, all inside the caller's transaction.
#pragma once

#include "force_model/force_model.hpp"
#include "motion_io/motion_io.hpp"
#include "common.hpp"
#include "db/alerts.hpp"

namespace cutload::server {

struct ProgramResult;

// Returns the number of alerts raised. The run must be 'running'; it becomes 'done'. `program`:
// the commanded prediction and comparison of a run uploaded with an NC program, or null.
int store_result(db::Session& s, std::int64_t run_id, const motion_io::MotionModel& motion,
                 const force_model::Prediction& p, const std::string& stock_bytes, const ProgramResult* program);

// An alert as the API shows it; load_alert: null when unknown.
json alert_json(const db::AlertRecord& a);
json load_alert(db::Session& s, std::int64_t alert_id);

// Metrics a threshold can test, and how to read each from a block summary.
const std::vector<std::string>& threshold_metrics();
const std::vector<std::string>& known_flags();

}  // namespace cutload::server
