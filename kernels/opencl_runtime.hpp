// One OpenCL platform/device/context per process and a cache of built programs. Chooses a GPU when
// one exists, else a CPU device (PoCL); CUTLOAD_OPENCL_DEVICE overrides: "gpu", "cpu", or a part of
// the device name (case-insensitive). Callers create their own queues and kernels, so concurrent
// predictions do not serialise on one queue or race on kernel arguments.
#pragma once

#include <CL/cl.h>

#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <map>
#include <utility>

namespace cutload::kernels {

class OpenClError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// Throws OpenClError "<what>: <error name> (<code>)" when err != CL_SUCCESS.
void check_cl(cl_int err, const char* what);

// Owning handles for OpenCL objects.
template <typename T, cl_int (*Release)(T)>
class ClHandle {
public:
    ClHandle() = default;
    explicit ClHandle(T h) : h_(h) {}
    ClHandle(const ClHandle&) = delete;
    ClHandle& operator=(const ClHandle&) = delete;
    ClHandle(ClHandle&& o) noexcept : h_(std::exchange(o.h_, nullptr)) {}
    ClHandle& operator=(ClHandle&& o) noexcept {
        if (this != &o) {
            reset();
            h_ = std::exchange(o.h_, nullptr);
        }
        return *this;
    }
    ~ClHandle() { reset(); }
    void reset() {
        if (h_) Release(h_);
        h_ = nullptr;
    }
    T get() const { return h_; }
    explicit operator bool() const { return h_ != nullptr; }

private:
    T h_ = nullptr;
};

using ClQueue = ClHandle<cl_command_queue, clReleaseCommandQueue>;
using ClKernel = ClHandle<cl_kernel, clReleaseKernel>;
using ClMem = ClHandle<cl_mem, clReleaseMemObject>;
using ClProgram = ClHandle<cl_program, clReleaseProgram>;
using ClContext = ClHandle<cl_context, clReleaseContext>;

class OpenClRuntime {
public:
    // The process-wide runtime; throws OpenClError naming the cause when no usable device exists.
    static OpenClRuntime& instance();

    cl_context context() const { return context_.get(); }
    cl_device_id device() const { return device_; }
    const std::string& device_name() const { return device_name_; }
    bool is_gpu() const { return is_gpu_; }
    // True when device and host share memory (CPU devices): buffers can wrap host arrays.
    bool host_unified_memory() const { return host_unified_; }

    ClQueue make_queue() const;
    // The built program for an embedded kernels/*.cl file; built once per (name, options) in a
    // process, and loaded from the on-disk program cache (program_cache.hpp) when it holds the
    // binary of the same source, options, platform, device and driver.
    cl_program program(const std::string& cl_file, const std::string& options = "");
    ClKernel make_kernel(const std::string& cl_file, const char* kernel_name);

private:
    OpenClRuntime();
    std::string cache_key(const char* source, const std::string& options) const;
    cl_device_id device_ = nullptr;
    ClContext context_;
    std::string device_name_;
    bool is_gpu_ = false, host_unified_ = false;
    std::mutex mutex_;
    std::map<std::string, ClProgram> programs_;
};

}  // namespace cutload::kernels
