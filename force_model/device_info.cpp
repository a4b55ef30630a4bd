#include "force_model/force_model.hpp"
#include "kernels/opencl_runtime.hpp"

namespace cutload::force_model {

std::string opencl_device_name() { return kernels::OpenClRuntime::instance().device_name(); }

}  // namespace cutload::force_model
