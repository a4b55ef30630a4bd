// The scalar pose backend: the twins of kernels/tri_dexel.cl on the host stock, one thread.
#include "engine/pose_backend.hpp"

namespace cutload::force_model {

namespace {

class CpuPoseBackend final : public PoseBackend {
public:
    CpuPoseBackend(kernels::TriDexel stock, const kernels::EdgeTable& tool, kernels::ConvexToolSolid solid,
                   const kernels::EngageParams& params)
        : stock_(std::move(stock)), tool_(tool), solid_(std::move(solid)), params_(params) {}
    std::string name() const override { return "cpu (scalar C++ twins)"; }
    void engage(const kernels::PoseStep* steps, std::size_t n, double spin, kernels::StepResult* out) override {
        kernels::engage_tri_dexel(steps, n, spin, tool_, params_, stock_, out);
    }
    std::array<double, 3> sweep(const kernels::ToolChord* chords, std::size_t n) override {
        return kernels::sweep_tri_dexel(stock_, solid_, chords, n);
    }
    const kernels::TriDexel& stock() override { return stock_; }
    kernels::TriDexel take_stock() override { return std::move(stock_); }

private:
    kernels::TriDexel stock_;
    const kernels::EdgeTable& tool_;
    kernels::ConvexToolSolid solid_;
    kernels::EngageParams params_;
};

}  // namespace

std::unique_ptr<PoseBackend> make_cpu_pose_backend(kernels::TriDexel stock, const kernels::EdgeTable& tool,
                                                   kernels::ConvexToolSolid solid, const kernels::EngageParams& params) {
    return std::make_unique<CpuPoseBackend>(std::move(stock), tool, std::move(solid), params);
}

}  // namespace cutload::force_model
