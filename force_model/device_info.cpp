#include "force_model/force_model.hpp"
#include "kernels/opencl_runtime.hpp"

namespace cutload::force_model {

std::string opencl_device_name() { return kernels::OpenClRuntime::instance().device_name(); }

void prepare_opencl() {
    kernels::OpenClRuntime& rt = kernels::OpenClRuntime::instance();
    // Leased and given back at once: they wait in the pool for the engine's backend.
    rt.lease_kernel("engage.cl", "engage");
    rt.lease_kernel("remove.cl", "remove_sweep");
    rt.lease_kernel("remove.cl", "refresh_tops");
}

}  // namespace cutload::force_model
