// Internal: what a prediction builds before its walk: the cutter's kernel tables, the cutting law,
// the stock it starts from and the backend that holds the stock. Kept apart from the walk so that
// a caller can hold them across runs (a device-resident engine, a tool table).
#pragma once

#include "cutters/cutter.hpp"
#include "cutters/tool_geometry.hpp"
#include "cutting_law.hpp"
#include "engine/backend.hpp"
#include "force_model/engine_settings.hpp"
#include "stock.hpp"

#include <memory>

namespace cutload::force_model {

class EngineSetup {
public:
    // The stock is opt.base_stock's copy, else a fresh box; the backend is opt.device's.
    EngineSetup(const RunSpec& spec, const Cutter& cutter, const PredictOptions& opt, const EngineSettings& settings);
    // The backend holds references to the tool and the stock: the set-up stays where it is built.
    EngineSetup(const EngineSetup&) = delete;
    EngineSetup& operator=(const EngineSetup&) = delete;

    const ToolGeometry tool;
    const LinearEdgeForceLaw law;
    const bool fresh_stock;
    StockPtr stock;
    std::unique_ptr<Backend> backend;
};

}  // namespace cutload::force_model
