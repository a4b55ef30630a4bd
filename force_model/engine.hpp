// Engine internals and extensions of the public force_model.hpp: settings that the run spec does not
// (yet) carry, and the backend interface that the OpenCL kernels and their scalar twins implement.
#pragma once

#include "force_model/force_model.hpp"
#include "force_model/stock.hpp"
#include "force_model/tool_geometry.hpp"
#include "kernels/engine_kernels.hpp"

#include <memory>
#include <string>
#include <vector>

namespace cutload::force_model {

struct EngineSettings {
    // A move at or above this feed counts as a rapid (G0); cutting at it is flagged rapid_in_material.
    double rapid_feed_mm_min = 20000;
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
};

// Same as predict(), with explicit engine settings.
Prediction predict_with(const motion_io::MotionModel& motion, const RunSpec& spec, const PredictOptions& opt,
                        const EngineSettings& settings);

// The two heavy loops behind one interface: engage() evaluates a batch of time steps against the
// current stock, sweep() removes the tool's swept volume along path segments from it.
class Backend {
public:
    virtual ~Backend() = default;
    virtual std::string name() const = 0;
    virtual void engage(const kernels::StepBatch& steps, const kernels::EngageParams& p,
                        kernels::StepResult* out) = 0;
    virtual void sweep(const std::vector<kernels::SweepSegment>& segs, const kernels::SweepParams& p,
                       kernels::SweepCellResult* out) = 0;
    // Copies the backend's stock into the host stock (end of run).
    virtual void download(Stock& stock) = 0;
};

// Both work on `stock` (the OpenCL backend copies it to the device, or wraps it on CPU devices).
std::unique_ptr<Backend> make_cpu_backend(Stock& stock, const ToolGeometry& tool);
std::unique_ptr<Backend> make_opencl_backend(Stock& stock, const ToolGeometry& tool);   // throws OpenClError

}  // namespace cutload::force_model
