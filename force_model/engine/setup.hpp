// Internal: what a prediction builds before its walk: the kernel tables of every cutter the run
// uses (its tool plan's slots), the cutting law, the stock it starts from and the backend that
// holds the stock. Kept apart from the walk so that a caller can hold them across runs (a
// device-resident engine).
#pragma once

#include "cutters/cutter.hpp"
#include "cutters/tool_geometry.hpp"
#include "cutting_law.hpp"
#include "engine/backend.hpp"
#include "engine/tool_plan.hpp"
#include "force_model/engine_settings.hpp"
#include "stock.hpp"

#include <memory>
#include <vector>

namespace cutload::force_model {

class EngineSetup {
public:
    // The stock is opt.own_stock taken over, else opt.base_stock's copy, else a fresh box; the
    // backend is opt.device's.
    EngineSetup(const RunSpec& spec, const ToolPlan& plan, const PredictOptions& opt, const EngineSettings& settings);
    // The backend holds references to the tools and the stock: the set-up stays where it is built.
    EngineSetup(const EngineSetup&) = delete;
    EngineSetup& operator=(const EngineSetup&) = delete;

    const std::vector<ToolGeometry> tools;   // by the plan's slot
    const LinearEdgeForceLaw law;
    const bool fresh_stock;
    StockPtr stock;
    std::unique_ptr<Backend> backend;
};

}  // namespace cutload::force_model
