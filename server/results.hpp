// Internal to server: turning a finished prediction into rows (blocks, series, stock, summary) and
// evaluating thresholds into alerts and webhook deliveries, all inside the caller's transaction.
#pragma once

#include "app/predict_run.hpp"
#include "common.hpp"
#include "db/alerts.hpp"
#include "series.hpp"

#include <array>
#include <filesystem>
#include <fstream>
#include <optional>
#include <span>

namespace cutload::server {

struct ProgramResult;

// One row of the forces series (series_channels(Forces) order). `block_of` maps the prediction's
// block indices to the stored block names (identity: empty).
void force_row(const force_model::ForceSample& s, const std::vector<std::int32_t>& block_of, float* row);
// A prediction's rows as the forces series, the same way.
SeriesData force_series(const force_model::Prediction& p, const std::vector<std::int32_t>& block_of = {});

// The stored level a run's forces series starts at: 0 (every row) when the rows it expects fit
// max_raw_rows (0: no limit), else the first envelope level that fits (docs/api.md, "Long runs").
int force_series_first_level(double expected_rows, double max_raw_rows);

// One series' chunks spooled to a file as its builder makes them, copied into the store later
// (replay). The file is removed on destruction.
class ChunkSpool {
public:
    ChunkSpool(std::filesystem::path file, SeriesId series, int first_level = 0);
    ~ChunkSpool();
    ChunkSpool(const ChunkSpool&) = delete;
    ChunkSpool& operator=(const ChunkSpool&) = delete;
    SeriesBuilder& builder() { return builder_; }
    const SeriesBuilder& builder() const { return builder_; }
    void finish();   // after the last row
    void replay(db::RunRepository& runs, std::int64_t run_id) const;
    void remove_file();
    std::uint64_t bytes() const { return bytes_; }

private:
    std::filesystem::path file_;
    std::ofstream out_;
    SeriesBuilder builder_;
    std::uint64_t bytes_ = 0;
};

// A run's forces series built while the engine runs (app::RunInput::rows_out), its chunks spooled
// to a file beside the run's uploads rather than held in memory, and copied into the store by
// store_result in the transaction that marks the run done. The files are removed on destruction.
class ForceSeriesSpool {
public:
    ForceSeriesSpool(std::filesystem::path file, int first_level);
    ForceSeriesSpool(const ForceSeriesSpool&) = delete;
    ForceSeriesSpool& operator=(const ForceSeriesSpool&) = delete;
    void add(std::span<const force_model::ForceSample> rows);
    // A piece of the run's motion (app::RunInput::motion_out), spooled as its motion series: a run
    // whose motion is not kept whole stores it from here. A file of its own ("NAME.motion.spool"
    // beside "NAME.spool"): the motion comes from the engine's thread while the rows come from the
    // rows pipe's.
    void add_motion(const motion_io::MotionModel& piece);
    bool holds_motion() const { return motion_.has_value(); }
    void finish();   // after the last rows and motion
    std::size_t rows() const;
    int first_level() const { return first_level_; }
    std::uint64_t bytes() const { return forces_.bytes() + (motion_ ? motion_->bytes() : 0); }
    void replay(db::RunRepository& runs, std::int64_t run_id) const;
    void remove_file();

private:
    std::filesystem::path file_;
    ChunkSpool forces_;
    std::optional<ChunkSpool> motion_;
    int first_level_;
};

// Returns the number of alerts raised. The run must be 'running'; it becomes 'done'. `program`:
// the commanded prediction and comparison of a run uploaded with an NC program, or null.
// `cancel`, when set before the commit, rolls everything back and throws force_model::Cancelled
// (a cancel while storing leaves nothing half-written).
// `limit_alerts`: flagged blocks raise an alert without a threshold (ServerOptions::limit_alerts).
// `forces`: the forces series built while predicting (p.samples is then empty), else built from p.
// `kinematics`: for a run with a machine definition, what the summary says of the tool's
// orientation (kinematics_summary), else null. `tool_axis`: a turning tool's axis per motion
// sample (app::RunResult::motion_tool_axis), stored as SeriesId::ToolAxis when not empty; it must
// then be as long as `motion` (std::invalid_argument).
int store_result(db::Session& s, std::int64_t run_id, const motion_io::MotionModel& motion,
                 const force_model::Prediction& p, const ProgramResult* program, bool limit_alerts = true, const std::atomic<bool>* cancel = nullptr,
                 ForceSeriesSpool* forces = nullptr, const json* kinematics = nullptr,
                 std::span<const std::array<float, 3>> tool_axis = {});

// A run's summary.kinematics: the tool's axis where it cuts (stock axes), its lean from +Z in
// degrees, whether the engine ran in the tool's frame (a fixed tilt, docs/five_axis.md 2.5), and
// whether the tool turned while it could cut (simultaneous five-axis work on the multi-direction
// stock, section 3.4: then the axis is the log's first and the lean the largest).
json kinematics_summary(const std::array<double, 3>& tool_axis, double tool_lean_deg, bool fixed_tilt, bool turning);

// A live run's close (live_runs.cpp): the same rows as store_result, but its alerts were raised
// block by block while it ran (`alerts_raised` of them, none now), `live` goes into the summary
// as "live", and a run closed after a restart has no final stock (p.final_stock null).
int store_live_result(db::Session& s, std::int64_t run_id, const motion_io::MotionModel& motion,
                      const force_model::Prediction& p, int alerts_raised, const json& live);

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
