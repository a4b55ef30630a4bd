#include "engine/setup.hpp"

namespace cutload::force_model {

EngineSetup::EngineSetup(const RunSpec& spec, const Cutter& cutter, const PredictOptions& opt,
                         const EngineSettings& settings)
    : tool(build_tool_geometry(cutter, spec.resolution.axial_step_mm)),
      law(cutting_law(spec.material, settings.min_chip_mm)),
      fresh_stock(opt.base_stock == nullptr),
      stock(fresh_stock ? make_stock(spec.stock, spec.resolution.grid_mm) : copy_stock(*opt.base_stock)),
      backend(opt.device == Device::OpenCL ? make_opencl_backend(*stock, tool) : make_cpu_backend(*stock, tool)) {}

}  // namespace cutload::force_model
