// Public: tuning of the force engine that the run spec does not (yet) carry, where a prediction's
// wall time went, and predict() with both. For benchmarks, studies of the method and tests; the
// defaults are what predict() uses.
#pragma once

#include "force_model/force_model.hpp"

#include <cstddef>

namespace cutload::force_model {

struct EngineSettings {
    // Stock removal trails the engagement test by this much travel, in grid cells (see
    // docs/force_model.md, "Stock lag"): front edge points then sit clearly inside the stock.
    double removal_lag_cells = 4;
    // A batch of time steps ends when the feed direction turns by more than this.
    double batch_turn_deg = 5;
    std::size_t max_batch_steps = 16384;
    // Minimum uncut chip thickness: thinner chips rub rather than cut and carry no edge force. It
    // also keeps sub-micron vertical jitter of a repaired log from switching the whole flat bottom
    // into "cutting" with full edge forces.
    double min_chip_mm = 5e-4;
    // An edge point near a recorded sub-cell wall cuts only when it lies deeper than this past the
    // wall (docs/force_model.md, "Sub-cell walls"). Float round-off only (the kernels' sliver
    // length): anything larger shifts the immersion boundary of every finishing pass along a swept
    // wall by that much.
    double wall_tolerance_mm = 1e-4;
    // The removed path is simplified into chords that stay within this many cells of the tool's
    // positions. The sub-cell walls resolve the swept volume far finer than a cell, so a tool
    // position off its chord by this much shows as material on a later pass along the same wall
    // (a quarter cell left up to 109 N on a re-cut of the demo; a sixteenth, 68 N).
    double chord_tolerance_cells = 1.0 / 16;
    // A batch's engagement is queued before the batch in flight is completed (docs/force_model.md,
    // "Pipeline"). False: each batch is completed before the next is queued, the order the
    // pipeline must give the same rows and stock as (tests/force_model/test_engine_pipeline.cpp).
    bool queue_before_completing = true;
    // OpenCL: edge points over rays whose material lies wholly below them are not looked up
    // (docs/force_model.md, "Lookups skipped"). False: every point is, which must give the same
    // rows (tests/force_model/test_skipped_lookups.cpp).
    bool skip_lookups_below_tops = true;
};

// Where a prediction's wall time went (bench_force prints these). The backend works asynchronously:
// `queue` is the time spent handing it work (for the scalar twins, the work itself), `wait` the time
// the driver blocked on it, which is what the host's own work did not hide.
struct EnginePhases {
    double setup_s = 0;     // tool geometry, stock, backend (buffers, kernels)
    double walk_s = 0;      // motion walk: step times, positions, batching, air checks
    double queue_s = 0;     // backend calls that queue engagement and removal
    double wait_s = 0;      // blocked until the backend finished
    double rows_s = 0;      // step results to rows
    double removal_s = 0;   // pending path, chords, top map and tile updates (host side of removal)
    double holder_s = 0;    // shank and holder contact checks
    double finish_s = 0;    // stock download, block summaries, releasing the backend
    double total_s = 0;
    std::size_t batches = 0, sweeps = 0;   // engagement batches and removal calls queued
};

// Same as predict(), with explicit engine settings; fills `phases` when given.
Prediction predict_with(const motion_io::MotionModel& motion, const RunSpec& spec, const PredictOptions& opt,
                        const EngineSettings& settings, EnginePhases* phases = nullptr);

}  // namespace cutload::force_model
