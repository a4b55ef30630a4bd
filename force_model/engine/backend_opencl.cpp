// The OpenCL path: engage.cl and remove.cl on the runtime's device, on one in-order queue, so an
// engagement always sees the removals queued before it. Nothing blocks until wait() or
// wait_for(): writes and result reads are non-blocking, and a host staging array stays untouched
// until the driver has waited for the work that reads it (engagements alternate between two
// staging sets, as two batches may be queued). The queue, kernels and buffers are leased from the
// runtime's pool and given back at the end, so a later prediction in the process creates none of
// them (but for the wrapped arrays below, which belong to their host memory); staging buffers grow
// by doubling.
// On CPU devices (PoCL) the stock buffers wrap the host arrays (no copy), and so does the batch's
// step array where the device reads it in place (no write per batch). On a GPU the stock lives
// in pooled device buffers: a fresh stock is zero bytes (the codec's "never cut"), filled on the
// device; at the end only the tiles a removal touched are read back (docs/force_model.md,
// "Device state").
#include "engine/backend.hpp"
#include "engine/stock_map.hpp"
#include "engine/stock_pages.hpp"
#include "kernels/opencl_runtime.hpp"

#include <array>
#include <bit>
#include <cmath>
#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <new>
#include <numbers>
#include <optional>

namespace cutload::force_model {

namespace {

using kernels::check_cl;
using kernels::ClEvent;
using kernels::ClMem;

// Work-group size on CPU devices: small groups keep both cores busy when the cutting steps of a
// batch are bunched together (PoCL would otherwise pick groups of up to 4096 steps).
constexpr std::size_t kCpuGroupSize = 64;

// Removal calls mark the stock tiles they may change; the end of the run reads back only those.
constexpr int kDirtyTile = 16;   // rays along each side
constexpr std::size_t kRayBytes = kernels::kDexelFloats * sizeof(float);
constexpr std::size_t kRayWallBytes = kernels::kWallSlots * kernels::kWallFloats * sizeof(float);

class OpenClBackend final : public Backend {
public:
    OpenClBackend(Stock& stock, const std::vector<ToolGeometry>& tools, bool fresh_stock)
        : rt_(kernels::OpenClRuntime::instance()), stock_(stock) {
        queue_ = rt_.lease_queue();
        drain_.queue = &queue_;
        engage_ = rt_.lease_kernel("engage.cl", "engage");
        remove_ = rt_.lease_kernel("remove.cl", "remove_sweep");
        refresh_ = rt_.lease_kernel("remove.cl", "refresh_tops");
        wrap_host_ = rt_.host_unified_memory();
        group_ = rt_.is_gpu() ? 0 : kCpuGroupSize;
        steps_in_place_ = wrap_host_ && rt_.wraps_host_arrays_in_place();
        top_base_ = std::bit_cast<cl_uint>(stock.codec.base_top());
        const std::size_t tops_bytes = stock.rays() * sizeof(cl_uint);
        if (wrap_host_) {
            host_tops_ = ZeroPages(tops_bytes);
            if (!fresh_stock) fill_tops(static_cast<cl_uint*>(host_tops_.data()));
            host_pages_.emplace(stock, &host_tops_);
            wrapped_cells_ = host_buffer(CL_MEM_USE_HOST_PTR | CL_MEM_READ_WRITE, stock.storage.bytes(), stock.stored());
            wrapped_walls_ = host_buffer(CL_MEM_USE_HOST_PTR | CL_MEM_READ_WRITE, stock.walls.bytes(), stock.stored_walls());
            wrapped_tops_ = host_buffer(CL_MEM_USE_HOST_PTR | CL_MEM_READ_WRITE, tops_bytes, host_tops_.data());
        } else {
            cells_lease_ = rt_.lease_buffer(stock.storage.bytes(), CL_MEM_READ_WRITE);
            walls_lease_ = rt_.lease_buffer(stock.walls.bytes(), CL_MEM_READ_WRITE);
            tops_lease_ = rt_.lease_buffer(tops_bytes, CL_MEM_READ_WRITE);
            if (fresh_stock) {
                // A fresh stock is all zero bytes (kernels::RayCodec): filled on the device, no copy.
                const cl_uint zero = 0;
                check_cl(clEnqueueFillBuffer(queue_.get(), cells_lease_.get(), &zero, sizeof zero, 0,
                                             stock.storage.bytes(), 0, nullptr, nullptr),
                         "fill stock");
                check_cl(clEnqueueFillBuffer(queue_.get(), walls_lease_.get(), &zero, sizeof zero, 0,
                                             stock.walls.bytes(), 0, nullptr, nullptr),
                         "fill walls");
                check_cl(clEnqueueFillBuffer(queue_.get(), tops_lease_.get(), &zero, sizeof zero, 0, tops_bytes, 0,
                                             nullptr, nullptr),
                         "fill tops");
            } else {
                write(cells_lease_.get(), stock.stored(), stock.storage.bytes());
                write(walls_lease_.get(), stock.stored_walls(), stock.walls.bytes());
                tops_upload_.assign(stock.rays(), 0);
                fill_tops(tops_upload_.data());
                write(tops_lease_.get(), tops_upload_.data(), tops_bytes);
            }
            tiles_x_ = (stock.grid.nx + kDirtyTile - 1) / kDirtyTile;
            tiles_y_ = (stock.grid.ny + kDirtyTile - 1) / kDirtyTile;
            dirty_.assign(std::size_t(tiles_x_) * std::size_t(tiles_y_), 0);
        }
        for (int k = 0; k < 4; ++k) {
            base_lo_.s[k] = stock.codec.base[k];
            base_hi_.s[k] = stock.codec.base[4 + k];
        }
        base_ = rt_.lease_buffer(sizeof stock.codec.base, CL_MEM_READ_ONLY);
        write(base_.get(), stock.codec.base.data(), sizeof stock.codec.base);

        tools_.reserve(tools.size());
        for (const ToolGeometry& t : tools) tools_.push_back(upload_tool(t));
        tool_ = &tools_.at(0);
        coef_ = rt_.lease_buffer(sizeof coef_host_, CL_MEM_READ_ONLY);
    }

    // Leases go back to the pool only once the device is done with them: drain_ (the last member,
    // so the first destroyed, also when the constructor throws with writes queued) finishes the
    // queue, and a queue that fails to finish is dropped rather than handed to the next prediction.
    ~OpenClBackend() override = default;

    std::string name() const override { return "opencl: " + rt_.device_name(); }

    void engage(const kernels::StepBatch& steps, const kernels::EngageParams& p, kernels::StepResult* out) override {
        const std::size_t n = steps.size();
        if (n == 0) return;
        const std::array<float, 10> coef{float(p.k.Ktc),           float(p.k.Krc),         float(p.k.Kac),
                                         float(p.k.Kte),           float(p.k.Kre),         float(p.k.Kae),
                                         float(p.holder_face_z_mm), float(p.min_chip_mm),   float(stock_.grid.cell_mm),
                                         float(p.wall_tolerance_mm)};
        // Written only when they change (a tool change): on PoCL every command costs tens of
        // microseconds of both cores, and the coefficients of a run's batches are mostly the same.
        if (!coef_written_ || coef != coef_host_) {
            // The queue is in order, and the values change only at a tool change, which comes after
            // a full wait (Engagement::use_tool: nothing in flight): the write has been read by
            // then, and batches queued before keep the values they were queued with.
            coef_host_ = coef;
            coef_written_ = false;
            check_cl(clEnqueueWriteBuffer(queue_.get(), coef_.get(), CL_FALSE, 0, sizeof coef_host_, coef_host_.data(),
                                          0, nullptr, nullptr),
                     "write coefficients");
            coef_written_ = true;
        }
        // Two batches may be outstanding: each engage() call stages in the set the one before the
        // last used, which the driver has waited for by now.
        set_ ^= 1;
        EngageStaging& st = staging_[set_];
        grow(st.out_buf, n * sizeof(kernels::StepResult), CL_MEM_WRITE_ONLY);
        float* const staged = stage_steps(st, 8 * n);
        for (std::size_t i = 0; i < n; ++i) {
            float* s = staged + 8 * i;
            s[0] = float(steps.tip_x[i]);
            s[1] = float(steps.tip_y[i]);
            s[2] = float(steps.tip_z[i]);
            s[3] = float(steps.feed_x[i]);
            s[4] = float(steps.feed_y[i]);
            s[5] = float(steps.feed_z[i]);
            s[6] = float(steps.cos_a[i]);
            s[7] = float(steps.sin_a[i]);
        }
        if (!steps_in_place_)
            check_cl(clEnqueueWriteBuffer(queue_.get(), st.steps_buf.get(), CL_FALSE, 0, 8 * n * sizeof(float),
                                          st.host_steps.data(), 0, nullptr, nullptr),
                     "write steps");
        const DeviceTool& t = *tool_;
        const cl_int n_steps = cl_int(n), n_elems = cl_int(t.stride), n_flutes = t.flutes, bottom = t.bottom_count,
                     end = p.element_end, nx = stock_.grid.nx, ny = stock_.grid.ny;
        const float x0 = float(stock_.grid.x0_mm), y0 = float(stock_.grid.y0_mm), inv = float(1.0 / stock_.grid.cell_mm);
        const float spin = float(steps.spin);
        cl_kernel k = engage_.get();
        int a = 0;
        kernels::set_arg(k, a++, n_steps);
        kernels::set_arg(k, a++, steps_in_place_ ? st.in_place_steps.get() : st.steps_buf.get());
        kernels::set_arg(k, a++, spin);
        kernels::set_arg(k, a++, t.elems.get());
        kernels::set_arg(k, a++, t.rot.get());
        kernels::set_arg(k, a++, n_elems);
        kernels::set_arg(k, a++, n_flutes);
        kernels::set_arg(k, a++, bottom);
        kernels::set_arg(k, a++, end);
        kernels::set_arg(k, a++, cells());
        kernels::set_arg(k, a++, walls());
        kernels::set_arg(k, a++, base_lo_);
        kernels::set_arg(k, a++, base_hi_);
        kernels::set_arg(k, a++, tops());
        kernels::set_arg(k, a++, top_base_);
        kernels::set_arg(k, a++, cl_int(p.skip_lookups_below_tops ? 1 : 0));
        kernels::set_arg(k, a++, x0);
        kernels::set_arg(k, a++, y0);
        kernels::set_arg(k, a++, inv);
        kernels::set_arg(k, a++, nx);
        kernels::set_arg(k, a++, ny);
        kernels::set_arg(k, a++, coef_.get());
        kernels::set_arg(k, a++, st.out_buf.get());
        kernels::launch_1d(queue_.get(), k, n, group_);
        cl_event read = nullptr;
        check_cl(clEnqueueReadBuffer(queue_.get(), st.out_buf.get(), CL_FALSE, 0, n * sizeof(kernels::StepResult), out, 0,
                                     nullptr, &read),
                 "read step results");
        last_read_ = ClEvent(read);
    }

    void sweep(const std::vector<kernels::SweepSegment>& segs, const std::vector<kernels::SweepCall>& calls,
               const kernels::SweepParams& p, kernels::SweepCellResult* out) override {
        std::size_t n_cells = 0;
        for (const kernels::SweepCall& c : calls) n_cells += c.cells();
        if (n_cells == 0 || segs.empty()) return;
        grow(sweep_buf_, n_cells * sizeof(kernels::SweepCellResult), CL_MEM_WRITE_ONLY);
        grow(changed_buf_, n_cells, CL_MEM_READ_WRITE);
        host_segs_.resize(6 * segs.size());
        for (std::size_t i = 0; i < segs.size(); ++i) {
            const auto& s = segs[i];
            const float v[6] = {float(s.ax), float(s.ay), float(s.az), float(s.bx), float(s.by), float(s.bz)};
            std::copy(v, v + 6, host_segs_.begin() + std::ptrdiff_t(6 * i));
        }
        // The staged segments also carry refresh_tops' table of calls (one write for both).
        const std::size_t table_first = host_segs_.size();
        const RefreshTable table = engaging_ ? stage_refresh_table(calls) : RefreshTable{};
        if (!engaging_) grow_stale_box(calls);
        grow(segs_buf_, host_segs_.size() * sizeof(float), CL_MEM_READ_ONLY);
        check_cl(clEnqueueWriteBuffer(queue_.get(), segs_buf_.get(), CL_FALSE, 0, host_segs_.size() * sizeof(float),
                                      host_segs_.data(), 0, nullptr, nullptr),
                 "write segments");
        const cl_int nx = stock_.grid.nx, n_lower = tool_->n_lower;
        const float x0 = float(stock_.grid.x0_mm), y0 = float(stock_.grid.y0_mm), cell = float(stock_.grid.cell_mm),
                    radius = float(p.radius_mm), cut = float(p.cut_length_mm), band = float(p.wall_band_mm);
        cl_kernel k = remove_.get();
        std::size_t out_first = 0;
        for (const kernels::SweepCall& c : calls) {
            // CPU devices: the call's rays are made writable before the kernel reads them.
            if (host_pages_) host_pages_->prepare(c.i0, c.j0, c.i0 + c.width, c.j0 + c.height);
            mark_dirty(c);
            const cl_int i0 = c.i0, j0 = c.j0, w = c.width, h = c.height, seg_first = cl_int(c.first_segment),
                         n_segs = cl_int(c.segments), first = cl_int(out_first);
            int a = 0;
            kernels::set_arg(k, a++, cells());
            kernels::set_arg(k, a++, base_.get());
            kernels::set_arg(k, a++, nx);
            kernels::set_arg(k, a++, x0);
            kernels::set_arg(k, a++, y0);
            kernels::set_arg(k, a++, cell);
            kernels::set_arg(k, a++, i0);
            kernels::set_arg(k, a++, j0);
            kernels::set_arg(k, a++, w);
            kernels::set_arg(k, a++, h);
            kernels::set_arg(k, a++, segs_buf_.get());
            kernels::set_arg(k, a++, seg_first);
            kernels::set_arg(k, a++, n_segs);
            kernels::set_arg(k, a++, tool_->lower.get());
            kernels::set_arg(k, a++, n_lower);
            kernels::set_arg(k, a++, radius);
            kernels::set_arg(k, a++, cut);
            kernels::set_arg(k, a++, sweep_buf_.get());
            kernels::set_arg(k, a++, first);
            kernels::set_arg(k, a++, walls());
            kernels::set_arg(k, a++, band);
            kernels::set_arg(k, a++, changed_buf_.get());
            kernels::launch_1d(queue_.get(), k, c.cells(), group_);
            out_first += c.cells();
        }
        if (table.items > 0)
            launch_refresh(segs_buf_.get(), cl_int(table_first), table.calls, changed_buf_.get(), {}, table.items);
        cl_event read = nullptr;
        check_cl(clEnqueueReadBuffer(queue_.get(), sweep_buf_.get(), CL_FALSE, 0, n_cells * sizeof(kernels::SweepCellResult),
                                     out, 0, nullptr, &read),
                 "read sweep results");
        last_read_ = ClEvent(read);
    }

    void wait() override {
        check_cl(clFinish(queue_.get()), "clFinish");
        tops_upload_ = {};   // read by now
    }

    // The queue is in order and every engage() and sweep() ends with a read of its results, so the
    // last read's event completes after everything queued before it.
    std::uint64_t fence() override {
        if (!last_read_) return 0;
        check_cl(clRetainEvent(last_read_.get()), "clRetainEvent");
        Fence& f = fences_[++fences_made_ % fences_.size()];
        f.id = fences_made_;
        f.done = ClEvent(last_read_.get());
        return f.id;
    }

    void wait_for(std::uint64_t id) override {
        if (id == 0) return;
        Fence& f = fences_[id % fences_.size()];
        if (f.id != id || !f.done) {   // not kept (never in the driver's use): everything, to be safe
            wait();
            return;
        }
        const cl_event e = f.done.get();
        check_cl(clWaitForEvents(1, &e), "clWaitForEvents");
        cl_int status = CL_COMPLETE;
        check_cl(clGetEventInfo(e, CL_EVENT_COMMAND_EXECUTION_STATUS, sizeof status, &status, nullptr), "clGetEventInfo");
        check_cl(status, "queued work");
        f.done.reset();
    }

    // Kernel arguments are taken when a kernel is queued, so queued work keeps its tool's tables.
    void use_tool(std::size_t slot) override { tool_ = &tools_.at(slot); }

    void set_engaging(bool engaging) override {
        engaging_ = engaging;
        if (!engaging_ || stale_.i1 <= stale_.i0) return;
        // Once, every ray a window's lead-in may have changed (its calls' rectangles and one ray
        // around them), as it removed material without refreshing them.
        if (host_pages_) host_pages_->prepare_tops(stale_.i0, stale_.j0, stale_.i1, stale_.j1);
        // The table and the flags are not read for a rectangle: base_ stands in for them (it
        // is never grown, so no later sweep can give it up while this is queued).
        launch_refresh(base_.get(), 0, 0, base_.get(), stale_,
                       std::size_t(stale_.i1 - stale_.i0) * std::size_t(stale_.j1 - stale_.j0));
        stale_ = {};
    }

    bool read_lookup_tops(std::vector<std::uint32_t>& tops) override {
        tops.assign(stock_.rays(), 0);
        check_cl(clEnqueueReadBuffer(queue_.get(), this->tops(), CL_TRUE, 0, tops.size() * sizeof(std::uint32_t),
                                     tops.data(), 0, nullptr, nullptr),
                 "read tops");
        return true;
    }

    void download(Stock& stock) override {
        if (wrap_host_) {
            map_to_host(wrapped_cells_, stock.stored(), stock.storage.bytes());
            map_to_host(wrapped_walls_, stock.stored_walls(), stock.walls.bytes());
        } else {
            read_dirty_tiles(stock);
        }
    }

private:
    // One cutter's tables on the device.
    struct DeviceTool {
        kernels::BufferLease elems, rot, lower;
        std::vector<float> host_elems, host_rot, host_lower;   // sources of the non-blocking writes
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
        d.host_elems = std::move(elems);
        d.elems = table(d.host_elems);
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
        d.host_rot = std::move(rot);
        d.rot = table(d.host_rot);
        d.host_lower.assign(tool.lower_mm.begin(), tool.lower_mm.end());
        d.n_lower = cl_int(d.host_lower.size());
        d.lower = table(d.host_lower);
        return d;
    }

    kernels::BufferLease table(const std::vector<float>& host) {
        kernels::BufferLease b = rt_.lease_buffer(host.size() * sizeof(float), CL_MEM_READ_ONLY);
        if (!host.empty()) write(b.get(), host.data(), host.size() * sizeof(float));
        return b;
    }

    // Non-blocking: `host` must stay unchanged until the next wait.
    void write(cl_mem buf, const void* host, std::size_t bytes) {
        check_cl(clEnqueueWriteBuffer(queue_.get(), buf, CL_FALSE, 0, bytes, host, 0, nullptr, nullptr), "write buffer");
    }

    cl_mem cells() const { return wrap_host_ ? wrapped_cells_.get() : cells_lease_.get(); }
    cl_mem walls() const { return wrap_host_ ? wrapped_walls_.get() : walls_lease_.get(); }
    cl_mem tops() const { return wrap_host_ ? wrapped_tops_.get() : tops_lease_.get(); }

    // The per-ray tops of a stock that is not fresh (those of a fresh one are all 0).
    void fill_tops(cl_uint* tops) const {
        static_assert(sizeof(cl_uint) == sizeof(std::uint32_t));
        kernels::refresh_tops_twin(stock_.view(), 0, 0, stock_.grid.nx, stock_.grid.ny,
                                   reinterpret_cast<std::uint32_t*>(tops));
    }

    struct RefreshTable {
        cl_int calls = 0;
        std::size_t items = 0;   // work items: one per ray of each call's rectangle and one ray around it
    };

    // A call's rectangle grown by one ray, clipped to the grid.
    CellRect grown(const kernels::SweepCall& c) const {
        return {std::max(c.i0 - 1, 0), std::max(c.j0 - 1, 0), std::min(c.i0 + c.width + 1, stock_.grid.nx),
                std::min(c.j0 + c.height + 1, stock_.grid.ny)};
    }

    // The table of refresh_tops (remove.cl) for `calls`, appended to the staged segments.
    RefreshTable stage_refresh_table(const std::vector<kernels::SweepCall>& calls) {
        auto put = [&](cl_int v) { host_segs_.push_back(std::bit_cast<float>(v)); };
        RefreshTable t;
        cl_int changed_first = 0;
        for (const kernels::SweepCall& c : calls) {
            if (c.width > 0 && c.height > 0) {   // a call that wrote nothing has no entry
                const CellRect g = grown(c);
                // Only the tops: the rays around a call are only read.
                if (host_pages_) host_pages_->prepare_tops(g.i0, g.j0, g.i1, g.j1);
                for (const cl_int v : {c.i0, c.j0, c.width, c.height, changed_first, cl_int(t.items)}) put(v);
                t.items += std::size_t(g.i1 - g.i0) * std::size_t(g.j1 - g.j0);
                ++t.calls;
            }
            changed_first += cl_int(c.cells());
        }
        put(cl_int(t.items));
        return t;
    }

    // A window's lead-in: the rays its calls may change, for set_engaging.
    void grow_stale_box(const std::vector<kernels::SweepCall>& calls) {
        for (const kernels::SweepCall& c : calls) {
            if (c.width <= 0 || c.height <= 0) continue;
            const CellRect g = grown(c);
            if (stale_.i1 <= stale_.i0) {
                stale_ = g;
            } else {
                stale_ = {std::min(stale_.i0, g.i0), std::min(stale_.j0, g.j0), std::max(stale_.i1, g.i1),
                          std::max(stale_.j1, g.j1)};
            }
        }
    }

    // refresh_tops over the `n_calls` calls of the table at `table_first` in `table`, with their
    // flags in `changed`; with none, over every ray of `rect`.
    void launch_refresh(cl_mem table, cl_int table_first, cl_int n_calls, cl_mem changed, const CellRect& rect,
                        std::size_t items) {
        cl_kernel k = refresh_.get();
        int a = 0;
        kernels::set_arg(k, a++, cells());
        kernels::set_arg(k, a++, base_.get());
        kernels::set_arg(k, a++, cl_int(stock_.grid.nx));
        kernels::set_arg(k, a++, cl_int(stock_.grid.ny));
        kernels::set_arg(k, a++, table);
        kernels::set_arg(k, a++, table_first);
        kernels::set_arg(k, a++, n_calls);
        kernels::set_arg(k, a++, changed);
        kernels::set_arg(k, a++, cl_int(rect.i0));
        kernels::set_arg(k, a++, cl_int(rect.j0));
        kernels::set_arg(k, a++, cl_int(rect.i1 - rect.i0));
        kernels::set_arg(k, a++, cl_int(rect.j1 - rect.j0));
        kernels::set_arg(k, a++, tops());
        kernels::set_arg(k, a++, top_base_);
        kernels::launch_1d(queue_.get(), k, items, group_);
    }

    void will_cut(int i0, int j0, int i1, int j1) override {
        if (host_pages_) host_pages_->prepare(i0, j0, i1, j1);
    }

    void mark_dirty(const kernels::SweepCall& c) {
        if (wrap_host_ || c.width <= 0 || c.height <= 0) return;
        const int tx0 = std::max(c.i0, 0) / kDirtyTile, ty0 = std::max(c.j0, 0) / kDirtyTile;
        const int tx1 = std::min((c.i0 + c.width - 1) / kDirtyTile, tiles_x_ - 1);
        const int ty1 = std::min((c.j0 + c.height - 1) / kDirtyTile, tiles_y_ - 1);
        for (int ty = ty0; ty <= ty1; ++ty)
            for (int tx = tx0; tx <= tx1; ++tx) dirty_[std::size_t(ty) * std::size_t(tiles_x_) + std::size_t(tx)] = 1;
    }

    // One rectangular read per run of dirty tiles along a tile row, runs of the same extent in the
    // rows below merged into it (a contour's walls are a few tall rectangles, not a read per tile
    // row: each command costs PoCL about 0.1 ms), for the rays and for their walls.
    void read_dirty_tiles(Stock& stock) {
        const std::size_t nx = std::size_t(stock.grid.nx), ny = std::size_t(stock.grid.ny);
        auto dirty = [&](int tx, int ty) {
            return dirty_[std::size_t(ty) * std::size_t(tiles_x_) + std::size_t(tx)] != 0;
        };
        auto run_at = [&](int tx0, int tx1, int ty) {   // [tx0, tx1) is exactly a run of row ty
            if ((tx0 > 0 && dirty(tx0 - 1, ty)) || (tx1 < tiles_x_ && dirty(tx1, ty))) return false;
            for (int tx = tx0; tx < tx1; ++tx)
                if (!dirty(tx, ty)) return false;
            return true;
        };
        for (int ty = 0; ty < tiles_y_; ++ty) {
            for (int tx = 0; tx < tiles_x_;) {
                if (!dirty(tx, ty)) {
                    ++tx;
                    continue;
                }
                int end = tx;
                while (end < tiles_x_ && dirty(end, ty)) ++end;
                int rows = 1;
                while (ty + rows < tiles_y_ && run_at(tx, end, ty + rows)) ++rows;
                for (int k = 1; k < rows; ++k)   // taken: cleared so the rows below do not read it again
                    for (int t = tx; t < end; ++t) dirty_[std::size_t(ty + k) * std::size_t(tiles_x_) + std::size_t(t)] = 0;
                const std::size_t i0 = std::size_t(tx) * kDirtyTile, j0 = std::size_t(ty) * kDirtyTile;
                const std::size_t i1 = std::min(nx, std::size_t(end) * kDirtyTile);
                const std::size_t j1 = std::min(ny, std::size_t(ty + rows) * kDirtyTile);
                read_rect(cells_lease_.get(), stock.stored(), kRayBytes, nx, i0, j0, i1, j1);
                read_rect(walls_lease_.get(), stock.stored_walls(), kRayWallBytes, nx, i0, j0, i1, j1);
                tx = end;
            }
        }
        check_cl(clFinish(queue_.get()), "finish stock read");
        std::fill(dirty_.begin(), dirty_.end(), 0);
    }

    void read_rect(cl_mem buf, void* host, std::size_t ray_bytes, std::size_t nx, std::size_t i0, std::size_t j0,
                   std::size_t i1, std::size_t j1) {
        const std::size_t origin[3] = {i0 * ray_bytes, j0, 0};
        const std::size_t region[3] = {(i1 - i0) * ray_bytes, j1 - j0, 1};
        const std::size_t pitch = nx * ray_bytes;
        check_cl(clEnqueueReadBufferRect(queue_.get(), buf, CL_FALSE, origin, origin, region, pitch, 0, pitch, 0, host,
                                         0, nullptr, nullptr),
                 "read stock tiles");
    }

    void map_to_host(const ClMem& buf, void* host, std::size_t bytes) {
        // Mapping makes the host array current; PoCL maps a USE_HOST_PTR buffer in place.
        cl_int e = CL_SUCCESS;
        void* p = clEnqueueMapBuffer(queue_.get(), buf.get(), CL_TRUE, CL_MAP_READ, 0, bytes, 0, nullptr, nullptr, &e);
        check_cl(e, "map stock");
        if (p != host) std::memcpy(host, p, bytes);
        check_cl(clEnqueueUnmapMemObject(queue_.get(), buf.get(), p, 0, nullptr, nullptr), "unmap stock");
        check_cl(clFinish(queue_.get()), "finish");
    }

    ClMem host_buffer(cl_mem_flags flags, std::size_t bytes, void* host) {
        cl_int e = CL_SUCCESS;
        ClMem m(clCreateBuffer(rt_.context(), flags, std::max<std::size_t>(bytes, 16), host, &e));
        check_cl(e, "clCreateBuffer");
        return m;
    }

    // Where the batch's steps are packed for the kernel, `floats` of them, in staging set `st`. On a CPU device that
    // reads wrapped host arrays in place (OpenClRuntime::wraps_host_arrays_in_place), a page-aligned
    // array wrapped as a buffer: the batch queues no write. On PoCL's CPU device that write was the
    // command that woke its sleeping threads after each wait, which preempted the host for about
    // 0.2 ms per batch on two cores. Called only after the wait that completed the last kernel that
    // read the set's array.
    struct EngageStaging;
    float* stage_steps(EngageStaging& st, std::size_t floats) {
        if (!steps_in_place_) {
            grow(st.steps_buf, floats * sizeof(float), CL_MEM_READ_ONLY);
            st.host_steps.resize(floats);
            return st.host_steps.data();
        }
        if (floats * sizeof(float) > st.in_place_bytes) {
            constexpr std::size_t kPage = 4096;
            const std::size_t bytes = (std::max(floats * sizeof(float), 2 * st.in_place_bytes) + kPage - 1) / kPage * kPage;
            st.in_place_steps = {};
            st.in_place_bytes = 0;   // until the new array is wrapped
            st.in_place_host.reset(static_cast<float*>(std::aligned_alloc(kPage, bytes)));
            if (!st.in_place_host) throw std::bad_alloc();
            st.in_place_steps = host_buffer(CL_MEM_USE_HOST_PTR | CL_MEM_READ_ONLY, bytes, st.in_place_host.get());
            st.in_place_bytes = bytes;
        }
        return st.in_place_host.get();
    }

    // A staging buffer too small is given back and a larger one leased (at least double). Called
    // only while no queued command uses the buffer (a sweep comes after the wait that completes the
    // sweep before it, an engagement after the one that completes the last use of its set).
    void grow(kernels::BufferLease& buf, std::size_t bytes, cl_mem_flags flags) {
        if (buf && bytes <= buf.bytes()) return;
        const std::size_t want = std::max(bytes, 2 * buf.bytes());
        buf = rt_.lease_buffer(want, flags);
    }


    kernels::OpenClRuntime& rt_;
    Stock& stock_;
    std::vector<DeviceTool> tools_;
    const DeviceTool* tool_ = nullptr;
    kernels::QueueLease queue_;
    kernels::KernelLease engage_, remove_, refresh_;
    bool wrap_host_ = false;
    std::size_t group_ = 0;
    // Per ray, the top by which engage.cl skips lookups (kernels::refresh_tops_twin), kept by
    // remove.cl's refresh_tops: derived from the stock, never read back.
    ZeroPages host_tops_;                                // CPU devices: in host pages
    ClMem wrapped_cells_, wrapped_walls_, wrapped_tops_;  // CPU devices: the host stock itself
    std::optional<StockPages> host_pages_;               // and its pages made writable
    kernels::BufferLease cells_lease_, walls_lease_, tops_lease_;   // otherwise: the stock on the device
    std::vector<cl_uint> tops_upload_;                   // source of the tops' write for a stock not fresh, until a wait
    cl_uint top_base_ = 0;
    int tiles_x_ = 0, tiles_y_ = 0;
    std::vector<std::uint8_t> dirty_;                    // tiles a removal may have changed
    kernels::BufferLease base_, coef_;
    cl_uint4 base_lo_{}, base_hi_{};
    kernels::BufferLease segs_buf_, sweep_buf_;
    kernels::BufferLease changed_buf_;   // remove_sweep's flags of the rays it wrote, for refresh_tops
    bool engaging_ = true;               // set_engaging
    CellRect stale_;                     // the rays whose tops a lead-in's sweeps left (none: empty)
    struct Drain {
        kernels::QueueLease* queue = nullptr;
        ~Drain() {
            if (queue && *queue && clFinish(queue->get()) != CL_SUCCESS) queue->discard();
        }
    };
    std::array<float, 10> coef_host_{};
    bool coef_written_ = false;
    std::vector<float> host_segs_;   // the segments' staging, refresh_tops' table of calls after them
    struct Free {
        void operator()(float* p) const { std::free(p); }
    };
    bool steps_in_place_ = false;
    struct EngageStaging {
        kernels::BufferLease steps_buf, out_buf;
        std::vector<float> host_steps;
        std::unique_ptr<float, Free> in_place_host;   // stage_steps: the array a CPU device reads in place
        std::size_t in_place_bytes = 0;
        ClMem in_place_steps;                         // released before its array (declared after it)
    };
    std::array<EngageStaging, 2> staging_;   // engage() alternates between them
    int set_ = 0;
    ClEvent last_read_;   // of the last engage() or sweep() that queued work
    struct Fence {
        std::uint64_t id = 0;
        ClEvent done;
    };
    std::array<Fence, 4> fences_;   // the driver waits for at most the one before the last
    std::uint64_t fences_made_ = 0;
    Drain drain_;   // last: destroyed first
};

}  // namespace

std::unique_ptr<Backend> make_opencl_backend(Stock& stock, const std::vector<ToolGeometry>& tools, bool fresh_stock) {
    return std::make_unique<OpenClBackend>(stock, tools, fresh_stock);
}

}  // namespace cutload::force_model
