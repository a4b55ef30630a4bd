// The scalar path: the kernels' C++ twins on the host stock, one thread. Work runs when it is
// queued, so wait() and wait_for() have nothing to wait for.
#include "engine/backend.hpp"
#include "engine/stock_pages.hpp"

namespace cutload::force_model {

namespace {

class CpuBackend final : public Backend {
public:
    CpuBackend(Stock& stock, const std::vector<ToolGeometry>& tools)
        : stock_(stock), tools_(tools), tool_(&tools.at(0)), pages_(stock) {}
    std::string name() const override { return "cpu (scalar C++ twins)"; }
    void engage(const kernels::StepBatch& steps, const kernels::EngageParams& p, kernels::StepResult* out) override {
        kernels::engage_twin(steps, tool_->edges, p, stock_.view(), out);
    }
    void sweep(const std::vector<kernels::SweepSegment>& segs, const std::vector<kernels::SweepCall>& calls,
               const kernels::SweepParams& p, kernels::SweepCellResult* out) override {
        for (const kernels::SweepCall& call : calls) {
            pages_.prepare(call.i0, call.j0, call.i0 + call.width, call.j0 + call.height);
            kernels::sweep_twin(segs.data(), call, p, stock_.view(), out);
            out += call.cells();
        }
    }
    void wait() override {}
    std::uint64_t fence() override { return 0; }
    void wait_for(std::uint64_t) override {}
    void use_tool(std::size_t slot) override { tool_ = &tools_.at(slot); }
    void download(Stock&) override {}
    void will_cut(int i0, int j0, int i1, int j1) override { pages_.prepare(i0, j0, i1, j1); }

private:
    Stock& stock_;
    const std::vector<ToolGeometry>& tools_;
    const ToolGeometry* tool_;
    StockPages pages_;
};

}  // namespace

std::unique_ptr<Backend> make_cpu_backend(Stock& stock, const std::vector<ToolGeometry>& tools) {
    return std::make_unique<CpuBackend>(stock, tools);
}

}  // namespace cutload::force_model
