// Internal: the force engine's driver. It walks the motion model session by session; each motion
// interval is air (one row per sample, nothing evaluated), a stopped spindle (no chip: one row, the
// stock still removed) or cutting: time steps gathered into batches, each batch's engagement and
// the lagged removal of the path before it queued on the backend and completed while the walk
// produces the next batch (docs/force_model.md, "Pipeline"). The parts it drives each do one job:
// motion_walk (time steps), batcher (batches), stock_map and removal_path (stock tracking),
// engagement (backend calls), rows and derived (output rows), holder_check. The tool plan says
// which cutter cuts each sample: a tool change completes the work in flight and removes the whole
// pending path with the old cutter before the next one cuts, so each tool cuts what the ones
// before it left.
#pragma once

#include "engine/batcher.hpp"
#include "engine/engagement.hpp"
#include "engine/removal_path.hpp"
#include "engine/rows.hpp"
#include "engine/setup.hpp"
#include "engine/stock_map.hpp"

#include <functional>
#include <optional>

namespace cutload::force_model {

class Engine {
public:
    Engine(const motion_io::MotionModel& motion, const RunSpec& spec, const ToolPlan& plan, const PredictOptions& opt,
           const EngineSettings& settings, EngineSetup& setup, EnginePhases& phases);
    Engine(const Engine&) = delete;
    Engine& operator=(const Engine&) = delete;

    // Walks the whole motion model; every batch and every removal is complete on return.
    void run();

    // Streaming (a live run, force_model/streaming.hpp): the motion model grows between calls.
    // walk(from, to) walks the intervals between samples from .. to - 1 (one session); settle()
    // flushes the batch being gathered and completes it, so every row so far is final, the stock
    // lag kept; end_session() also removes the whole pending path (the next samples start a new
    // session).
    void walk(std::size_t from, std::size_t to);
    void settle();
    void end_session();
    // A motion model that drops the samples it has walked (StreamingPrediction's whole-log pace):
    // its first `n` samples are gone, so every index from now on is n lower. Checkpoints keep
    // counting from the log's first sample.
    void forget_samples(std::size_t n);
    // Checkpoints (PredictOptions::checkpoint) as run() writes them for a motion of one session,
    // from a walk by walk(): the caller knows the log has one session. `t0_s`: its first sample.
    void write_checkpoints_from(double t0_s);

    // Rows taken out as they become final (PredictOptions::rows_out): whenever the table holds a
    // piece's worth, `take(rows, n)` gets its first n rows, which the engine then drops; the last
    // row always stays (the volume of a stop's path is booked onto it). drain_rows() takes what is
    // left once every batch is complete.
    using RowTaker = std::function<void(const RowTable& rows, std::size_t n)>;
    void take_rows_as_they_come(RowTaker take);   // not with a watcher (below)
    // Or the rows stay in the table and `watch(rows, first, end)` sees [first, end) once they are
    // final, in pieces of at least 4096 rows during the walk (while the device works on the batch
    // in flight) rather than all at the end. Not with a taker, which drops rows from the table.
    using RowWatcher = std::function<void(const RowTable& rows, std::size_t first, std::size_t end)>;
    void watch_rows_as_they_come(RowWatcher watch);
    // The rows left over to the taker or the watcher, once every batch is complete.
    void drain_rows();

    // Walks a window (PredictOptions::window): before it, every interval as the whole run walks
    // it (the same batches, the same removal path and lag) but with no engagement evaluated and
    // no rows; after it, on until a row past to_s is written, so that the window's last batch and
    // the volume booked on its rows are the whole run's, then it stops (the batch then being
    // gathered is dropped). Call before run(). Rows before from_s (the batch the window starts in
    // is evaluated whole) and from to_s on are the caller's to drop.
    void limit_to(const TimeWindow& window);
    // run() starts at this checkpoint (PredictOptions::resume) instead of the log's start: the
    // stock the set-up holds is the checkpoint's. Call before run().
    void resume_at(const StockCheckpoint& at) { start_sample_ = at.sample; }

    RowTable& rows() { return rows_; }
    std::size_t steps() const { return steps_; }   // angle steps evaluated

private:
    void walk_interval(std::size_t i);
    // Makes slot (with T number `number`) the cutter of what follows; slot -1: no cutter.
    void use_tool(std::int32_t slot, std::int32_t number);
    bool interval_in_air(std::size_t i);
    void walk_stopped_spindle(std::size_t i);
    void walk_angle_steps(std::size_t i);
    // Queues the batch's engagement, completes the batch before it, then queues the removal of the
    // pending path up to the lag behind the new batch.
    void flush_batch();
    void queue_removal(bool keep_lag);
    // Completes what is in flight, then removes the whole pending path (the tool stops or leaves).
    void remove_all_pending();
    // Waits for the batch in flight (the older of two) and applies its results: stock tops, then
    // rows, removed volume and holder checks. With `defer_rows` the rows wait in done_ until
    // write_done_rows(), so that flush_batch can queue the removal after the next batch first and
    // the device works while the host writes them.
    void complete(bool defer_rows = false);
    void write_done_rows();
    void report_progress();
    void check_rows() const;   // TooManyRows past options_.max_rows
    void hand_out_rows(std::size_t keep);
    void show_rows(std::size_t keep);   // to watch_rows_: all but the last `keep` rows not yet shown
    // Before a window: the batch's path joins the pending removal; nothing is evaluated.
    void replay_batch();
    bool window_rows_final() const;   // every row before the window's end is final
    // At a clean point (an interval in air just walked): the stock to PredictOptions::checkpoint
    // when one is due.
    void checkpoint_before(std::size_t sample);

    const motion_io::MotionModel& motion_;
    const double* offset_mm_;   // added to logged positions: tool tip in stock coordinates
    const double angle_step_deg_;
    const PredictOptions& options_;
    const ToolPlan& plan_;
    const std::vector<ToolGeometry>& tools_;
    const ToolGeometry* tool_;   // the cutter in the spindle (the last known one while it is unknown)
    std::int32_t slot_ = 0, number_ = -1;
    EnginePhases& phases_;
    Stock& stock_;
    Backend& backend_;

    StockMap stock_map_;
    RemovalPath removal_path_;
    StepBatcher batcher_;       // the batch being walked
    Engagement engagement_;     // the batch (and removal) queued on the backend
    // A completed batch whose rows are not written yet (complete(true)); nothing else writes rows
    // while it waits, so rows stay in time order and a stop's volume lands on the same row.
    struct Done {
        kernels::StepBatch steps;
        std::vector<StepMeta> meta;
        std::vector<kernels::StepResult> results;
        TipBounds bounds;
        double removed_mm3 = 0;
        bool has_batch = false, waiting = false;
    } done_;
    const bool queue_before_completing_;   // EngineSettings::queue_before_completing
    RowTable rows_;
    RowTaker take_rows_;
    std::size_t rows_taken_ = 0;   // rows handed out and dropped from rows_
    RowWatcher watch_rows_;
    std::size_t rows_shown_ = 0;   // rows_[0, rows_shown_) went to watch_rows_
    std::size_t steps_ = 0;
    std::size_t current_interval_ = 0;   // for progress
    double last_progress_ = -1;

    std::optional<TimeWindow> window_;   // limit_to
    bool replaying_ = false;             // walking the motion before the window
    std::size_t start_sample_ = 0;       // resume_at
    bool checkpointing_ = false;         // run() of one session with PredictOptions::checkpoint
    std::size_t forgotten_ = 0;          // samples dropped from the motion's front (forget_samples)
    double last_checkpoint_t_s_ = 0;
};

}  // namespace cutload::force_model
