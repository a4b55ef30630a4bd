// Internal: engagement and force evaluation, and the removal queued with it, on the backend. The
// backend only queues work: a flushed batch and its removal stay in flight while the walk produces
// the next batch, and their results are read after wait() (docs/force_model.md, "Pipeline").
#pragma once

#include "cutting_law.hpp"
#include "engine/backend.hpp"
#include "engine/batcher.hpp"
#include "force_model/engine_settings.hpp"

#include <vector>

namespace cutload::force_model {

// What the backend is working on: one batch's engagement and the removal queued with it.
struct InFlight {
    kernels::StepBatch steps;
    std::vector<StepMeta> meta;
    std::vector<kernels::StepResult> results;
    TipBounds bounds;
    std::vector<kernels::SweepSegment> segs;
    std::vector<kernels::SweepCall> calls;
    std::vector<kernels::SweepCellResult> sweep_out;
    bool has_batch = false, active = false;
};

class Engagement {
public:
    Engagement(Backend& backend, const ToolGeometry& tool, const LinearEdgeForceLaw& law,
               const EngineSettings& settings, const kernels::GridInfo& grid, EnginePhases& phases);
    Engagement(const Engagement&) = delete;
    Engagement& operator=(const Engagement&) = delete;
    // On an exception the backend may still be writing into the in-flight slot: let it finish
    // before the slot goes away.
    ~Engagement();

    InFlight& in_flight() { return in_flight_; }
    // The tool of the work queued from now on (nothing may be in flight): its holder face and
    // removal tables here, its edge tables in the backend.
    void use_tool(const ToolGeometry& tool, std::size_t slot);
    // Queues the engagement of the batcher's batch over the edge elements [0, element_end) (none
    // when 0: every result is zero) and takes the batch into the in-flight slot.
    void queue_batch(StepBatcher& batcher, const TipBounds& bounds, int element_end);
    // The rays [i0, i1) x [j0, j1) are the next batch's to read and cut (Backend::will_cut).
    void will_cut(int i0, int j0, int i1, int j1) { backend_.will_cut(i0, j0, i1, j1); }
    // Queues the removal calls gathered in the in-flight slot, if any.
    void queue_sweep();
    // Blocks until the backend has finished what is in flight.
    void wait();
    // Empties the slot once its results are applied.
    void release();

private:
    void set_tool_params(const ToolGeometry& tool);

    Backend& backend_;
    EnginePhases& phases_;
    kernels::EngageParams engage_params_;
    kernels::SweepParams sweep_params_;
    InFlight in_flight_;
};

}  // namespace cutload::force_model
