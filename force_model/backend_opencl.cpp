// The OpenCL path: engage.cl and remove.cl on the runtime's device. Buffers are created once and
// grown by doubling; on CPU devices (PoCL) the stock buffer wraps the host array (no copy).
#include "force_model/engine.hpp"
#include "kernels/opencl_runtime.hpp"

#include <cmath>
#include <numbers>

namespace cutload::force_model {

namespace {

using kernels::check_cl;
using kernels::ClMem;

class OpenClBackend final : public Backend {
public:
    OpenClBackend(Stock& stock, const ToolGeometry& tool)
        : rt_(kernels::OpenClRuntime::instance()), stock_(stock), tool_(tool) {
        queue_ = rt_.make_queue();
        engage_ = rt_.make_kernel("engage.cl", "engage");
        remove_ = rt_.make_kernel("remove.cl", "remove_sweep");
        wrap_host_ = rt_.host_unified_memory();
        cells_ = buffer((wrap_host_ ? CL_MEM_USE_HOST_PTR : CL_MEM_COPY_HOST_PTR) | CL_MEM_READ_WRITE,
                        stock.cells.size() * sizeof(float), stock.cells.data());

        // Structure-of-arrays element table padded to whole float8 lanes (padding never cuts: nr = nz = 0).
        const auto& e = tool.edges;
        const std::size_t E = e.size();
        stride_ = (std::max<std::size_t>(E, 1) + 7) / 8 * 8;
        std::vector<float> elems(7 * stride_, 0.0f);
        for (std::size_t k = 0; k < E; ++k) {
            const double row[7] = {e.r_mm[k], e.z_mm[k], e.nr[k], e.nz[k], e.db_mm[k], e.z_lo_mm[k], e.z_hi_mm[k]};
            for (int f = 0; f < 7; ++f) elems[f * stride_ + k] = float(row[f]);
        }
        elems_ = buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, elems.size() * sizeof(float), elems.data());
        std::vector<float> rot(2 * 2 * std::size_t(e.flutes) * stride_, 0.0f);
        for (int s = 0; s < 2; ++s)
            for (int j = 0; j < e.flutes; ++j)
                for (std::size_t k = 0; k < E; ++k) {
                    const double spin = s == 0 ? 1.0 : -1.0;
                    const double psi = -2 * std::numbers::pi * j / e.flutes + spin * e.lag_rad[k];
                    const std::size_t base = 2 * (std::size_t(s) * e.flutes + j) * stride_;
                    rot[base + k] = float(std::cos(psi));
                    rot[base + stride_ + k] = float(std::sin(psi));
                }
        rot_ = buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, rot.size() * sizeof(float), rot.data());
        std::vector<float> lower(tool.lower_mm.begin(), tool.lower_mm.end());
        lower_ = buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, lower.size() * sizeof(float), lower.data());
        coef_ = buffer(CL_MEM_READ_ONLY, 8 * sizeof(float), nullptr);
    }

    std::string name() const override { return "opencl: " + rt_.device_name(); }

    void engage(const kernels::StepBatch& steps, const kernels::EngageParams& p, kernels::StepResult* out) override {
        const std::size_t n = steps.size();
        if (n == 0) return;
        const float coef[8] = {float(p.k.Ktc), float(p.k.Krc), float(p.k.Kac), float(p.k.Kte),
                               float(p.k.Kre), float(p.k.Kae), float(p.holder_face_z_mm), float(p.min_chip_mm)};
        check_cl(clEnqueueWriteBuffer(queue_.get(), coef_.get(), CL_FALSE, 0, sizeof coef, coef, 0, nullptr, nullptr),
                 "write coefficients");
        grow(steps_buf_, steps_cap_, n, 8 * sizeof(float), CL_MEM_READ_ONLY);
        grow(out_buf_, out_cap_, n, sizeof(kernels::StepResult), CL_MEM_WRITE_ONLY);
        host_steps_.resize(8 * n);
        for (std::size_t i = 0; i < n; ++i) {
            // Reduce the angle in double: float cannot hold an unwrapped angle of many revolutions.
            const double A = std::remainder(std::numbers::pi / 2 - steps.theta_rad[i], 2 * std::numbers::pi);
            float* s = host_steps_.data() + 8 * i;
            s[0] = float(steps.tip_x[i]);
            s[1] = float(steps.tip_y[i]);
            s[2] = float(steps.tip_z[i]);
            s[3] = float(steps.feed_x[i]);
            s[4] = float(steps.feed_y[i]);
            s[5] = float(steps.feed_z[i]);
            s[6] = float(A);
            s[7] = float(steps.spin[i]);
        }
        check_cl(clEnqueueWriteBuffer(queue_.get(), steps_buf_.get(), CL_FALSE, 0, 8 * n * sizeof(float),
                                      host_steps_.data(), 0, nullptr, nullptr),
                 "write steps");
        const auto& e = tool_.edges;
        const cl_int n_steps = cl_int(n), n_elems = cl_int(stride_), n_flutes = e.flutes,
                     bottom = e.bottom_count, end = p.element_end, nx = stock_.grid.nx, ny = stock_.grid.ny;
        const float x0 = float(stock_.grid.x0_mm), y0 = float(stock_.grid.y0_mm), inv = float(1.0 / stock_.grid.cell_mm);
        cl_kernel k = engage_.get();
        int a = 0;
        arg(k, a++, n_steps);
        arg(k, a++, steps_buf_.get());
        arg(k, a++, elems_.get());
        arg(k, a++, rot_.get());
        arg(k, a++, n_elems);
        arg(k, a++, n_flutes);
        arg(k, a++, bottom);
        arg(k, a++, end);
        arg(k, a++, cells_.get());
        arg(k, a++, x0);
        arg(k, a++, y0);
        arg(k, a++, inv);
        arg(k, a++, nx);
        arg(k, a++, ny);
        arg(k, a++, coef_.get());
        arg(k, a++, out_buf_.get());
        launch(k, n);
        check_cl(clEnqueueReadBuffer(queue_.get(), out_buf_.get(), CL_TRUE, 0, n * sizeof(kernels::StepResult), out, 0,
                                     nullptr, nullptr),
                 "read step results");
    }

    void sweep(const std::vector<kernels::SweepSegment>& segs, const kernels::SweepParams& p,
               kernels::SweepCellResult* out) override {
        const std::size_t cells = std::size_t(p.width) * p.height;
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
        const cl_int nx = stock_.grid.nx, i0 = p.i0, j0 = p.j0, w = p.width, h = p.height, n_segs = cl_int(segs.size()),
                     n_lower = cl_int(tool_.lower_mm.size());
        const float x0 = float(stock_.grid.x0_mm), y0 = float(stock_.grid.y0_mm), cell = float(stock_.grid.cell_mm),
                    radius = float(p.radius_mm), cut = float(p.cut_length_mm);
        cl_kernel k = remove_.get();
        int a = 0;
        arg(k, a++, cells_.get());
        arg(k, a++, nx);
        arg(k, a++, x0);
        arg(k, a++, y0);
        arg(k, a++, cell);
        arg(k, a++, i0);
        arg(k, a++, j0);
        arg(k, a++, w);
        arg(k, a++, h);
        arg(k, a++, segs_buf_.get());
        arg(k, a++, n_segs);
        arg(k, a++, lower_.get());
        arg(k, a++, n_lower);
        arg(k, a++, radius);
        arg(k, a++, cut);
        arg(k, a++, sweep_buf_.get());
        launch(k, cells);
        check_cl(clEnqueueReadBuffer(queue_.get(), sweep_buf_.get(), CL_TRUE, 0,
                                     cells * sizeof(kernels::SweepCellResult), out, 0, nullptr, nullptr),
                 "read sweep results");
    }

    void download(Stock& stock) override {
        const std::size_t bytes = stock.cells.size() * sizeof(float);
        if (wrap_host_) {
            // Mapping makes the host array current; PoCL maps a USE_HOST_PTR buffer in place.
            cl_int e = CL_SUCCESS;
            void* p = clEnqueueMapBuffer(queue_.get(), cells_.get(), CL_TRUE, CL_MAP_READ, 0, bytes, 0, nullptr,
                                         nullptr, &e);
            check_cl(e, "map stock");
            if (p != stock.cells.data()) std::copy_n(static_cast<const float*>(p), stock.cells.size(), stock.cells.data());
            check_cl(clEnqueueUnmapMemObject(queue_.get(), cells_.get(), p, 0, nullptr, nullptr), "unmap stock");
            check_cl(clFinish(queue_.get()), "finish");
        } else {
            check_cl(clEnqueueReadBuffer(queue_.get(), cells_.get(), CL_TRUE, 0, bytes, stock.cells.data(), 0, nullptr,
                                         nullptr),
                     "read stock");
        }
    }

private:
    ClMem buffer(cl_mem_flags flags, std::size_t bytes, void* host) {
        cl_int e = CL_SUCCESS;
        ClMem m(clCreateBuffer(rt_.context(), flags, std::max<std::size_t>(bytes, 16), host, &e));
        check_cl(e, "clCreateBuffer");
        return m;
    }

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
        // Let the runtime choose the work-group size (PoCL vectorises across it); pad the global
        // size to a multiple of 64, the kernels ignore the padding items.
        const std::size_t global = (n + 63) / 64 * 64;
        check_cl(clEnqueueNDRangeKernel(queue_.get(), k, 1, nullptr, &global, nullptr, 0, nullptr, nullptr),
                 "clEnqueueNDRangeKernel");
    }

    kernels::OpenClRuntime& rt_;
    Stock& stock_;
    const ToolGeometry& tool_;
    kernels::ClQueue queue_;
    kernels::ClKernel engage_, remove_;
    bool wrap_host_ = false;
    std::size_t stride_ = 8;
    ClMem cells_, elems_, rot_, lower_, coef_;
    ClMem steps_buf_, out_buf_, segs_buf_, sweep_buf_;
    std::size_t steps_cap_ = 0, out_cap_ = 0, segs_cap_ = 0, sweep_cap_ = 0;
    std::vector<float> host_steps_, host_segs_;
};

}  // namespace

std::unique_ptr<Backend> make_opencl_backend(Stock& stock, const ToolGeometry& tool) {
    return std::make_unique<OpenClBackend>(stock, tool);
}

}  // namespace cutload::force_model
