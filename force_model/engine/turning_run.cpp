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
    ToolGeometry tool_;
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
    if (plan.tools.size() != 1)
        throw SpecError(fmt::format("tools: a tool that turns while it cuts (simultaneous five-axis work) is predicted "
                                    "with one cutter so far, and this run plans {} (docs/five_axis.md, section 3.4)",
                                    plan.tools.size()));
    if (opt.base_stock || opt.own_stock)
        throw SpecError("base_stock: a tool that turns while it cuts cuts the multi-direction stock, which starts from the "
                        "run spec's box so far: a base stock (a Z-map) cannot be its start (docs/five_axis.md, section 3.4)");
    const Cutter& cutter = plan.tools[0].cutter;
    tool_ = build_tool_geometry(cutter, spec.resolution.axial_step_mm);
    tool_.holder_clearance_mm = plan.tools[0].limits.holder_clearance_mm;
    const double grid_mm = spec.resolution.grid_mm;
    std::vector<std::array<double, 2>> rz;
    for (const ProfilePoint& p : profile_polyline(cutter.profile, grid_mm / 64)) rz.push_back({p.r_mm, p.z_mm});
    kernels::ConvexToolSolid solid;
    try {
        solid = kernels::convex_tool_solid(rz);
    } catch (const std::invalid_argument& e) {
        throw SpecError(std::string("tool: a tool that turns while it cuts needs a convex cutting part: ") + e.what());
    }
    const std::array<double, 3> lo{spec.stock.min_mm[0], spec.stock.min_mm[1], spec.stock.min_mm[2]};
    const std::array<double, 3> hi{spec.stock.max_mm[0], spec.stock.max_mm[1], spec.stock.max_mm[2]};
    const double rays = double(kernels::tri_dexel_bytes(lo, hi, grid_mm)) / (kernels::kDexelFloats * sizeof(float));
    if (rays > kMaxStockRays)
        throw SpecError(fmt::format("resolution.grid_mm: the multi-direction stock of this box at {} mm takes {:.3g} rays, "
                                    "more than {:.3g}",
                                    grid_mm, rays, kMaxStockRays));
    kernels::EngageParams params;
    set_kernel_law(cutting_law(spec.material, EngineSettings{}.min_chip_mm), params);
    params.holder_face_z_mm = tool_.stickout_mm;
    params.element_end = int(tool_.edges.size());
    PoseEngineSettings settings;
    settings.opencl = opt.device == Device::OpenCL;
    try {
        engine_.emplace(kernels::make_tri_dexel_box(lo, hi, grid_mm), tool_, solid, params, settings);
    } catch (const kernels::OpenClError& e) {
        // A device without double precision (or none at all) still predicts, on the twins, and says so.
        settings.opencl = false;
        engine_.emplace(kernels::make_tri_dexel_box(lo, hi, grid_mm), tool_, std::move(solid), params, settings);
        device_note_ = std::string(" (OpenCL not used: ") + e.what() + ")";
    }
    rows_.use_tool(0, motion.size() > 0 ? plan.number_at(0) : -1, tool_.shank_diameter_mm);
    rows_.reserve(std::min<std::size_t>(expected_rows(motion, spec.resolution.angle_step_deg), kRowsOutPiece * 4));
    if (opt.rows_out) {
        std::vector<Limits> limits;
        for (const PlannedTool& t : plan.tools) limits.push_back(t.limits);
        blocks_.emplace(motion, std::move(limits));
    }
}

// Neither sample's cutting part (the cylinder of its widest radius from the tip up the flutes) can
// reach the stock box.
bool TurningWalk::in_air(std::size_t i) const {
    const double r = tool_.radius_mm + spec_.resolution.grid_mm;
    for (std::size_t k : {i, i + 1}) {
        const Mat R = to_mat(poses_.tool_to_stock[k]);
        const Vec tip{motion_.x_mm[k] + spec_.offset_mm[0], motion_.y_mm[k] + spec_.offset_mm[1],
                      motion_.z_mm[k] + spec_.offset_mm[2]};
        bool overlaps = true;
        for (int a = 0; a < 3 && overlaps; ++a) {
            const double top = tip[a] + tool_.flute_length_mm * R[a][2];
            overlaps = std::min(tip[a], top) - r <= spec_.stock.max_mm[a] && std::max(tip[a], top) + r >= spec_.stock.min_mm[a];
        }
        if (overlaps) return false;
    }
    return true;
}

// A stopped spindle with the cutter in material: its tip or a point up its axis (a radius, half the
// flutes) inside the stock.
bool TurningWalk::in_material(std::size_t i) const {
    const Mat R = to_mat(poses_.tool_to_stock[i]);
    for (double z : {0.0, tool_.radius_mm, tool_.flute_length_mm / 2}) {
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
    rows_.attribute_removed(rows_.size(), 0, engine_->removed_mm3() - before);
}

void TurningWalk::flush() {
    if (chunk_.empty()) return;
    const double before = engine_->removed_mm3();
    engine_->run(chunk_, results_, chunk_spin_, &body_);
    const std::size_t first = rows_.size();
    rows_.append_steps(meta_, results_);
    for (std::size_t k = 0; k < body_.size(); ++k) {
        rows_.samples[first + k].holder_contact = body_[k].contact;
        if (body_[k].clearance_mm < tool_.holder_clearance_mm)
            rows_.extra[first + k].holder_clearance_mm = float(body_[k].clearance_mm);
    }
    rows_.attribute_removed(first, meta_.size(), engine_->removed_mm3() - before);
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
    rows_.use_tool(0, plan_.number_at(i), tool_.shank_diameter_mm);
    const double rpm0 = motion_.spindle_rpm[i], rpm1 = motion_.spindle_rpm[i + 1];
    const bool turning = std::abs(rpm0) >= 1 && std::abs(rpm1) >= 1 && (rpm0 > 0) == (rpm1 > 0);
    if (!turning || in_air(i)) {
        leave();
        rows_.append_motion_sample(motion_, i, !turning && in_material(i));
        return;
    }
    IntervalSteps steps(motion_, i, spec_.offset_mm, spec_.resolution.angle_step_deg, tool_.edges.flutes);
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
        const double per_tooth_s = 60 / (tool_.edges.flutes * std::abs(s.rpm));
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
