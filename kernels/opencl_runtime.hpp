// One OpenCL platform/device/context per process, a cache of built programs and a pool of the device
// objects predictions borrow. Chooses a GPU when one exists, else a CPU device (PoCL);
// CUTLOAD_OPENCL_DEVICE overrides: "gpu", "cpu", or a part of the device name (case-insensitive).
// A prediction leases its own queue, kernels and buffers, so concurrent predictions do not
// serialise on one queue or race on kernel arguments, and gives them back when it ends: the next
// prediction in the process creates nothing (docs/force_model.md, "Device state").
#pragma once

#include <CL/cl.h>

#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <map>
#include <utility>
#include <vector>

namespace cutload::kernels {

class OpenClError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// Throws OpenClError "<what>: <error name> (<code>)" when err != CL_SUCCESS.
void check_cl(cl_int err, const char* what);

// Sets argument i of kernel k to v (a cl_mem, a scalar or an OpenCL vector type).
template <typename T>
void set_arg(cl_kernel k, int i, const T& v) {
    check_cl(clSetKernelArg(k, cl_uint(i), sizeof(T), &v), "clSetKernelArg");
}
// Queues n work items of a 1-D kernel in groups of `group` (0: the runtime chooses, as on GPUs),
// the global size padded to whole groups (at least 64): the kernels ignore the padding items.
void launch_1d(cl_command_queue queue, cl_kernel k, std::size_t n, std::size_t group);

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
using ClEvent = ClHandle<cl_event, clReleaseEvent>;

class OpenClRuntime;

// A queue, kernel or buffer borrowed from the runtime's pool; it goes back to the pool when the
// lease ends. The holder must have finished every command that uses it by then.
template <typename Handle>
class Lease {
public:
    Lease() = default;
    Lease(OpenClRuntime* rt, std::string key, std::size_t bytes, Handle h)
        : rt_(rt), key_(std::move(key)), bytes_(bytes), h_(std::move(h)) {}
    Lease(Lease&& o) noexcept = default;
    Lease& operator=(Lease&& o) noexcept {
        if (this != &o) {
            give_back();
            rt_ = std::exchange(o.rt_, nullptr);
            key_ = std::move(o.key_);
            bytes_ = o.bytes_;
            h_ = std::move(o.h_);
        }
        return *this;
    }
    ~Lease() { give_back(); }
    auto get() const { return h_.get(); }
    std::size_t bytes() const { return bytes_; }   // buffers: the capacity, at least what was asked
    explicit operator bool() const { return bool(h_); }
    void give_back() noexcept;
    // Releases the object instead of giving it back (a queue left in an error state).
    void discard() noexcept {
        h_ = Handle();
        rt_ = nullptr;
    }

private:
    OpenClRuntime* rt_ = nullptr;
    std::string key_;
    std::size_t bytes_ = 0;
    Handle h_;
};

using QueueLease = Lease<ClQueue>;
using KernelLease = Lease<ClKernel>;
using BufferLease = Lease<ClMem>;

// What the pool has done since the process started (tests and benchmarks read it).
struct PoolStats {
    std::size_t queues_created = 0, kernels_created = 0, buffers_created = 0;
    std::size_t leases = 0, reused = 0;
    std::size_t idle_buffer_bytes = 0;
};

class OpenClRuntime {
public:
    // The process-wide runtime; throws OpenClError naming the cause when no usable device exists.
    static OpenClRuntime& instance();

    cl_context context() const { return context_.get(); }
    cl_device_id device() const { return device_; }
    const std::string& device_name() const { return device_name_; }
    bool is_gpu() const { return is_gpu_; }
    // True when device and host share memory (CPU devices): buffers can wrap host arrays.
    // CUTLOAD_OPENCL_DISCRETE=1 says false on any device, so the tests run a GPU's transfers on PoCL.
    bool host_unified_memory() const { return host_unified_; }
    // True when, on top of that, the device reads a CL_MEM_USE_HOST_PTR buffer over a page-aligned
    // host array where it lies (PoCL's CPU devices): it sees what the host wrote there since the
    // last wait, with no write command. The standard does not promise that, so the device is asked
    // once per process: it copies out a wrapped page twice, each after the host rewrote it.
    bool wraps_host_arrays_in_place();

    ClQueue make_queue() const;
    // The built program for an embedded kernels/*.cl file; built once per (name, options) in a
    // process, and loaded from the on-disk program cache (program_cache.hpp) when it holds the
    // binary of the same source, options, platform, device and driver.
    cl_program program(const std::string& cl_file, const std::string& options = "");
    ClKernel make_kernel(const std::string& cl_file, const char* kernel_name);

    // Leases from the pool, created when none is idle. A buffer lease holds at least `bytes` with
    // these flags (never CL_MEM_USE_HOST_PTR or COPY_HOST_PTR: pooled buffers outlive any host
    // array); the pool keeps the smallest idle buffer that fits, so buffers settle at the size of
    // the largest run so far. Idle buffers beyond a quarter of the device's memory are released.
    QueueLease lease_queue();
    KernelLease lease_kernel(const std::string& cl_file, const char* kernel_name);
    BufferLease lease_buffer(std::size_t bytes, cl_mem_flags flags);
    PoolStats pool_stats();

private:
    template <typename Handle>
    friend class Lease;
    void give_back(std::string key, std::size_t bytes, ClQueue h);
    void give_back(std::string key, std::size_t bytes, ClKernel h);
    void give_back(std::string key, std::size_t bytes, ClMem h);

    OpenClRuntime();
    std::string cache_key(const char* source, const std::string& options) const;
    cl_device_id device_ = nullptr;
    ClContext context_;
    std::string device_name_;
    bool is_gpu_ = false, host_unified_ = false;
    std::once_flag in_place_once_;
    bool in_place_ = false;
    std::mutex mutex_;
    std::map<std::string, ClProgram> programs_;

    std::mutex pool_mutex_;
    std::vector<ClQueue> idle_queues_;
    std::multimap<std::string, ClKernel> idle_kernels_;   // by "file/kernel"
    struct IdleBuffer {
        cl_mem_flags flags;
        std::size_t bytes;
        ClMem mem;
    };
    std::vector<IdleBuffer> idle_buffers_;
    std::size_t idle_cap_bytes_ = 0;
    PoolStats stats_;
};

template <typename Handle>
void Lease<Handle>::give_back() noexcept {
    try {
        if (rt_ && h_) rt_->give_back(std::move(key_), bytes_, std::move(h_));
    } catch (...) {   // out of memory in the pool's bookkeeping: the object is released instead
    }
    rt_ = nullptr;
    h_ = Handle();
}

}  // namespace cutload::kernels
