#include "engine/engagement.hpp"
#include "engine/phase_timer.hpp"

#include <exception>
#include <stdexcept>

namespace cutload::force_model {

Engagement::Engagement(Backend& backend, const ToolGeometry& tool, const LinearEdgeForceLaw& law,
                       const EngineSettings& settings, const kernels::GridInfo& grid, EnginePhases& phases)
    : backend_(backend), phases_(phases) {
    set_kernel_law(law, engage_params_);
    engage_params_.wall_tolerance_mm = settings.wall_tolerance_mm;
    engage_params_.skip_lookups_below_tops = settings.skip_lookups_below_tops;
    set_tool_params(tool);
    // An edge point lies within half a cell diagonal of its ray's centre: walls farther than that
    // from the centre cannot change a test. A whole cell keeps a margin.
    sweep_params_.wall_band_mm = grid.cell_mm;
    for (InFlight& f : slots_) {
        f.steps.reserve(settings.max_batch_steps);
        f.meta.reserve(settings.max_batch_steps);
    }
}

void Engagement::set_tool_params(const ToolGeometry& tool) {
    engage_params_.holder_face_z_mm = tool.stickout_mm;
    sweep_params_.lower_mm = tool.lower_mm;
    sweep_params_.radius_mm = tool.radius_mm;
    sweep_params_.cut_length_mm = tool.flute_length_mm;
}

void Engagement::use_tool(const ToolGeometry& tool, std::size_t slot) {
    if (any_in_flight()) throw std::logic_error("engine: a tool change with work in flight");
    set_tool_params(tool);
    backend_.use_tool(slot);
}

Engagement::~Engagement() {
    if (!any_in_flight()) return;
    try {
        backend_.wait();
    } catch (const std::exception&) {   // already unwinding from the first error
    }
}

void Engagement::queue_batch(StepBatcher& batcher, const TipBounds& bounds, int element_end) {
    if (slots_[newest_].active) {
        if (slots_[newest_ ^ 1].active) throw std::logic_error("engine: a third batch queued with two in flight");
        newest_ ^= 1;
    }
    InFlight& f = slots_[newest_];
    f.bounds = bounds;
    engage_params_.element_end = element_end;
    if (element_end > 0) {
        // The engagement writes every step's result whole: only a batch it skips needs zeros.
        f.results.resize(batcher.size());
        ++phases_.batches;
        PhaseTimer timer(phases_.queue_s);
        backend_.engage(batcher.steps(), engage_params_, f.results.data());
    } else {
        f.results.assign(batcher.size(), kernels::StepResult{});
    }
    batcher.hand_over(f.steps, f.meta);
    f.has_batch = true;
    f.active = true;
    f.fence = backend_.fence();
}

void Engagement::queue_sweep() {
    if (two_in_flight()) throw std::logic_error("engine: a removal queued with two batches in flight");
    InFlight& f = slots_[newest_];
    if (f.calls.empty()) return;
    std::size_t cells = 0;
    for (const auto& c : f.calls) cells += c.cells();
    f.sweep_out.resize(cells);
    phases_.sweeps += f.calls.size();
    f.active = true;
    PhaseTimer timer(phases_.queue_s);
    backend_.sweep(f.segs, f.calls, sweep_params_, f.sweep_out.data());
    f.fence = backend_.fence();
}

void Engagement::wait() {
    PhaseTimer timer(phases_.wait_s);
    if (two_in_flight()) backend_.wait_for(completing().fence);
    else backend_.wait();
}

void Engagement::release() {
    InFlight& f = completing();
    f.active = f.has_batch = false;
    f.steps.clear();
    f.meta.clear();
    f.calls.clear();
    f.segs.clear();
}

}  // namespace cutload::force_model
