// Internal: engagement and force evaluation, and the removal queued with it, on the backend. The
// backend only queues work: a flushed batch and its removal stay in flight while the walk produces
// the next batch, and their results are read after wait() (docs/force_model.md, "Pipeline").
// Two slots: the driver queues a batch's engagement before it completes the batch before it, so
// the device has work while the host applies and writes the older one.
#pragma once

#include "cutting_law.hpp"
#include "engine/backend.hpp"
#include "engine/batcher.hpp"
#include "force_model/engine_settings.hpp"

#include <array>
#include <cstdint>
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
    std::uint64_t fence = 0;   // Backend::fence() once the slot's last work was queued
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

    // The slot queued last: the removal queued next joins it.
    InFlight& in_flight() { return slots_[newest_]; }
    // The slot wait() waits for and release() empties: the older of two in flight, else the newest.
    InFlight& completing() { return slots_[completing_index()]; }
    bool two_in_flight() const { return slots_[0].active && slots_[1].active; }
    bool any_in_flight() const { return slots_[0].active || slots_[1].active; }
    // The tool of the work queued from now on (nothing may be in flight): its holder face and
    // removal tables here, its edge tables in the backend.
    void use_tool(const ToolGeometry& tool, std::size_t slot);
    // Queues the engagement of the batcher's batch over the edge elements [0, element_end) (none
    // when 0: every result is zero) and takes the batch into a slot of its own (the newest); at
    // most one other may be in flight.
    void queue_batch(StepBatcher& batcher, const TipBounds& bounds, int element_end);
    // The rays [i0, i1) x [j0, j1) are the next batch's to read and cut (Backend::will_cut).
    void will_cut(int i0, int j0, int i1, int j1) { backend_.will_cut(i0, j0, i1, j1); }
    // Queues the removal calls gathered in the newest slot, if any; nothing else may be in flight.
    void queue_sweep();
    // Blocks until the backend has finished the completing slot's work (and what came before it).
    void wait();
    // Empties the completing slot once its results are applied.
    void release();

private:
    void set_tool_params(const ToolGeometry& tool);

    Backend& backend_;
    EnginePhases& phases_;
    kernels::EngageParams engage_params_;
    kernels::SweepParams sweep_params_;
    std::size_t completing_index() const { return slots_[newest_ ^ 1].active ? newest_ ^ 1 : newest_; }

    std::array<InFlight, 2> slots_;
    std::size_t newest_ = 0;
};

}  // namespace cutload::force_model
