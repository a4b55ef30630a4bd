// The OpenCL path: engage.cl and remove.cl on the runtime's device, on one in-order queue, so an
// engagement always sees the removals queued before it. Nothing blocks until wait(): writes and
// result reads are non-blocking, the host staging arrays stay untouched until the driver's next
// wait(). Buffers are created once and grown by doubling; on CPU devices (PoCL) the stock buffer
// wraps the host array (no copy).
#include "engine/backend.hpp"
#include "kernels/opencl_runtime.hpp"

#include <array>
#include <cmath>
#include <cstring>
#include <numbers>

namespace cutload::force_model {

namespace {

using kernels::check_cl;
using kernels::ClMem;

// Work-group size on CPU devices: small groups keep both cores busy when the cutting steps of a
// batch are bunched together (PoCL would otherwise pick groups of up to 4096 steps).
constexpr std::size_t kCpuGroupSize = 64;

class OpenClBackend final : public Backend {
public:
    OpenClBackend(Stock& stock, const std::vector<ToolGeometry>& tools)
        : rt_(kernels::OpenClRuntime::instance()), stock_(stock) {
        queue_ = rt_.make_queue();
        engage_ = rt_.make_kernel("engage.cl", "engage");
        remove_ = rt_.make_kernel("remove.cl", "remove_sweep");
        wrap_host_ = rt_.host_unified_memory();
        group_ = rt_.is_gpu() ? 0 : kCpuGroupSize;
        cells_ = buffer((wrap_host_ ? CL_MEM_USE_HOST_PTR : CL_MEM_COPY_HOST_PTR) | CL_MEM_READ_WRITE,
                        stock.storage.bytes(), stock.stored());
        walls_ = buffer((wrap_host_ ? CL_MEM_USE_HOST_PTR : CL_MEM_COPY_HOST_PTR) | CL_MEM_READ_WRITE,
                        stock.walls.bytes(), stock.stored_walls());
        for (int k = 0; k < 4; ++k) {
            base_lo_.s[k] = stock.codec.base[k];
            base_hi_.s[k] = stock.codec.base[4 + k];
        }
        base_ = buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, sizeof stock.codec.base,
                       const_cast<std::uint32_t*>(stock.codec.base.data()));

        for (const ToolGeometry& t : tools) tools_.push_back(upload_tool(t));
        tool_ = &tools_.at(0);
        coef_ = buffer(CL_MEM_READ_ONLY, sizeof coef_host_, nullptr);
    }

    std::string name() const override { return "opencl: " + rt_.device_name(); }

    void engage(const kernels::StepBatch& steps, const kernels::EngageParams& p, kernels::StepResult* out) override {
        const std::size_t n = steps.size();
        if (n == 0) return;
        coef_host_ = {float(p.k.Ktc),           float(p.k.Krc),         float(p.k.Kac),
                      float(p.k.Kte),           float(p.k.Kre),         float(p.k.Kae),
                      float(p.holder_face_z_mm), float(p.min_chip_mm),   float(stock_.grid.cell_mm),
                      float(p.wall_tolerance_mm)};
        check_cl(clEnqueueWriteBuffer(queue_.get(), coef_.get(), CL_FALSE, 0, sizeof coef_host_, coef_host_.data(), 0,
                                      nullptr, nullptr),
                 "write coefficients");
        grow(steps_buf_, steps_cap_, n, 8 * sizeof(float), CL_MEM_READ_ONLY);
        grow(out_buf_, out_cap_, n, sizeof(kernels::StepResult), CL_MEM_WRITE_ONLY);
        host_steps_.resize(8 * n);
        for (std::size_t i = 0; i < n; ++i) {
            float* s = host_steps_.data() + 8 * i;
            s[0] = float(steps.tip_x[i]);
            s[1] = float(steps.tip_y[i]);
            s[2] = float(steps.tip_z[i]);
            s[3] = float(steps.feed_x[i]);
            s[4] = float(steps.feed_y[i]);
            s[5] = float(steps.feed_z[i]);
            s[6] = float(steps.cos_a[i]);
            s[7] = float(steps.sin_a[i]);
        }
        check_cl(clEnqueueWriteBuffer(queue_.get(), steps_buf_.get(), CL_FALSE, 0, 8 * n * sizeof(float),
                                      host_steps_.data(), 0, nullptr, nullptr),
                 "write steps");
        const DeviceTool& t = *tool_;
        const cl_int n_steps = cl_int(n), n_elems = cl_int(t.stride), n_flutes = t.flutes, bottom = t.bottom_count,
                     end = p.element_end, nx = stock_.grid.nx, ny = stock_.grid.ny;
        const float x0 = float(stock_.grid.x0_mm), y0 = float(stock_.grid.y0_mm), inv = float(1.0 / stock_.grid.cell_mm);
        const float spin = float(steps.spin);
        cl_kernel k = engage_.get();
        int a = 0;
        arg(k, a++, n_steps);
        arg(k, a++, steps_buf_.get());
        arg(k, a++, spin);
        arg(k, a++, t.elems.get());
        arg(k, a++, t.rot.get());
        arg(k, a++, n_elems);
        arg(k, a++, n_flutes);
        arg(k, a++, bottom);
        arg(k, a++, end);
        arg(k, a++, cells_.get());
        arg(k, a++, walls_.get());
        arg(k, a++, base_lo_);
        arg(k, a++, base_hi_);
        arg(k, a++, x0);
        arg(k, a++, y0);
        arg(k, a++, inv);
        arg(k, a++, nx);
        arg(k, a++, ny);
        arg(k, a++, coef_.get());
        arg(k, a++, out_buf_.get());
        launch(k, n);
        check_cl(clEnqueueReadBuffer(queue_.get(), out_buf_.get(), CL_FALSE, 0, n * sizeof(kernels::StepResult), out, 0,
                                     nullptr, nullptr),
                 "read step results");
    }

    void sweep(const std::vector<kernels::SweepSegment>& segs, const std::vector<kernels::SweepCall>& calls,
               const kernels::SweepParams& p, kernels::SweepCellResult* out) override {
        std::size_t cells = 0;
        for (const kernels::SweepCall& c : calls) cells += c.cells();
        if (cells == 0 || segs.empty()) return;
        grow(segs_buf_, segs_cap_, segs.size(), 6 * sizeof(float), CL_MEM_READ_ONLY);
        grow(sweep_buf_, sweep_cap_, cells, sizeof(kernels::SweepCellResult), CL_MEM_WRITE_ONLY);
        host_segs_.resize(6 * segs.size());
        for (std::size_t i = 0; i < segs.size(); ++i) {
            const auto& s = segs[i];
            const float v[6] = {float(s.ax), float(s.ay), float(s.az), float(s.bx), float(s.by), float(s.bz)};
            std::copy(v, v + 6, host_segs_.begin() + std::ptrdiff_t(6 * i));
        }
        check_cl(clEnqueueWriteBuffer(queue_.get(), segs_buf_.get(), CL_FALSE, 0, host_segs_.size() * sizeof(float),
                                      host_segs_.data(), 0, nullptr, nullptr),
                 "write segments");
        const cl_int nx = stock_.grid.nx, n_lower = tool_->n_lower;
        const float x0 = float(stock_.grid.x0_mm), y0 = float(stock_.grid.y0_mm), cell = float(stock_.grid.cell_mm),
                    radius = float(p.radius_mm), cut = float(p.cut_length_mm), band = float(p.wall_band_mm);
        cl_kernel k = remove_.get();
        std::size_t out_first = 0;
        for (const kernels::SweepCall& c : calls) {
            const cl_int i0 = c.i0, j0 = c.j0, w = c.width, h = c.height, seg_first = cl_int(c.first_segment),
                         n_segs = cl_int(c.segments), first = cl_int(out_first);
            int a = 0;
            arg(k, a++, cells_.get());
            arg(k, a++, base_.get());
            arg(k, a++, nx);
            arg(k, a++, x0);
            arg(k, a++, y0);
            arg(k, a++, cell);
            arg(k, a++, i0);
            arg(k, a++, j0);
            arg(k, a++, w);
            arg(k, a++, h);
            arg(k, a++, segs_buf_.get());
            arg(k, a++, seg_first);
            arg(k, a++, n_segs);
            arg(k, a++, tool_->lower.get());
            arg(k, a++, n_lower);
            arg(k, a++, radius);
            arg(k, a++, cut);
            arg(k, a++, sweep_buf_.get());
            arg(k, a++, first);
            arg(k, a++, walls_.get());
            arg(k, a++, band);
            launch(k, c.cells());
            out_first += c.cells();
        }
        check_cl(clEnqueueReadBuffer(queue_.get(), sweep_buf_.get(), CL_FALSE, 0, cells * sizeof(kernels::SweepCellResult),
                                     out, 0, nullptr, nullptr),
                 "read sweep results");
    }

    void wait() override { check_cl(clFinish(queue_.get()), "clFinish"); }

    // Kernel arguments are taken when a kernel is queued, so queued work keeps its tool's tables.
    void use_tool(std::size_t slot) override { tool_ = &tools_.at(slot); }

    void download(Stock& stock) override {
        download(cells_, stock.stored(), stock.storage.bytes());
        download(walls_, stock.stored_walls(), stock.walls.bytes());
    }

private:
    // One cutter's tables on the device.
    struct DeviceTool {
        ClMem elems, rot, lower;
        std::size_t stride = 8;
        cl_int flutes = 1, bottom_count = 0, n_lower = 0;
    };

    DeviceTool upload_tool(const ToolGeometry& tool) {
        DeviceTool d;
        // Structure-of-arrays element table padded to whole float8 lanes (padding never cuts: nr = nz = 0).
        const auto& e = tool.edges;
        const std::size_t E = e.size();
        d.stride = (std::max<std::size_t>(E, 1) + 7) / 8 * 8;
        d.flutes = e.flutes;
        d.bottom_count = e.bottom_count;
        std::vector<float> elems(8 * d.stride, 0.0f);
        for (std::size_t k = 0; k < E; ++k) {
            const double span = e.z_hi_mm[k] - e.z_lo_mm[k];
            const double row[8] = {e.r_mm[k],    e.z_mm[k],    e.nr[k],      e.nz[k],
                                   e.db_mm[k],   e.z_lo_mm[k], e.z_hi_mm[k], span > 0 ? 1 / span : 0.0};
            for (int f = 0; f < 8; ++f) elems[f * d.stride + k] = float(row[f]);
        }
        d.elems = buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, elems.size() * sizeof(float), elems.data());
        std::vector<float> rot(2 * 2 * std::size_t(e.flutes) * d.stride, 0.0f);
        for (int s = 0; s < 2; ++s)
            for (int j = 0; j < e.flutes; ++j)
                for (std::size_t k = 0; k < E; ++k) {
                    const double spin = s == 0 ? 1.0 : -1.0;
                    const double psi = -2 * std::numbers::pi * j / e.flutes + spin * e.lag_rad[k];
                    const std::size_t base = 2 * (std::size_t(s) * e.flutes + j) * d.stride;
                    rot[base + k] = float(std::cos(psi));
                    rot[base + d.stride + k] = float(std::sin(psi));
                }
        d.rot = buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, rot.size() * sizeof(float), rot.data());
        std::vector<float> lower(tool.lower_mm.begin(), tool.lower_mm.end());
        d.n_lower = cl_int(lower.size());
        d.lower = buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, lower.size() * sizeof(float), lower.data());
        return d;
    }

    void download(const ClMem& buf, void* host, std::size_t bytes) {
        if (wrap_host_) {
            // Mapping makes the host array current; PoCL maps a USE_HOST_PTR buffer in place.
            cl_int e = CL_SUCCESS;
            void* p = clEnqueueMapBuffer(queue_.get(), buf.get(), CL_TRUE, CL_MAP_READ, 0, bytes, 0, nullptr, nullptr, &e);
            check_cl(e, "map stock");
            if (p != host) std::memcpy(host, p, bytes);
            check_cl(clEnqueueUnmapMemObject(queue_.get(), buf.get(), p, 0, nullptr, nullptr), "unmap stock");
            check_cl(clFinish(queue_.get()), "finish");
        } else {
            check_cl(clEnqueueReadBuffer(queue_.get(), buf.get(), CL_TRUE, 0, bytes, host, 0, nullptr, nullptr),
                     "read stock");
        }
    }

    ClMem buffer(cl_mem_flags flags, std::size_t bytes, void* host) {
        cl_int e = CL_SUCCESS;
        ClMem m(clCreateBuffer(rt_.context(), flags, std::max<std::size_t>(bytes, 16), host, &e));
        check_cl(e, "clCreateBuffer");
        return m;
    }

    // Growing replaces the buffer; commands already queued keep the old one alive (OpenCL reference
    // counting), so this is safe between waits.
    void grow(ClMem& buf, std::size_t& cap, std::size_t n, std::size_t elem_bytes, cl_mem_flags flags) {
        if (buf && n <= cap) return;
        cap = std::max<std::size_t>(n, 2 * cap);
        buf = buffer(flags, cap * elem_bytes, nullptr);
    }

    template <typename T>
    static void arg(cl_kernel k, int i, const T& v) {
        check_cl(clSetKernelArg(k, cl_uint(i), sizeof(T), &v), "clSetKernelArg");
    }

    void launch(cl_kernel k, std::size_t n) {
        // Pad the global size to whole groups; the kernels ignore the padding items. On GPUs the
        // runtime chooses the group size.
        const std::size_t pad = std::max<std::size_t>(64, group_);
        const std::size_t global = (n + pad - 1) / pad * pad;
        check_cl(clEnqueueNDRangeKernel(queue_.get(), k, 1, nullptr, &global, group_ ? &group_ : nullptr, 0, nullptr,
                                        nullptr),
                 "clEnqueueNDRangeKernel");
    }

    kernels::OpenClRuntime& rt_;
    Stock& stock_;
    std::vector<DeviceTool> tools_;
    const DeviceTool* tool_ = nullptr;
    kernels::ClQueue queue_;
    kernels::ClKernel engage_, remove_;
    bool wrap_host_ = false;
    std::size_t group_ = 0;
    ClMem cells_, walls_, base_, coef_;
    cl_uint4 base_lo_{}, base_hi_{};
    ClMem steps_buf_, out_buf_, segs_buf_, sweep_buf_;
    std::size_t steps_cap_ = 0, out_cap_ = 0, segs_cap_ = 0, sweep_cap_ = 0;
    std::array<float, 10> coef_host_{};
    std::vector<float> host_steps_, host_segs_;
};

}  // namespace

std::unique_ptr<Backend> make_opencl_backend(Stock& stock, const std::vector<ToolGeometry>& tools) {
    return std::make_unique<OpenClBackend>(stock, tools);
}

}  // namespace cutload::force_model
