// Internal: the pose engine's two heavy loops, engagement on the tri-dexel stock and removal of the
// tool's sweep along chords, behind one interface: the OpenCL kernels of kernels/tri_dexel.cl
// (pose_backend_opencl.cpp) and their scalar C++ twins (pose_backend.cpp). Both are synchronous:
// results are complete when a call returns, so the walk can book them at once.
#pragma once

#include "kernels/tri_dexel.hpp"

#include <array>
#include <cstddef>
#include <memory>
#include <string>

namespace cutload::force_model {

class PoseBackend {
public:
    virtual ~PoseBackend() = default;
    virtual std::string name() const = 0;
    // One result per step, against the stock as the removals so far left it.
    virtual void engage(const kernels::PoseStep* steps, std::size_t n, double spin, kernels::StepResult* out) = 0;
    // Removes the solid's sweep along each chord, in order; returns the material removed as each
    // family measures it, mm^3.
    virtual std::array<double, 3> sweep(const kernels::ToolChord* chords, std::size_t n) = 0;
    // The stock as it stands (read back from a GPU when removals changed it since the last read).
    virtual const kernels::TriDexel& stock() = 0;
    // Moves the stock out (read back first where it lives on a device); the backend is done with.
    virtual kernels::TriDexel take_stock() = 0;
    // The shank and the holder against the stock at one pose (kernels::tri_dexel_body_clearance on
    // the stock as it stands).
    virtual kernels::BodyClearance body_clearance(const std::array<double, 3>& tip_mm,
                                                  const std::array<std::array<double, 3>, 3>& rot,
                                                  const kernels::ToolBody& body, double shell_mm) {
        return kernels::tri_dexel_body_clearance(stock(), tip_mm, rot, body, shell_mm);
    }
};

// `tool` must outlive the backend.
std::unique_ptr<PoseBackend> make_cpu_pose_backend(kernels::TriDexel stock, const kernels::EdgeTable& tool,
                                                   kernels::ConvexToolSolid solid, const kernels::EngageParams& params);
// Throws kernels::OpenClError when no OpenCL device is usable or it lacks double precision
// (cl_khr_fp64), which tri_dexel.cl needs.
std::unique_ptr<PoseBackend> make_opencl_pose_backend(kernels::TriDexel stock, const kernels::EdgeTable& tool,
                                                      kernels::ConvexToolSolid solid, const kernels::EngageParams& params);

}  // namespace cutload::force_model
