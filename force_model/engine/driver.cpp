#include "engine/driver.hpp"
#include "engine/holder_check.hpp"
#include "engine/motion_walk.hpp"
#include "engine/phase_timer.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace cutload::force_model {

namespace {

constexpr std::size_t kMaxReservedRows = std::size_t(1) << 22;
constexpr std::size_t kRowsWatchPiece = 4096;

}  // namespace

Engine::Engine(const motion_io::MotionModel& motion, const RunSpec& spec, const ToolPlan& plan, const PredictOptions& opt,
               const EngineSettings& settings, EngineSetup& setup, EnginePhases& phases)
    : motion_(motion), offset_mm_(spec.offset_mm), angle_step_deg_(spec.resolution.angle_step_deg), options_(opt),
      plan_(plan), tools_(setup.tools), tool_(&setup.tools.at(std::size_t(plan.first_slot()))), slot_(plan.first_slot()),
      phases_(phases), stock_(*setup.stock), backend_(*setup.backend), stock_map_(*setup.stock, setup.fresh_stock),
      removal_path_(setup.stock->grid.cell_mm, tool_->radius_mm, settings.removal_lag_cells * setup.stock->grid.cell_mm,
                    settings.chord_tolerance_cells * setup.stock->grid.cell_mm),
      batcher_(settings, setup.stock->grid.cell_mm),
      engagement_(*setup.backend, *tool_, setup.law, settings, setup.stock->grid, phases),
      queue_before_completing_(settings.queue_before_completing) {
    setup.backend->use_tool(std::size_t(slot_));
    number_ = motion.size() > 0 ? plan.number_at(0) : -1;
    if (motion.size() > 0 && plan.slot_at(0) < 0) slot_ = -1;
    rows_.use_tool(slot_, number_, tool_->shank_diameter_mm);
}

void Engine::run() {
    // Rows kept whole are reserved for the whole run; taken ones need a piece or two
    // (take_rows_as_they_come), and reserving the run's first had set aside up to 500 MB of
    // address space for nothing, which a host with strict overcommit counts.
    if (!take_rows_) rows_.reserve(std::min(expected_rows(motion_, angle_step_deg_), kMaxReservedRows));
    if (motion_.size() < 2) return;
    const auto sessions = session_ranges(motion_);
    checkpointing_ = options_.checkpoint && !window_ && sessions.size() == 1;
    last_checkpoint_t_s_ = motion_.t_s.front();
    // Each session is a separate stretch: batches and pending removal end with it, so nothing is
    // interpolated or swept across the jump to the next one.
    for (const auto& [begin, end] : sessions) {
        // The previous session's rows are all written (its batch and removal completed below).
        if (options_.session_begins) options_.session_begins(begin, end, rows_taken_ + rows_.size());
        for (std::size_t i = std::max(begin, start_sample_); i + 1 < end; ++i) {
            if (window_ && motion_.t_s[i] >= window_->to_s && window_rows_final()) {
                // What is in flight and being gathered lies past the window: nothing of it is kept.
                complete();
                return;
            }
            current_interval_ = i;
            walk_interval(i);
        }
        flush_batch();
        remove_all_pending();
    }
    complete();
}

void Engine::take_rows_as_they_come(RowTaker take) {
    if (watch_rows_) throw std::logic_error("engine: rows are either taken or watched, not both");
    take_rows_ = std::move(take);
    // A piece and the batch that completes past it, not the whole run.
    rows_.reserve(2 * kRowsOutPiece);
}

void Engine::hand_out_rows(std::size_t keep) {
    const std::size_t n = rows_.size();
    if (!take_rows_ || n <= keep) return;
    const std::size_t take = n - keep;
    take_rows_(rows_, take);
    rows_.samples.erase(rows_.samples.begin(), rows_.samples.begin() + std::ptrdiff_t(take));
    rows_.extra.erase(rows_.extra.begin(), rows_.extra.begin() + std::ptrdiff_t(take));
    rows_taken_ += take;
}

void Engine::watch_rows_as_they_come(RowWatcher watch) {
    if (take_rows_) throw std::logic_error("engine: rows are either taken or watched, not both");
    watch_rows_ = std::move(watch);
}

void Engine::show_rows(std::size_t keep) {
    const std::size_t n = rows_.size();
    if (!watch_rows_ || n <= rows_shown_ + keep) return;
    watch_rows_(rows_, rows_shown_, n - keep);
    rows_shown_ = n - keep;
}

void Engine::drain_rows() {
    hand_out_rows(0);
    show_rows(0);
}

void Engine::use_tool(std::int32_t slot, std::int32_t number) {
    // What the old cutter walked is removed with its own shape before the next one cuts.
    flush_batch();
    remove_all_pending();
    if (slot >= 0 && tool_ != &tools_[std::size_t(slot)]) {
        tool_ = &tools_[std::size_t(slot)];
        removal_path_.set_cutter_radius(tool_->radius_mm);
        engagement_.use_tool(*tool_, std::size_t(slot));
    }
    slot_ = slot;
    number_ = number;
    rows_.use_tool(slot, number, tool_->shank_diameter_mm);
}

void Engine::walk(std::size_t from, std::size_t to) {
    for (std::size_t i = from; i + 1 < to; ++i) {
        current_interval_ = i;
        walk_interval(i);
    }
}

void Engine::forget_samples(std::size_t n) {
    current_interval_ -= std::min(n, current_interval_);
    start_sample_ -= std::min(n, start_sample_);
    forgotten_ += n;
}

void Engine::write_checkpoints_from(double t0_s) {
    checkpointing_ = options_.checkpoint && !window_;
    last_checkpoint_t_s_ = t0_s;
}

void Engine::settle() {
    flush_batch();
    complete();
}

void Engine::end_session() {
    flush_batch();
    remove_all_pending();
}

// A row is final once one follows it (the last one may still take a stop's removed volume), and
// rows come in time order within a session.
bool Engine::window_rows_final() const {
    return !rows_.samples.empty() && rows_.samples.back().t_s >= window_->to_s;
}

void Engine::limit_to(const TimeWindow& w) {
    window_ = w;
    replaying_ = true;
    backend_.set_engaging(false);
}

void Engine::walk_interval(std::size_t i) {
    if (!(motion_.t_s[i + 1] - motion_.t_s[i] > 0)) return;
    // The window starts. The batch being gathered is the whole run's, so it is evaluated whole
    // (its rows before from_s are dropped later): the stock each of its steps sees is the one the
    // whole run gave it, the removal lag included.
    // (A step may fall on the interval's end time itself: >= keeps a window starting there whole.)
    if (replaying_ && motion_.t_s[i + 1] >= window_->from_s) {
        replaying_ = false;
        backend_.set_engaging(true);
    }
    check_rows();
    // Rows already written are final (a batch in flight appends its own); the last one may still
    // take a stop's removed volume.
    if (rows_.size() >= kRowsOutPiece) hand_out_rows(1);
    // Small pieces (4096 rows and at most a batch more), so that the watcher reads rows the cache
    // may still hold.
    if (rows_.size() >= rows_shown_ + kRowsWatchPiece) show_rows(1);
    if (const std::int32_t slot = plan_.slot_at(i), number = plan_.number_at(i); slot != slot_ || number != number_)
        use_tool(slot, number);
    if (slot_ < 0) {
        // A tool the run does not have: nothing is guessed (no forces, no removal).
        if (!replaying_) rows_.append_unknown_tool(motion_, i, number_);
        return;
    }
    if (interval_in_air(i)) {
        flush_batch();
        remove_all_pending();
        if (!replaying_) rows_.append_motion_sample(motion_, i, false);
        if (checkpointing_) checkpoint_before(i + 1);
        return;
    }
    const double rpm0 = motion_.spindle_rpm[i], rpm1 = motion_.spindle_rpm[i + 1];
    if (std::abs(rpm0) < 1 || std::abs(rpm1) < 1 || rpm0 * rpm1 < 0) {
        walk_stopped_spindle(i);
        return;
    }
    walk_angle_steps(i);
}

// Nothing is in flight or pending here and the batcher is empty: the walk from `sample` on depends
// on the stock alone (and the motion, the spec and the tools), which is what a resume restores.
void Engine::checkpoint_before(std::size_t sample) {
    const double t_s = motion_.t_s[sample];
    if (sample + 1 >= motion_.size() || t_s - last_checkpoint_t_s_ < options_.checkpoint_every_s) return;
    last_checkpoint_t_s_ = t_s;
    backend_.download(stock_);
    options_.checkpoint(StockCheckpoint{forgotten_ + sample, t_s}, stock_);
}

// Whether the tool and its holder stay clear of the stock over the interval (coarse tile map).
bool Engine::interval_in_air(std::size_t i) {
    const Vec3 p0 = tip_position(motion_, i, offset_mm_), p1 = tip_position(motion_, i + 1, offset_mm_);
    const double h_s = motion_.t_s[i + 1] - motion_.t_s[i];
    const double v_max = std::max(speed_mm_s(motion_, i), speed_mm_s(motion_, i + 1));
    // The Hermite curve can leave the chord by about |v| h / 4 between samples.
    const double slack_mm = 0.05 + 0.25 * v_max * h_s;
    const double reach_mm = tool_->holder_radius_mm + slack_mm;
    const float top = stock_map_.max_top(std::min(p0.x, p1.x) - reach_mm, std::min(p0.y, p1.y) - reach_mm,
                                         std::max(p0.x, p1.x) + reach_mm, std::max(p0.y, p1.y) + reach_mm);
    return top <= std::min(p0.z, p1.z) - slack_mm;
}

// No chip thickness without rotation: the cutter is pushed, not cutting. Flagged when it is in
// material; the stock is still removed so later blocks see the crash's result.
void Engine::walk_stopped_spindle(std::size_t i) {
    flush_batch();
    complete();
    const Vec3 p0 = tip_position(motion_, i, offset_mm_), p1 = tip_position(motion_, i + 1, offset_mm_);
    removal_path_.add(p0);
    removal_path_.add(p1);
    const bool in_material = stock_map_.material_above(p0.x, p0.y, 0, tool_->radius_mm, p0.z + 1e-3) ||
                             stock_map_.material_above(p1.x, p1.y, 0, tool_->radius_mm, p1.z + 1e-3);
    if (!replaying_) rows_.append_motion_sample(motion_, i, in_material);
}

void Engine::walk_angle_steps(std::size_t i) {
    IntervalSteps steps(motion_, i, offset_mm_, angle_step_deg_, tool_->edges.flutes);
    if (steps.empty()) return;
    if (plan_.slot_at(i + 1) != slot_ || plan_.number_at(i + 1) != number_) steps.keep_first_block();
    if (batcher_.size() > 0 && steps.spin() != batcher_.spin()) flush_batch();
    TimeStep s;
    while (steps.next(s)) {
        if (batcher_.ends_before(s)) flush_batch();
        batcher_.add(s, steps.spin());
    }
}

void Engine::flush_batch() {
    const std::size_t n = batcher_.size();
    if (n == 0) return;
    if (replaying_) {
        replay_batch();
        return;
    }
    if (!queue_before_completing_) complete(true);
    steps_ += n;
    const TipBounds b = batcher_.tip_bounds();
    // Elements higher than the highest material under the batch cannot engage: skip them. The tops
    // may not hold the removal of the batch still in flight yet; removal only lowers them, so the
    // count is never too small (an element above all material finds none: the same forces).
    const double R = tool_->radius_mm;
    const double reach_mm = double(stock_map_.max_top(b.x0_mm - R, b.y0_mm - R, b.x1_mm + R, b.y1_mm + R)) - b.z_min_mm;
    const int element_end = tool_->elements_reaching(reach_mm);
    // An edge point lies within R of its tip and reads its cell's ray, or the one across a wall.
    const double near_mm = R + stock_map_.grid().cell_mm;
    if (CellRect under; element_end > 0 && stock_map_.cells_covering(b.x0_mm - near_mm, b.y0_mm - near_mm,
                                                                     b.x1_mm + near_mm, b.y1_mm + near_mm, under))
        engagement_.will_cut(under.i0, under.j0, under.i1, under.j1);
    // This batch is queued before the one in flight is completed, so the device works on it while
    // the host applies the older one's removal to the tops. Its own removal waits for those tops
    // (RemovalPath::take reads them), and the device runs both in the order they were queued:
    // engagement, removal, engagement, removal, as when each batch was queued after the last.
    engagement_.queue_batch(batcher_, b, element_end);
    if (engagement_.two_in_flight()) complete(true);
    removal_path_.add_batch(engagement_.in_flight().steps);
    queue_removal(true);
    write_done_rows();
}

void Engine::replay_batch() {
    complete();
    removal_path_.add_batch(batcher_.steps());
    batcher_.discard();
    queue_removal(true);
}

void Engine::queue_removal(bool keep_lag) {
    if (removal_path_.empty()) return;
    InFlight& f = engagement_.in_flight();
    {
        PhaseTimer timer(phases_.removal_s);
        removal_path_.take(keep_lag, stock_map_, f.segs, f.calls);
    }
    engagement_.queue_sweep();
}

void Engine::remove_all_pending() {
    complete();
    queue_removal(false);
    complete();
}

void Engine::complete(bool defer_rows) {
    write_done_rows();
    InFlight& f = engagement_.completing();
    if (!f.active) return;
    engagement_.wait();
    Done& d = done_;
    d.removed_mm3 = 0;
    if (!f.calls.empty()) {
        PhaseTimer timer(phases_.removal_s);
        d.removed_mm3 = stock_map_.apply_sweep(f.calls, f.sweep_out.data());
    }
    d.has_batch = f.has_batch;
    if (f.has_batch) {
        // The slot's vectors trade places, so the next batch reuses the capacity of the one before.
        std::swap(d.steps, f.steps);
        std::swap(d.meta, f.meta);
        std::swap(d.results, f.results);
        d.bounds = f.bounds;
    }
    d.waiting = true;
    engagement_.release();
    if (!defer_rows) write_done_rows();
    report_progress();
}

void Engine::write_done_rows() {
    Done& d = done_;
    if (!d.waiting) return;
    d.waiting = false;
    const std::size_t first_row = rows_.size();
    if (d.has_batch) {
        PhaseTimer timer(phases_.rows_s);
        rows_.append_steps(d.meta, d.results, d.removed_mm3);
    } else {
        rows_.attribute_removed(d.removed_mm3);
    }
    const std::size_t batch_rows = rows_.size() - first_row;
    if (batch_rows > 0) {
        PhaseTimer timer(phases_.holder_s);
        // The tile map is the one this batch's removal left: nothing has been applied to it since.
        mark_holder_contact(stock_map_, *tool_, d.steps, d.bounds, rows_.samples.data() + first_row,
                            rows_.extra.data() + first_row);
    }
    d.steps.clear();
    d.meta.clear();
    check_rows();   // the rows' limit counts these too (complete(true) checked before them)
}

// The estimate before a run is an upper bound; this is the net under it should it ever be wrong.
void Engine::check_rows() const {
    const std::size_t rows = rows_taken_ + rows_.size();
    if (options_.max_rows == 0 || rows <= options_.max_rows) return;
    throw TooManyRows(fmt::format("the prediction passed {} force rows at t = {:.3f} s of the motion, above the limit "
                                  "of {:.4g}: it was stopped",
                                  rows, motion_.t_s[current_interval_], double(options_.max_rows)));
}

void Engine::report_progress() {
    if (options_.cancel && options_.cancel->load()) throw Cancelled();
    check_rows();
    if (!options_.progress) return;
    const double f = double(current_interval_ + 1) / double(motion_.size());
    if (f - last_progress_ >= 0.005 || f >= 1.0) {
        last_progress_ = f;
        options_.progress(f);
    }
}

}  // namespace cutload::force_model
