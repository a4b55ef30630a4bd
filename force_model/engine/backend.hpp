// Internal: the two heavy loops of the engine behind one interface, implemented by the OpenCL
// kernels (backend_opencl.cpp) and by their scalar C++ twins (backend_cpu.cpp).
#pragma once

#include "cutters/tool_geometry.hpp"
#include "kernels/engine_kernels.hpp"
#include "stock.hpp"

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace cutload::force_model {

// engage() evaluates a batch of time steps against the stock, sweep() removes the tool's swept
// volume along path segments from it. Both only queue the work, in order (an engagement sees every
// removal queued before it); the results are valid after wait(), or after wait_for() a fence()
// taken once they were queued. The inputs may be reused as soon as the call returns; the outputs
// must stay in place until then. At most two engage() calls and one sweep() call may be
// outstanding: a third engage() or a second sweep() comes after waiting for the oldest. Both use
// the tool chosen by use_tool() (the first one until then): the backend holds every tool's tables,
// built once.
class Backend {
public:
    virtual ~Backend() = default;
    virtual std::string name() const = 0;
    virtual void engage(const kernels::StepBatch& steps, const kernels::EngageParams& p,
                        kernels::StepResult* out) = 0;
    // Call k writes its calls[k].cells() results after those of the calls before it.
    virtual void sweep(const std::vector<kernels::SweepSegment>& segs, const std::vector<kernels::SweepCall>& calls,
                       const kernels::SweepParams& p, kernels::SweepCellResult* out) = 0;
    virtual void wait() = 0;
    // A name for the work queued so far, and a wait for just that work: what was queued after the
    // fence may still run (the driver queues the next batch before it completes the one before).
    virtual std::uint64_t fence() = 0;
    virtual void wait_for(std::uint64_t fence) = 0;
    // The tool (an index into the tools the backend was made with) of the calls that follow.
    // Work already queued keeps its tool.
    virtual void use_tool(std::size_t slot) = 0;
    // Makes the host stock current (end of run): on a GPU, the tiles removals changed are read back.
    virtual void download(Stock& stock) = 0;
    // The rays [i0, i1) x [j0, j1) are about to be read by engage() and cut by a later sweep(): a
    // backend that works in the host's arrays maps their pages writable first (StockPages).
    virtual void will_cut(int i0, int j0, int i1, int j1) = 0;
    // Whether engage() calls follow the sweeps (false while a window's lead-in is walked for its
    // removal alone): the OpenCL backend then stops keeping the tops below up to date, and
    // rebuilds them all once when engaging resumes.
    virtual void set_engaging(bool) {}
    // The per-ray tops by which the OpenCL engagement skips lookups (kernels::refresh_tops_twin says
    // what they hold), as the device has them after everything queued: for tests. False where the
    // backend keeps none (the scalar twins look up every edge point).
    virtual bool read_lookup_tops(std::vector<std::uint32_t>&) { return false; }
};

// Both work on `stock` (the OpenCL backend wraps it on CPU devices; on a GPU it fills a fresh stock
// on the device and copies any other). `tools` (at least one) must outlive the backend.
std::unique_ptr<Backend> make_cpu_backend(Stock& stock, const std::vector<ToolGeometry>& tools);
std::unique_ptr<Backend> make_opencl_backend(Stock& stock, const std::vector<ToolGeometry>& tools,
                                             bool fresh_stock);   // throws OpenClError

}  // namespace cutload::force_model
