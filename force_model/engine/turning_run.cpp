#include "engine/turning_run.hpp"

#include "cutters/profile.hpp"
#include "cutters/tool_geometry.hpp"
#include "cutting_law.hpp"
#include "engine/block_summary.hpp"
#include "engine/motion_walk.hpp"
#include "engine/pose_engine.hpp"
#include "engine/rows.hpp"
#include "force_model/engine_settings.hpp"
#include "kernels/opencl_runtime.hpp"
#include "stock.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <stdexcept>

namespace cutload::force_model {

namespace {

using Vec = std::array<double, 3>;
using Mat = std::array<Vec, 3>;

Mat to_mat(const Rotation3& r) {
    return {{{r.m[0], r.m[1], r.m[2]}, {r.m[3], r.m[4], r.m[5]}, {r.m[6], r.m[7], r.m[8]}}};
}

// Between two samples' orientations (a milliradian or so apart): the blend, made orthonormal again
// with the tool axis kept first (it places the cutter; the turn about it is the spindle angle's).
Mat blend(const Mat& a, const Mat& b, double u) {
    Vec x, z;
    for (int r = 0; r < 3; ++r) {
        x[r] = (1 - u) * a[r][0] + u * b[r][0];
        z[r] = (1 - u) * a[r][2] + u * b[r][2];
    }
    const double nz = std::hypot(z[0], z[1], z[2]);
    for (double& c : z) c /= nz;
    const double d = x[0] * z[0] + x[1] * z[1] + x[2] * z[2];
    for (int r = 0; r < 3; ++r) x[r] -= d * z[r];
    const double nx = std::hypot(x[0], x[1], x[2]);
    for (double& c : x) c /= nx;
    const Vec y{z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]};
    return {{{x[0], y[0], z[0]}, {x[1], y[1], z[1]}, {x[2], y[2], z[2]}}};
}

// rot^T v
Vec into_tool(const Mat& rot, const Vec& v) {
    return {rot[0][0] * v[0] + rot[1][0] * v[1] + rot[2][0] * v[2], rot[0][1] * v[0] + rot[1][1] * v[1] + rot[2][1] * v[2],
            rot[0][2] * v[0] + rot[1][2] * v[1] + rot[2][2] * v[2]};
}

// The final stock as a Z-map (what save_stock, the service's base runs and the 3-D view take): the
// tri-dexel's Z family is laid out as make_stock lays out the same box, ray for ray. Untouched
// rays stay zero pages.
StockPtr z_map_of(const kernels::TriDexel& tri) {
    StockBox box;
    for (int a = 0; a < 3; ++a) box.min_mm[a] = tri.lo_mm[a], box.max_mm[a] = tri.hi_mm[a];
    StockPtr s = make_stock(box, tri.cell_mm);
    const kernels::RayFamily& z = tri.family[2];
    if (s->grid.nx != z.nu || s->grid.ny != z.nv)
        throw std::logic_error("predict_turning: the Z family and the Z-map of its box are laid out differently");
    const kernels::DexelView view = s->view();
    kernels::Ray full = kernels::kNoMaterial;
    full[0] = float(box.min_mm[2]);
    full[kernels::kDexelIntervals] = float(box.max_mm[2]);
    for (std::size_t r = 0; r < z.count(); ++r) {
        kernels::Ray ray;
        std::copy(z.ray(r), z.ray(r) + kernels::kDexelFloats, ray.begin());
        if (ray != full) view.store(r, ray);
    }
    return s;
}

// Appends the run of cells [k0, k1) (positions lo + k g along the ray) to a ray being built, as
// the box clips it; past kDexelIntervals runs the narrowest gap closes (as the removal does).
void append_run(float* ray, int& used, double lo_mm, double hi_mm, double g, int k0, int k1) {
    const float a = float(std::max(lo_mm, lo_mm + k0 * g)), b = float(std::min(hi_mm, lo_mm + k1 * g));
    if (!(b > a)) return;
    constexpr int K = kernels::kDexelIntervals;
    if (used == K) {
        // The narrowest gap closes: between stored runs k and k + 1, or the one before the new run
        // (k = used - 1; on a tie, that one), which then extends the last run to its end.
        int narrowest = used - 1;
        float least = a - ray[K + used - 1];
        for (int k = 0; k + 1 < used; ++k)
            if (ray[k + 1] - ray[K + k] < least) {
                least = ray[k + 1] - ray[K + k];
                narrowest = k;
            }
        if (narrowest == used - 1) {
            ray[K + used - 1] = b;
            return;
        }
        ray[K + narrowest] = ray[K + narrowest + 1];
        for (int k = narrowest + 1; k + 1 < used; ++k) {
            ray[k] = ray[k + 1];
            ray[K + k] = ray[K + k + 1];
        }
        --used;
    }
    ray[used] = a;
    ray[kernels::kDexelIntervals + used] = b;
    ++used;
}

// A three-axis run's stock (a Z-map) as the start of the multi-direction stock. The Z family is its
// rays as they are; an X or Y ray holds a cell where the Z ray of that cell's column holds the ray's
// height, so its walls lie on cell boundaries, half a cell at most from where the Z-map's sub-cell
// walls place them (not carried over yet), and its intervals are whole cells.
kernels::TriDexel tri_dexel_of(const Stock& base, const std::atomic<bool>* cancel) {
    if (!base.grid_from_stock.is_identity())
        throw SpecError("base_stock: it was cut with the tool tilted at a fixed orientation and is kept in that tool's "
                        "frame; a tool that turns while it cuts needs a stock in the part's axes (docs/five_axis.md, "
                        "section 3.4)");
    const std::array<double, 3> lo{base.box.min_mm[0], base.box.min_mm[1], base.box.min_mm[2]};
    const std::array<double, 3> hi{base.box.max_mm[0], base.box.max_mm[1], base.box.max_mm[2]};
    kernels::TriDexel t = kernels::make_tri_dexel_box(lo, hi, base.grid.cell_mm);
    const int nx = base.grid.nx, ny = base.grid.ny;
    kernels::RayFamily &fx = t.family[0], &fy = t.family[1], &fz = t.family[2];
    if (fz.nu != nx || fz.nv != ny || base.grid.x0_mm != lo[0] || base.grid.y0_mm != lo[1] || fx.nu != ny || fy.nv != nx)
        throw std::logic_error("predict_turning: the base stock's grid and the multi-direction stock of its box differ");
    const double g = t.cell_mm;
    const int nz = fx.nv;   // X rays: u = y (nu = ny), v = z; Y rays: u = z (nu = nz), v = x
    // Runs of material cells along X for each (y, z), along Y for each (z, x): where each began (-1: none).
    std::vector<int> x_run(std::size_t(ny) * std::size_t(nz), -1), x_used(x_run.size(), 0);
    std::vector<int> y_run(std::size_t(nz) * std::size_t(nx), -1), y_used(y_run.size(), 0);
    for (std::size_t r = 0; r < fx.count(); ++r) std::copy(kernels::kNoMaterial.begin(), kernels::kNoMaterial.end(), fx.ray(r));
    for (std::size_t r = 0; r < fy.count(); ++r) std::copy(kernels::kNoMaterial.begin(), kernels::kNoMaterial.end(), fy.ray(r));
    std::vector<char> solid(static_cast<std::size_t>(nz), 0);
    const auto same = [](const float* a, const float* b) { return std::equal(a, a + kernels::kDexelFloats, b); };
    // A run of ray r of family f opens at cell k where material begins and is stored where it ends.
    const auto step = [&](int f, std::size_t r, std::vector<int>& run, std::vector<int>& used, bool in, int k) {
        if (in && run[r] < 0) run[r] = k;
        if (!in && run[r] >= 0) {
            append_run(t.family[f].ray(r), used[r], lo[f], hi[f], g, run[r], k);
            run[r] = -1;
        }
    };
    for (int j = 0; j < ny; ++j) {
        if (cancel && cancel->load()) throw Cancelled();
        for (int i = 0; i <= nx; ++i) {
            // Column (i, j)'s intervals as they are (a wall mark in the last slot is no interval and
            // stays behind); past the last column none, so the runs close.
            const float* cur = kernels::kNoMaterial.data();
            if (i < nx) {
                const kernels::Ray ray = base.ray(i, j);
                float* z_ray = fz.ray(std::size_t(j) * std::size_t(nx) + std::size_t(i));
                std::copy(kernels::kNoMaterial.begin(), kernels::kNoMaterial.end(), z_ray);
                int z_used = 0;
                for (int k = 0; k < kernels::kDexelIntervals; ++k) {
                    if (!(ray[kernels::kDexelIntervals + k] > ray[k])) continue;
                    z_ray[z_used] = ray[k];
                    z_ray[kernels::kDexelIntervals + z_used] = ray[kernels::kDexelIntervals + k];
                    ++z_used;
                }
                cur = z_ray;
            }
            // A column like its neighbour before it along X (along Y) starts or ends no X (Y) run:
            // most of a stock is, so most columns cost a comparison, not a pass over its height.
            const float* before_x = i > 0 ? fz.ray(std::size_t(j) * std::size_t(nx) + std::size_t(i - 1)) : kernels::kNoMaterial.data();
            const float* before_y = j > 0 && i < nx ? fz.ray(std::size_t(j - 1) * std::size_t(nx) + std::size_t(i))
                                                    : kernels::kNoMaterial.data();
            const bool x_changes = !same(cur, before_x), y_changes = i < nx && !same(cur, before_y);
            if (!x_changes && !y_changes) continue;
            std::fill(solid.begin(), solid.end(), 0);
            for (int k = 0; k < kernels::kDexelIntervals; ++k) {
                const double a = cur[k], b = cur[kernels::kDexelIntervals + k];
                if (!(b > a)) continue;
                // Cells whose centre lies in [a, b).
                const int c0 = std::max(0, int(std::ceil((a - lo[2]) / g - 0.5)));
                const int c1 = std::min(nz, int(std::ceil((b - lo[2]) / g - 0.5)));
                for (int c = c0; c < c1; ++c) solid[std::size_t(c)] = 1;
            }
            for (int c = 0; c < nz; ++c) {
                const bool in = solid[std::size_t(c)] != 0;
                if (x_changes) step(0, std::size_t(c) * std::size_t(ny) + std::size_t(j), x_run, x_used, in, i);   // (u j, v c)
                if (y_changes) step(1, std::size_t(i) * std::size_t(nz) + std::size_t(c), y_run, y_used, in, j);   // (u c, v i)
            }
        }
    }
    for (std::size_t yr = 0; yr < y_run.size(); ++yr)
        if (y_run[yr] >= 0) append_run(fy.ray(yr), y_used[yr], lo[1], hi[1], g, y_run[yr], ny);
    return t;
}

class TurningWalk {
public:
    TurningWalk(const motion_io::MotionModel& motion, const ToolPoses& poses, const RunSpec& spec, const ToolPlan& plan,
                const PredictOptions& opt, const std::function<void(std::span<const ForceSample>)>& check_rows);
    Prediction run();

private:
    bool in_air(std::size_t i) const;
    bool in_material(std::size_t i) const;
    void walk_interval(std::size_t i);
    void flush();
    void leave();
    void hand_out(std::size_t keep);
    void check_progress(std::size_t i);

    const motion_io::MotionModel& motion_;
    const ToolPoses& poses_;
    const RunSpec& spec_;
    const ToolPlan& plan_;
    const PredictOptions& opt_;
    const std::function<void(std::span<const ForceSample>)>& check_rows_;
    struct TurningTool {
        ToolGeometry geometry;
        kernels::ConvexToolSolid solid;
        kernels::EngageParams params;
    };
    const TurningTool& tool() const { return tools_[std::size_t(slot_)]; }
    void use_slot(std::int32_t slot);

    std::vector<TurningTool> tools_;   // per slot of the plan
    std::int32_t slot_ = 0;            // the cutter the engine holds
    PoseEngineSettings settings_;
    StockBox stock_box_;   // the box the stock covers: the spec's, or the base stock's
    std::optional<PoseEngine> engine_;
    RowTable rows_;
    std::optional<BlockSummaries> blocks_;   // with rows_out: the rows leave, their summaries stay
    std::size_t rows_taken_ = 0, cutting_steps_ = 0, steps_ = 0;
    std::vector<kernels::PoseStep> chunk_;
    std::vector<StepMeta> meta_;
    std::vector<kernels::StepResult> results_;
    std::vector<kernels::BodyClearance> body_;   // the shank and holder check per step
    double chunk_spin_ = 1;
    double last_progress_ = -1;
    std::size_t current_ = 0;
    std::string device_note_;
};

TurningWalk::TurningWalk(const motion_io::MotionModel& motion, const ToolPoses& poses, const RunSpec& spec,
                         const ToolPlan& plan, const PredictOptions& opt,
                         const std::function<void(std::span<const ForceSample>)>& check_rows)
    : motion_(motion), poses_(poses), spec_(spec), plan_(plan), opt_(opt), check_rows_(check_rows) {
    if (poses.tool_to_stock.size() != motion.size() || poses.omega_tool_rad_s.size() != motion.size())
        throw std::invalid_argument(fmt::format("predict_turning: {} poses and {} turn rates for {} motion samples",
                                                poses.tool_to_stock.size(), poses.omega_tool_rad_s.size(), motion.size()));
    const Stock* base = opt.own_stock && *opt.own_stock ? opt.own_stock->get() : opt.base_stock;
    const double grid_mm = spec.resolution.grid_mm;
    const auto law = cutting_law(spec.material, EngineSettings{}.min_chip_mm);
    // Every cutter of the table up front (the engines keep references to their edge tables, so the
    // vector is not resized later), each refused by name where its cutting part is not convex.
    tools_.reserve(plan.tools.size());
    for (const PlannedTool& t : plan.tools) {
        TurningTool tool;
        tool.geometry = build_tool_geometry(t.cutter, spec.resolution.axial_step_mm);
        tool.geometry.holder_clearance_mm = t.limits.holder_clearance_mm;
        std::vector<std::array<double, 2>> rz;
        for (const ProfilePoint& p : profile_polyline(t.cutter.profile, grid_mm / 64)) rz.push_back({p.r_mm, p.z_mm});
        try {
            tool.solid = kernels::convex_tool_solid(rz);
        } catch (const std::invalid_argument& e) {
            const std::string which = t.number >= 0 ? fmt::format("tools (T{})", t.number) : std::string("tool");
            throw SpecError(which + ": a tool that turns while it cuts needs a convex cutting part: " + e.what());
        }
        set_kernel_law(law, tool.params);
        tool.params.holder_face_z_mm = tool.geometry.stickout_mm;
        tool.params.element_end = int(tool.geometry.edges.size());
        tools_.push_back(std::move(tool));
    }
    const StockBox& box = base ? base->box : spec.stock;
    const double cell_mm = base ? base->grid.cell_mm : grid_mm;
    stock_box_ = box;
    const std::array<double, 3> lo{box.min_mm[0], box.min_mm[1], box.min_mm[2]};
    const std::array<double, 3> hi{box.max_mm[0], box.max_mm[1], box.max_mm[2]};
    const double rays = double(kernels::tri_dexel_bytes(lo, hi, cell_mm)) / (kernels::kDexelFloats * sizeof(float));
    if (rays > kMaxStockRays)
        throw SpecError(fmt::format("resolution.grid_mm: the multi-direction stock of this box at {} mm takes {:.3g} rays, "
                                    "more than {:.3g}",
                                    cell_mm, rays, kMaxStockRays));
    const auto start = [&] { return base ? tri_dexel_of(*base, opt.cancel) : kernels::make_tri_dexel_box(lo, hi, cell_mm); };
    slot_ = std::max(0, plan.first_slot());
    settings_.opencl = opt.device == Device::OpenCL;
    try {
        engine_.emplace(start(), tool().geometry, tool().solid, tool().params, settings_);
    } catch (const kernels::OpenClError& e) {
        // A device without double precision (or none at all) still predicts, on the twins, and says so.
        settings_.opencl = false;
        engine_.emplace(start(), tool().geometry, tool().solid, tool().params, settings_);
        device_note_ = std::string(" (OpenCL not used: ") + e.what() + ")";
    }
    rows_.use_tool(slot_, motion.size() > 0 ? plan.number_at(0) : -1, tool().geometry.shank_diameter_mm);
    rows_.reserve(std::min<std::size_t>(expected_rows(motion, spec.resolution.angle_step_deg), kRowsOutPiece * 4));
    if (opt.rows_out) {
        std::vector<Limits> limits;
        for (const PlannedTool& t : plan.tools) limits.push_back(t.limits);
        blocks_.emplace(motion, std::move(limits));
    }
}

// A tool change: the path so far is removed and the stock handed to an engine for the new cutter.
void TurningWalk::use_slot(std::int32_t slot) {
    if (slot == slot_) return;
    leave();
    kernels::TriDexel stock = engine_->take_stock();
    engine_.reset();
    slot_ = slot;
    engine_.emplace(std::move(stock), tool().geometry, tool().solid, tool().params, settings_);
}

// Neither sample's cutting part (the cylinder of its widest radius from the tip up the flutes) can
// reach the stock box.
bool TurningWalk::in_air(std::size_t i) const {
    const double r = tool().geometry.radius_mm + spec_.resolution.grid_mm;
    for (std::size_t k : {i, i + 1}) {
        const Mat R = to_mat(poses_.tool_to_stock[k]);
        const Vec tip{motion_.x_mm[k] + spec_.offset_mm[0], motion_.y_mm[k] + spec_.offset_mm[1],
                      motion_.z_mm[k] + spec_.offset_mm[2]};
        bool overlaps = true;
        for (int a = 0; a < 3 && overlaps; ++a) {
            const double top = tip[a] + tool().geometry.flute_length_mm * R[a][2];
            overlaps = std::min(tip[a], top) - r <= stock_box_.max_mm[a] && std::max(tip[a], top) + r >= stock_box_.min_mm[a];
        }
        if (overlaps) return false;
    }
    return true;
}

// A stopped spindle with the cutter in material: its tip or a point up its axis (a radius, half the
// flutes) inside the stock.
bool TurningWalk::in_material(std::size_t i) const {
    const Mat R = to_mat(poses_.tool_to_stock[i]);
    for (double z : {0.0, tool().geometry.radius_mm, tool().geometry.flute_length_mm / 2}) {
        const Vec p{motion_.x_mm[i] + spec_.offset_mm[0] + z * R[0][2], motion_.y_mm[i] + spec_.offset_mm[1] + z * R[1][2],
                    motion_.z_mm[i] + spec_.offset_mm[2] + z * R[2][2]};
        if (kernels::tri_dexel_inside(engine_->stock(), p)) return true;
    }
    return false;
}

// The tool leaves the path (air, a stop, an unknown tool, the session's end): the batch is engaged
// and the pending path removed; its volume goes to the last row written, as the driver books a
// stop's.
void TurningWalk::leave() {
    flush();
    const double before = engine_->removed_mm3();
    engine_->finish();
    rows_.attribute_removed(engine_->removed_mm3() - before);
}

void TurningWalk::flush() {
    if (chunk_.empty()) return;
    const double before = engine_->removed_mm3();
    engine_->run(chunk_, results_, chunk_spin_, &body_);
    const std::size_t first = rows_.size();
    rows_.append_steps(meta_, results_, engine_->removed_mm3() - before);
    for (std::size_t k = 0; k < body_.size(); ++k) {
        rows_.samples[first + k].holder_contact = body_[k].contact;
        if (body_[k].clearance_mm < tool().geometry.holder_clearance_mm)
            rows_.extra[first + k].holder_clearance_mm = float(body_[k].clearance_mm);
    }
    for (const kernels::StepResult& r : results_) cutting_steps_ += r.engaged > 0 ? 1 : 0;
    steps_ += chunk_.size();
    chunk_.clear();
    meta_.clear();
    if (opt_.rows_out && rows_.size() >= kRowsOutPiece) hand_out(1);
}

// Hands the rows out but the last `keep` (the last row takes the volume removed at a stop).
void TurningWalk::hand_out(std::size_t keep) {
    const std::size_t n = rows_.size() - std::min(keep, rows_.size());
    if (n == 0) return;
    const std::span<const ForceSample> piece(rows_.samples.data(), n);
    check_rows_(piece);
    blocks_->add_rows(rows_.samples.data(), rows_.extra.data(), n);
    opt_.rows_out(piece);
    rows_.samples.erase(rows_.samples.begin(), rows_.samples.begin() + std::ptrdiff_t(n));
    rows_.extra.erase(rows_.extra.begin(), rows_.extra.begin() + std::ptrdiff_t(n));
    rows_taken_ += n;
}

void TurningWalk::check_progress(std::size_t i) {
    current_ = i;
    if (opt_.cancel && opt_.cancel->load()) throw Cancelled();
    const std::size_t rows = rows_taken_ + rows_.size() + chunk_.size();
    if (opt_.max_rows > 0 && rows > opt_.max_rows)
        throw TooManyRows(fmt::format("the prediction passed {} force rows at t = {:.3f} s of the motion, above the limit "
                                      "of {:.4g}: it was stopped",
                                      rows, motion_.t_s[i], double(opt_.max_rows)));
    if (!opt_.progress) return;
    const double f = double(i + 1) / double(motion_.size());
    if (f - last_progress_ >= 0.005) {
        last_progress_ = f;
        opt_.progress(f);
    }
}

void TurningWalk::walk_interval(std::size_t i) {
    if (!(motion_.t_s[i + 1] - motion_.t_s[i] > 0)) return;   // as the driver: no time, no steps
    // Rows already written are final; the last may still take a stop's volume.
    if (opt_.rows_out && rows_.size() >= kRowsOutPiece) hand_out(1);
    if (plan_.slot_at(i) < 0) {   // a tool the run spec's table lacks: no forces, and said so
        leave();
        rows_.append_unknown_tool(motion_, i, plan_.number_at(i));
        return;
    }
    use_slot(plan_.slot_at(i));
    rows_.use_tool(slot_, plan_.number_at(i), tool().geometry.shank_diameter_mm);
    const double rpm0 = motion_.spindle_rpm[i], rpm1 = motion_.spindle_rpm[i + 1];
    const bool turning = std::abs(rpm0) >= 1 && std::abs(rpm1) >= 1 && (rpm0 > 0) == (rpm1 > 0);
    if (!turning || in_air(i)) {
        leave();
        rows_.append_motion_sample(motion_, i, !turning && in_material(i));
        // The flutes are off the stock or still, but a leaning holder reaches far past the tip:
        // the shank and holder are checked at the sample all the same.
        kernels::PoseStep at;
        at.tip_mm = {motion_.x_mm[i] + spec_.offset_mm[0], motion_.y_mm[i] + spec_.offset_mm[1],
                     motion_.z_mm[i] + spec_.offset_mm[2]};
        at.rot = to_mat(poses_.tool_to_stock[i]);
        const kernels::BodyClearance body = engine_->body_at(at);
        rows_.samples.back().holder_contact = body.contact;
        if (body.clearance_mm < tool().geometry.holder_clearance_mm)
            rows_.extra.back().holder_clearance_mm = float(body.clearance_mm);
        return;
    }
    IntervalSteps steps(motion_, i, spec_.offset_mm, spec_.resolution.angle_step_deg, tool().geometry.edges.flutes);
    if (steps.spin() != chunk_spin_) {
        flush();
        chunk_spin_ = steps.spin();
    }
    const Mat R0 = to_mat(poses_.tool_to_stock[i]), R1 = to_mat(poses_.tool_to_stock[i + 1]);
    const Vec& w0 = poses_.omega_tool_rad_s[i];
    const Vec& w1 = poses_.omega_tool_rad_s[i + 1];
    const double t0 = motion_.t_s[i], h = motion_.t_s[i + 1] - t0;
    TimeStep s;
    while (steps.next(s)) {
        const double u = h > 0 ? std::clamp((s.t_s - t0) / h, 0.0, 1.0) : 0.0;
        kernels::PoseStep p;
        p.tip_mm = {s.tip_mm.x, s.tip_mm.y, s.tip_mm.z};
        p.rot = blend(R0, R1, u);
        p.feed_mm = into_tool(p.rot, {s.feed_per_tooth_mm.x, s.feed_per_tooth_mm.y, s.feed_per_tooth_mm.z});
        const double per_tooth_s = 60 / (tool().geometry.edges.flutes * std::abs(s.rpm));
        for (int c = 0; c < 3; ++c) p.turn_rad[c] = ((1 - u) * w0[c] + u * w1[c]) * per_tooth_s;
        p.theta_rad = s.theta_rad;
        chunk_.push_back(p);
        meta_.push_back({s.t_s, s.angle_deg, s.speed_mm_s * 60, s.rpm, s.block});
        if (chunk_.size() >= 4096) flush();
    }
}

Prediction TurningWalk::run() {
    const auto wall0 = std::chrono::steady_clock::now();
    for (const auto& [begin, end] : motion_.size() < 2 ? std::vector<std::pair<std::size_t, std::size_t>>{}
                                                       : session_ranges(motion_)) {
        flush();
        if (opt_.session_begins) opt_.session_begins(begin, end, rows_taken_ + rows_.size());
        for (std::size_t i = begin; i + 1 < end; ++i) {
            check_progress(i);
            walk_interval(i);
        }
        leave();   // nothing is swept across the jump to the next session
    }
    Prediction p;
    p.block_names = motion_.block_names;
    if (opt_.rows_out) {
        hand_out(0);
        p.blocks = blocks_->result();
    } else {
        std::vector<Limits> limits;
        for (const PlannedTool& t : plan_.tools) limits.push_back(t.limits);
        p.blocks = summarise_blocks(motion_, rows_.samples, rows_.extra, limits);
        p.samples = std::move(rows_.samples);
    }
    if (opt_.keep_final_stock) p.final_stock = z_map_of(engine_->stock());
    p.stats.cutting_steps = cutting_steps_;
    p.stats.steps = steps_;
    p.stats.unknown_tool_samples = plan_.unknown_samples;
    p.stats.unknown_tools = plan_.unknown_tools;
    p.stats.simulated_s = simulated_seconds(motion_);
    p.stats.device = engine_->device() + ", multi-direction stock (a tool turning while it cuts)" + device_note_;
    p.stats.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    if (opt_.progress) opt_.progress(1.0);
    return p;
}

}  // namespace

Prediction run_turning(const motion_io::MotionModel& motion, const ToolPoses& poses, const RunSpec& spec,
                       const ToolPlan& plan, const PredictOptions& opt,
                       const std::function<void(std::span<const ForceSample>)>& check_rows) {
    return TurningWalk(motion, poses, spec, plan, opt, check_rows).run();
}

}  // namespace cutload::force_model
