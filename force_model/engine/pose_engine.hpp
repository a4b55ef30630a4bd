// Internal: the engine for a tool whose orientation changes while it cuts (simultaneous five-axis
// work), on the tri-dexel stock (kernels/tri_dexel.hpp; docs/five_axis.md sections 3 and 4).
// Engagement per step with the twist's chip, then the batch's sweep removed in chords of fixed
// orientation, trailing the engagement by a lag of travel as the Z-map engine's removal does
// (docs/force_model.md, "Stock lag"). Both run on a PoseBackend: the OpenCL kernels of
// kernels/tri_dexel.cl or their scalar twins.
#pragma once

#include "cutters/tool_geometry.hpp"
#include "engine/pose_backend.hpp"
#include "kernels/tri_dexel.hpp"

#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace cutload::force_model {

struct PoseEngineSettings {
    // Removal trails the engagement by this much travel. A front point sits inside the stock by the
    // lag times the sine of its normal's angle to the feed; near a ball's bottom that angle is
    // small, and the rays need the margin: at 4 cells a vertical ball end mill lost 1.4 % of its
    // axial force to the rays around its tip, at 8 none (measured before the engagement's sub-cell
    // inside test; a shorter lag was not tried since).
    double lag_cells = 8;
    // A removal covers at least this much travel (and the lag behind it), so the stock trails the
    // engagement by lag_cells to lag_cells + removal_cells (plus half a lag within a batch).
    double removal_cells = 8;
    double chord_tolerance_cells = 0.5; // a chord's fixed orientation and straight tip stay this close
    std::size_t batch_steps = 256;      // steps engaged against one state of the stock (fewer past half the lag)
    bool opencl = false;                // the OpenCL kernels (throws kernels::OpenClError when unusable), else the twins
    // The shank and holder are checked against the stock at a path's first step and again whenever
    // the holder has moved this far (its farthest point: tip travel plus turn times its reach), or a
    // quarter of the clearance shell if that is less, so no near miss is stepped over; the steps
    // in between take the last check's result.
    double holder_check_mm = 0.25;
};

class PoseEngine {
public:
    // `reach_mm`: how far from the tip the tool's cutting part extends (flute length and radius),
    // which turns an orientation change into travel.
    PoseEngine(kernels::TriDexel stock, const ToolGeometry& tool, kernels::ConvexToolSolid solid,
               kernels::EngageParams params, PoseEngineSettings settings = {});

    // Engages and removes along the steps, in order, with the spindle turning `spin` (+1 M03, -1
    // M04); out receives one result per step. Steps of successive calls continue one path.
    // `body`, when given, receives the shank and holder check that holds for each step.
    void run(const std::vector<kernels::PoseStep>& steps, std::vector<kernels::StepResult>& out, double spin,
             std::vector<kernels::BodyClearance>* body = nullptr);
    // Removes what is still pending (the last lag of travel) and ends the path: the next run()
    // starts a new one, never swept to from this one's end (the tool left: air, a stop, a session's
    // end).
    void finish();

    // The stock as it stands (read back from the device when it changed there).
    const kernels::TriDexel& stock() const { return backend_->stock(); }
    // Ends the path (finish) and moves the stock out, for an engine with another cutter (a tool
    // change); this engine is done with.
    kernels::TriDexel take_stock() {
        finish();
        return backend_->take_stock();
    }
    std::string device() const { return backend_->name(); }
    // Material removed so far, as the Z family measures it, mm^3.
    double removed_mm3() const { return removed_mm3_; }
    std::size_t chords() const { return chords_; }
    std::size_t body_checks() const { return body_checks_; }
    // The shank and holder at one pose outside a path (the flutes off the stock, a stopped
    // spindle), under the same spacing rule as the path's checks.
    kernels::BodyClearance body_at(const kernels::PoseStep& pose);

private:
    void remove_through(std::size_t last);   // pending poses [0, last] become chords
    void check_body(const std::vector<kernels::PoseStep>& steps, std::size_t b0, std::size_t b1,
                    std::vector<kernels::BodyClearance>& body);

    double cell_mm_;
    std::unique_ptr<PoseBackend> backend_;
    PoseEngineSettings settings_;
    double reach_mm_;
    std::vector<kernels::PoseStep> pending_;   // poses not yet removed; the first is the last chord's end
    std::vector<double> travel_mm_;            // cumulative travel over pending_
    double removed_mm3_ = 0;
    std::size_t chords_ = 0;
    // Shank and holder checks (ToolGeometry's holder; the shell is its holder_clearance_mm).
    kernels::ToolBody body_;
    double shell_mm_ = 0;
    double body_reach_mm_ = 0;
    std::optional<kernels::PoseStep> checked_at_;   // the pose of the last check; none: none yet
    kernels::BodyClearance last_check_;
    std::size_t body_checks_ = 0;
};

}  // namespace cutload::force_model
