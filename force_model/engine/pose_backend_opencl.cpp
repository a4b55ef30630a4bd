// The OpenCL pose backend: kernels/tri_dexel.cl on the runtime's device. The tri-dexel stock stays
// on the device for the whole run: on CPU devices (PoCL) its buffers wrap the host families (no
// copy at all); on a GPU it is written once when the run starts and read back only when the walk
// asks for it (a stopped spindle's "in material?" and the final stock); the shank and holder check
// runs on the device too. The queue, kernels and
// staging buffers are leased from the runtime's pool, so a later run in the process creates none.
// Each call waits for its own results: the walk books a batch's rows and removed volume before it
// builds the next.
#include "engine/pose_backend.hpp"
#include "kernels/opencl_runtime.hpp"

#include <algorithm>
#include <limits>
#include <vector>

namespace cutload::force_model {

namespace {

using kernels::check_cl;
using kernels::ClMem;

constexpr int kStepDoubles = 20;    // tri_dexel.cl, engage_poses: steps
constexpr int kChordDoubles = 24;   // tri_dexel.cl, sweep_chords: chords
constexpr int kElemDoubles = 8;     // tri_dexel.cl, engage_poses: elems
constexpr int kPoseDoubles = 14;    // tri_dexel.cl, body_rays: pose

class OpenClPoseBackend final : public PoseBackend {
public:
    OpenClPoseBackend(kernels::TriDexel stock, const kernels::EdgeTable& tool, kernels::ConvexToolSolid solid,
                      const kernels::EngageParams& params)
        : rt_(kernels::OpenClRuntime::instance()), stock_(std::move(stock)), solid_(std::move(solid)) {
        cl_device_fp_config fp64 = 0;
        check_cl(clGetDeviceInfo(rt_.device(), CL_DEVICE_DOUBLE_FP_CONFIG, sizeof fp64, &fp64, nullptr),
                 "clGetDeviceInfo(CL_DEVICE_DOUBLE_FP_CONFIG)");
        if (fp64 == 0)
            throw kernels::OpenClError("the OpenCL device " + rt_.device_name() +
                                       " has no double precision (cl_khr_fp64), which the multi-direction stock's "
                                       "kernels need");
        queue_ = rt_.lease_queue();
        drain_.queue = &queue_;
        engage_ = rt_.lease_kernel("tri_dexel.cl", "engage_poses");
        sweep_ = rt_.lease_kernel("tri_dexel.cl", "sweep_chords");
        body_ = rt_.lease_kernel("tri_dexel.cl", "body_rays");
        wrap_host_ = rt_.host_unified_memory();
        engage_group_ = rt_.is_gpu() ? 0 : 8;   // a batch is at most a few hundred steps: small groups use every core
        sweep_group_ = rt_.is_gpu() ? 0 : 32;
        for (int f = 0; f < 3; ++f) {
            std::vector<float>& rays = stock_.family[f].rays;
            const std::size_t bytes = std::max<std::size_t>(rays.size() * sizeof(float), 16);
            if (wrap_host_) {
                cl_int e = CL_SUCCESS;
                wrapped_[f] = ClMem(clCreateBuffer(rt_.context(), CL_MEM_USE_HOST_PTR | CL_MEM_READ_WRITE, bytes,
                                                   rays.data(), &e));
                check_cl(e, "clCreateBuffer (stock rays)");
            } else {
                leased_[f] = rt_.lease_buffer(bytes, CL_MEM_READ_WRITE);
                write(leased_[f].get(), rays.data(), rays.size() * sizeof(float));
            }
        }

        std::vector<double> elems(std::size_t(kElemDoubles) * std::max<std::size_t>(tool.r_mm.size(), 1), 0.0);
        for (std::size_t e = 0; e < tool.r_mm.size(); ++e) {
            const double v[kElemDoubles] = {tool.r_mm[e],    tool.z_mm[e],    tool.nr[e],      tool.nz[e],
                                            tool.db_mm[e],   tool.z_lo_mm[e], tool.z_hi_mm[e], tool.lag_rad[e]};
            std::copy(v, v + kElemDoubles, elems.begin() + std::ptrdiff_t(kElemDoubles * e));
        }
        elems_ = upload(elems);
        flutes_ = tool.flutes;
        element_end_ = params.element_end;
        coef_ = upload(std::vector<double>{params.k.Ktc, params.k.Krc, params.k.Kac, params.k.Kte, params.k.Kre,
                                           params.k.Kae, params.holder_face_z_mm, params.min_chip_mm});
        std::vector<double> grid{stock_.cell_mm};
        std::vector<cl_int> dims;
        for (const kernels::RayFamily& fam : stock_.family) {
            grid.push_back(fam.u0_mm);
            grid.push_back(fam.v0_mm);
            dims.push_back(fam.nu);
            dims.push_back(fam.nv);
        }
        grid_ = upload(grid);
        dims_ = upload(dims);
        std::vector<double> cones;
        for (const auto& piece : solid_.cones) cones.insert(cones.end(), piece.begin(), piece.end());
        cones_ = upload(cones);
        check_cl(clFinish(queue_.get()), "clFinish (upload)");
    }

    // Leases go back to the pool only once the device is done with them (drain_, destroyed first).
    ~OpenClPoseBackend() override = default;

    std::string name() const override { return "opencl: " + rt_.device_name(); }

    void engage(const kernels::PoseStep* steps, std::size_t n, double spin, kernels::StepResult* out) override {
        if (n == 0) return;
        host_steps_.assign(n * kStepDoubles, 0.0);
        for (std::size_t i = 0; i < n; ++i) {
            const kernels::PoseStep& s = steps[i];
            double* d = host_steps_.data() + kStepDoubles * i;
            for (int c = 0; c < 3; ++c) d[c] = s.tip_mm[c];
            for (int r = 0; r < 3; ++r)
                for (int c = 0; c < 3; ++c) d[3 + 3 * r + c] = s.rot[r][c];
            for (int c = 0; c < 3; ++c) {
                d[12 + c] = s.feed_mm[c];
                d[15 + c] = s.turn_rad[c];
            }
            d[18] = s.theta_rad;
        }
        grow(steps_buf_, host_steps_.size() * sizeof(double), CL_MEM_READ_ONLY);
        grow(out_buf_, n * sizeof(kernels::StepResult), CL_MEM_WRITE_ONLY);
        write(steps_buf_.get(), host_steps_.data(), host_steps_.size() * sizeof(double));
        cl_kernel k = engage_.get();
        int a = 0;
        kernels::set_arg(k, a++, cl_int(n));
        kernels::set_arg(k, a++, steps_buf_.get());
        kernels::set_arg(k, a++, spin);
        kernels::set_arg(k, a++, elems_.get());
        kernels::set_arg(k, a++, cl_int(flutes_));
        kernels::set_arg(k, a++, cl_int(element_end_));
        kernels::set_arg(k, a++, coef_.get());
        kernels::set_arg(k, a++, grid_.get());
        kernels::set_arg(k, a++, dims_.get());
        for (int f = 0; f < 3; ++f) kernels::set_arg(k, a++, rays(f));
        kernels::set_arg(k, a++, out_buf_.get());
        kernels::launch_1d(queue_.get(), k, n, engage_group_);
        check_cl(clEnqueueReadBuffer(queue_.get(), out_buf_.get(), CL_TRUE, 0, n * sizeof(kernels::StepResult), out, 0,
                                     nullptr, nullptr),
                 "read step results");
    }

    std::array<double, 3> sweep(const kernels::ToolChord* chords, std::size_t n) override {
        std::array<double, 3> removed{};
        if (n == 0) return removed;
        host_chords_.assign(n * kChordDoubles, 0.0);
        std::array<kernels::RayRect, 3> all;
        for (int f = 0; f < 3; ++f) all[f] = {1 << 30, -1, 1 << 30, -1};
        for (std::size_t c = 0; c < n; ++c) {
            const kernels::ToolChord& ch = chords[c];
            const kernels::ChordReach reach = kernels::chord_reach(solid_, ch, stock_.cell_mm);
            double* d = host_chords_.data() + kChordDoubles * c;
            for (int i = 0; i < 3; ++i) {
                d[i] = ch.from_mm[i];
                d[3 + i] = ch.to_mm[i];
                d[15 + i] = reach.lo_mm[i];
                d[18 + i] = reach.hi_mm[i];
            }
            for (int r = 0; r < 3; ++r)
                for (int col = 0; col < 3; ++col) d[6 + 3 * r + col] = ch.rot[r][col];
            d[21] = reach.samples;
            for (int f = 0; f < 3; ++f) {
                const kernels::RayRect r = kernels::rays_in_reach(stock_, f, reach);
                if (r.i1 < r.i0 || r.j1 < r.j0) continue;
                all[f] = {std::min(all[f].i0, r.i0), std::max(all[f].i1, r.i1), std::min(all[f].j0, r.j0),
                          std::max(all[f].j1, r.j1)};
            }
        }
        grow(chords_buf_, host_chords_.size() * sizeof(double), CL_MEM_READ_ONLY);
        write(chords_buf_.get(), host_chords_.data(), host_chords_.size() * sizeof(double));
        std::array<std::size_t, 3> items{};
        for (int f = 0; f < 3; ++f) {
            const kernels::RayRect& r = all[f];
            if (r.i1 < r.i0 || r.j1 < r.j0) continue;
            const cl_int ni = r.i1 - r.i0 + 1, nj = r.j1 - r.j0 + 1;
            items[f] = std::size_t(ni) * std::size_t(nj);
            grow(removed_buf_[f], items[f] * sizeof(double), CL_MEM_READ_WRITE);
            cl_kernel k = sweep_.get();
            int a = 0;
            kernels::set_arg(k, a++, cl_int(f));
            kernels::set_arg(k, a++, cl_int(r.i0));
            kernels::set_arg(k, a++, cl_int(r.j0));
            kernels::set_arg(k, a++, ni);
            kernels::set_arg(k, a++, nj);
            kernels::set_arg(k, a++, chords_buf_.get());
            kernels::set_arg(k, a++, cl_int(n));
            kernels::set_arg(k, a++, cones_.get());
            kernels::set_arg(k, a++, cl_int(solid_.cones.size()));
            kernels::set_arg(k, a++, grid_.get());
            kernels::set_arg(k, a++, dims_.get());
            kernels::set_arg(k, a++, rays(f));
            kernels::set_arg(k, a++, removed_buf_[f].get());
            kernels::launch_1d(queue_.get(), k, items[f], sweep_group_);
        }
        const double cell_area_mm2 = stock_.cell_mm * stock_.cell_mm;
        for (int f = 0; f < 3; ++f) {
            if (items[f] == 0) continue;
            host_removed_.resize(items[f]);
            check_cl(clEnqueueReadBuffer(queue_.get(), removed_buf_[f].get(), CL_TRUE, 0, items[f] * sizeof(double),
                                         host_removed_.data(), 0, nullptr, nullptr),
                     "read removed lengths");
            double len = 0;
            for (double l : host_removed_) len += l;
            removed[f] = len * cell_area_mm2;
        }
        host_stale_ = true;
        return removed;
    }

    // On the device, so a GPU's stock is never read back for it.
    kernels::BodyClearance body_clearance(const std::array<double, 3>& tip_mm,
                                          const std::array<std::array<double, 3>, 3>& rot, const kernels::ToolBody& body,
                                          double shell_mm) override {
        kernels::BodyClearance result;
        kernels::ChordReach box;
        if (!kernels::body_reach(stock_, tip_mm, rot, body, shell_mm, box)) return result;
        const std::vector<double> b{body.flute_length_mm, body.stickout_mm,     body.holder_length_mm,
                                    body.shank_radius_mm, body.holder_radius_mm, std::max(shell_mm, 0.0)};
        if (!body_buf_) body_buf_ = rt_.lease_buffer(b.size() * sizeof(double), CL_MEM_READ_ONLY);
        write(body_buf_.get(), b.data(), b.size() * sizeof(double));
        for (int f = 0; f < 3; ++f) {
            const kernels::RayRect r = kernels::rays_in_reach(stock_, f, box);
            if (r.i1 < r.i0 || r.j1 < r.j0) continue;
            double pose[kPoseDoubles];
            for (int c = 0; c < 3; ++c) pose[c] = tip_mm[c];
            for (int row = 0; row < 3; ++row)
                for (int c = 0; c < 3; ++c) pose[3 + 3 * row + c] = rot[row][c];
            pose[12] = box.lo_mm[f];
            pose[13] = box.hi_mm[f];
            grow(pose_buf_[f], sizeof pose, CL_MEM_READ_ONLY);
            write(pose_buf_[f].get(), pose, sizeof pose);
            const cl_int ni = r.i1 - r.i0 + 1, nj = r.j1 - r.j0 + 1;
            const std::size_t items = std::size_t(ni) * std::size_t(nj);
            grow(body_out_[f], items * 2 * sizeof(double), CL_MEM_WRITE_ONLY);
            cl_kernel k = body_.get();
            int a = 0;
            kernels::set_arg(k, a++, cl_int(f));
            kernels::set_arg(k, a++, cl_int(r.i0));
            kernels::set_arg(k, a++, cl_int(r.j0));
            kernels::set_arg(k, a++, ni);
            kernels::set_arg(k, a++, nj);
            kernels::set_arg(k, a++, pose_buf_[f].get());
            kernels::set_arg(k, a++, body_buf_.get());
            kernels::set_arg(k, a++, grid_.get());
            kernels::set_arg(k, a++, dims_.get());
            kernels::set_arg(k, a++, rays(f));
            kernels::set_arg(k, a++, body_out_[f].get());
            kernels::launch_1d(queue_.get(), k, items, sweep_group_);
            host_body_.resize(items * 2);
            check_cl(clEnqueueReadBuffer(queue_.get(), body_out_[f].get(), CL_TRUE, 0, items * 2 * sizeof(double),
                                         host_body_.data(), 0, nullptr, nullptr),
                     "read body clearances");
            for (std::size_t it = 0; it < items; ++it) {
                if (host_body_[2 * it] != 0) return {true, std::numeric_limits<double>::infinity()};
                result.clearance_mm = std::min(result.clearance_mm, host_body_[2 * it + 1]);
            }
        }
        return result;
    }

    const kernels::TriDexel& stock() override {
        if (!host_stale_) return stock_;
        if (wrap_host_) {
            // Mapping makes the host arrays current; PoCL maps a USE_HOST_PTR buffer in place.
            for (int f = 0; f < 3; ++f) {
                std::vector<float>& rays = stock_.family[f].rays;
                cl_int e = CL_SUCCESS;
                void* p = clEnqueueMapBuffer(queue_.get(), wrapped_[f].get(), CL_TRUE, CL_MAP_READ, 0,
                                             rays.size() * sizeof(float), 0, nullptr, nullptr, &e);
                check_cl(e, "map stock rays");
                if (p != rays.data()) std::copy_n(static_cast<const float*>(p), rays.size(), rays.data());
                check_cl(clEnqueueUnmapMemObject(queue_.get(), wrapped_[f].get(), p, 0, nullptr, nullptr),
                         "unmap stock rays");
            }
            check_cl(clFinish(queue_.get()), "clFinish (stock)");
        } else {
            for (int f = 0; f < 3; ++f) {
                std::vector<float>& rays = stock_.family[f].rays;
                check_cl(clEnqueueReadBuffer(queue_.get(), leased_[f].get(), CL_TRUE, 0, rays.size() * sizeof(float),
                                             rays.data(), 0, nullptr, nullptr),
                         "read stock rays");
            }
        }
        host_stale_ = false;
        return stock_;
    }

    kernels::TriDexel take_stock() override {
        stock();
        // The device is done with the families (each call waited for its work), so they can go.
        return std::move(stock_);
    }

private:
    cl_mem rays(int f) const { return wrap_host_ ? wrapped_[f].get() : leased_[f].get(); }

    template <typename T>
    kernels::BufferLease upload(const std::vector<T>& v) {
        const std::size_t bytes = std::max<std::size_t>(v.size() * sizeof(T), 16);
        kernels::BufferLease b = rt_.lease_buffer(bytes, CL_MEM_READ_ONLY);
        if (!v.empty()) write(b.get(), v.data(), v.size() * sizeof(T));
        return b;
    }

    // Blocking: the host arrays are reused (or gone) as soon as the call returns.
    void write(cl_mem buf, const void* host, std::size_t bytes) {
        check_cl(clEnqueueWriteBuffer(queue_.get(), buf, CL_TRUE, 0, bytes, host, 0, nullptr, nullptr), "write buffer");
    }

    void grow(kernels::BufferLease& buf, std::size_t bytes, cl_mem_flags flags) {
        if (buf && bytes <= buf.bytes()) return;
        buf = rt_.lease_buffer(std::max(bytes, 2 * buf.bytes()), flags);
    }


    kernels::OpenClRuntime& rt_;
    kernels::TriDexel stock_;
    kernels::ConvexToolSolid solid_;
    int flutes_ = 2, element_end_ = 0;
    bool wrap_host_ = false, host_stale_ = false;
    std::size_t engage_group_ = 0, sweep_group_ = 0;
    kernels::QueueLease queue_;
    kernels::KernelLease engage_, sweep_, body_;
    std::array<ClMem, 3> wrapped_;                   // CPU devices: the host families themselves
    std::array<kernels::BufferLease, 3> leased_;     // otherwise: the families on the device
    kernels::BufferLease elems_, coef_, grid_, dims_, cones_;
    kernels::BufferLease steps_buf_, out_buf_, chords_buf_;
    std::array<kernels::BufferLease, 3> removed_buf_, pose_buf_, body_out_;
    kernels::BufferLease body_buf_;
    std::vector<double> host_body_;
    std::vector<double> host_steps_, host_chords_, host_removed_;
    struct Drain {
        kernels::QueueLease* queue = nullptr;
        ~Drain() {
            if (queue && *queue && clFinish(queue->get()) != CL_SUCCESS) queue->discard();
        }
    };
    Drain drain_;   // last: destroyed first
};

}  // namespace

std::unique_ptr<PoseBackend> make_opencl_pose_backend(kernels::TriDexel stock, const kernels::EdgeTable& tool,
                                                      kernels::ConvexToolSolid solid, const kernels::EngageParams& params) {
    return std::make_unique<OpenClPoseBackend>(std::move(stock), tool, std::move(solid), params);
}

}  // namespace cutload::force_model
