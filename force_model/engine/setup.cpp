#include "engine/setup.hpp"

namespace cutload::force_model {

namespace {

std::vector<ToolGeometry> tool_tables(const ToolPlan& plan, double axial_step_mm) {
    std::vector<ToolGeometry> tools;
    tools.reserve(plan.tools.size());
    for (const PlannedTool& t : plan.tools) {
        tools.push_back(build_tool_geometry(t.cutter, axial_step_mm));
        tools.back().holder_clearance_mm = t.limits.holder_clearance_mm;
    }
    return tools;
}

}  // namespace

EngineSetup::EngineSetup(const RunSpec& spec, const ToolPlan& plan, const PredictOptions& opt,
                         const EngineSettings& settings)
    : tools(tool_tables(plan, spec.resolution.axial_step_mm)),
      law(cutting_law(spec.material, settings.min_chip_mm)),
      fresh_stock(opt.base_stock == nullptr && !(opt.own_stock && *opt.own_stock)),
      stock(opt.own_stock && *opt.own_stock ? std::move(*opt.own_stock)
            : fresh_stock                   ? make_stock(spec.stock, spec.resolution.grid_mm)
                                            : copy_stock(*opt.base_stock)),
      backend(opt.device == Device::OpenCL ? make_opencl_backend(*stock, tools, fresh_stock) : make_cpu_backend(*stock, tools)) {}

}  // namespace cutload::force_model
