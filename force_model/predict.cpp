// The force engine's driver: walks the motion model, cuts it into batches of angle steps, runs the
// engagement backend on each batch, removes the swept volume with a lag, and collects rows.
//
// Pipeline: a flushed batch's engagement and removal are queued on the backend and left in flight
// while the walk produces the next batch; the next flush (or anything that needs the results, such
// as an air row) completes it first. The host's maps of stock tops are updated at completion, so
// every decision taken from them happens at the same point of the walk on every backend.
//
// Time steps: one per angle_step_deg of spindle rotation (the log's own spindle angle). Intervals
// where the tool cannot reach material (coarse tile map of stock tops) are written one row per
// motion sample and never evaluated per angle step. See docs/force_model.md.
#include "engine.hpp"
#include "summary.hpp"

#include "kernels/opencl_runtime.hpp"
#include "motion_io/hermite.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>

namespace cutload::force_model {

namespace {

constexpr int kTile = 16;                 // cells per side of a tile of the coarse max-top map
constexpr double kMovingSpeed_mm_s = 0.5; // slower moves have no meaningful direction
constexpr std::size_t kHolderCheckStride = 16;
constexpr std::size_t kMaxChordPoints = 128;   // bounds the quadratic chord check
constexpr std::size_t kMaxReservedRows = std::size_t(1) << 22;

using Clock = std::chrono::steady_clock;

// Adds the time from construction to destruction to `acc`.
class PhaseTimer {
public:
    explicit PhaseTimer(double& acc) : acc_(acc), t0_(Clock::now()) {}
    PhaseTimer(const PhaseTimer&) = delete;
    PhaseTimer& operator=(const PhaseTimer&) = delete;
    ~PhaseTimer() { acc_ += std::chrono::duration<double>(Clock::now() - t0_).count(); }

private:
    double& acc_;
    Clock::time_point t0_;
};

// The top of every ray, encoded like the rays (XOR with the box top), so the map of a fresh stock is
// zero pages that are only faulted in where the tool cuts.
class TopMap {
public:
    TopMap(const Stock& stock, bool fresh)
        : base_(std::bit_cast<std::uint32_t>(stock.codec.base_top())), bits_(stock.rays() * sizeof(std::uint32_t)) {
        if (fresh) return;
        for (std::size_t r = 0; r < stock.rays(); ++r)
            if (!stock.untouched(r)) set(r, kernels::ray_top(stock.ray(r)));
    }
    float at(std::size_t r) const { return std::bit_cast<float>(data()[r] ^ base_); }
    void set(std::size_t r, float top) {
        const std::uint32_t v = std::bit_cast<std::uint32_t>(top) ^ base_;
        if (data()[r] != v) data()[r] = v;   // no write, no page fault, where nothing changed
    }

private:
    std::uint32_t* data() const { return static_cast<std::uint32_t*>(bits_.data()); }
    std::uint32_t base_;
    ZeroPages bits_;
};

struct Vec3 {
    double x = 0, y = 0, z = 0;
};

struct StepMeta {
    double t_s, angle_deg, feed_mm_min, rpm;
    std::int32_t block;
};

struct PathPoint {
    Vec3 p;
    double s_mm;
};

// std::hypot's overflow care costs more than the rest of a step; these are millimetres.
double norm3(double x, double y, double z) { return std::sqrt(x * x + y * y + z * z); }
double dist(const Vec3& a, const Vec3& b) { return norm3(a.x - b.x, a.y - b.y, a.z - b.z); }

// The sessions as [begin, end) sample ranges; a model without a session list is one session.
std::vector<std::pair<std::size_t, std::size_t>> session_ranges(const motion_io::MotionModel& m) {
    std::vector<std::size_t> starts = m.session_start;
    if (starts.empty() || starts.front() != 0) starts.insert(starts.begin(), 0);
    std::vector<std::pair<std::size_t, std::size_t>> out;
    for (std::size_t s = 0; s < starts.size(); ++s) out.emplace_back(starts[s], s + 1 < starts.size() ? starts[s + 1] : m.size());
    return out;
}

// Motion time actually simulated: the sum of the sessions' spans (time may jump between them).
double simulated_seconds(const motion_io::MotionModel& m) {
    double total = 0;
    for (const auto& [b, e] : session_ranges(m))
        if (e > b + 1) total += m.t_s[e - 1] - m.t_s[b];
    return total;
}

// What the backend is working on: one batch's engagement and the removal queued with it.
struct InFlight {
    kernels::StepBatch steps;
    std::vector<StepMeta> meta;
    std::vector<kernels::StepResult> results;
    double x0 = 0, y0 = 0, x1 = 0, y1 = 0, zmin = 0;   // bounding box of the batch's tip positions
    std::vector<kernels::SweepSegment> segs;
    std::vector<kernels::SweepCall> calls;
    std::vector<kernels::SweepCellResult> sweep_out;
    bool has_batch = false, active = false;
};

class Engine {
public:
    Engine(const motion_io::MotionModel& m, const RunSpec& spec, const PredictOptions& opt, const EngineSettings& set,
           Stock& stock, bool fresh_stock, Backend& backend, const ToolGeometry& tool, EnginePhases& phases)
        : m_(m), spec_(spec), opt_(opt), set_(set), be_(backend), tool_(tool), g_(stock.grid),
          phases_(phases), top_(stock, fresh_stock) {
        tiles_x_ = (g_.nx + kTile - 1) / kTile;
        tiles_y_ = (g_.ny + kTile - 1) / kTile;
        tile_max_.assign(std::size_t(tiles_x_) * tiles_y_, stock.codec.base_top());
        if (!fresh_stock) refresh_tiles(0, 0, g_.nx, g_.ny);
        lag_mm_ = set.removal_lag_cells * g_.cell_mm;
        cos_turn_ = std::cos(set.batch_turn_deg * std::numbers::pi / 180);
        params_.k = {spec.material.Ktc_N_mm2, spec.material.Krc_N_mm2, spec.material.Kac_N_mm2,
                     spec.material.Kte_N_mm,  spec.material.Kre_N_mm,  spec.material.Kae_N_mm};
        params_.holder_face_z_mm = tool.stickout_mm;
        params_.min_chip_mm = set.min_chip_mm;
        params_.wall_tolerance_mm = set.wall_tolerance_mm;
        sweep_.lower_mm = tool.lower_mm;
        sweep_.radius_mm = tool.radius_mm;
        sweep_.cut_length_mm = tool.flute_length_mm;
        // An edge point lies within half a cell diagonal of its ray's centre: walls farther than
        // that from the centre cannot change a test. A whole cell keeps a margin.
        sweep_.wall_band_mm = g_.cell_mm;
        batch_.reserve(set.max_batch_steps);
        meta_.reserve(set.max_batch_steps);
        fly_.steps.reserve(set.max_batch_steps);
        fly_.meta.reserve(set.max_batch_steps);
        const double d = 2 * tool.radius_mm;
        section_modulus_mm3_ = std::numbers::pi * d * d * d / 32;
        const std::size_t expected = std::min(expected_rows(), kMaxReservedRows);
        rows.reserve(expected);
        extra.reserve(expected);
    }

    Engine(const Engine&) = delete;
    Engine& operator=(const Engine&) = delete;
    // On an exception the backend may still be writing into the in-flight slot: let it finish
    // before the slot goes away.
    ~Engine() {
        if (!fly_.active) return;
        try {
            be_.wait();
        } catch (const std::exception&) {   // already unwinding from the first error
        }
    }

    void run() {
        if (m_.size() < 2) return;
        // Each session is a separate stretch: batches and pending removal end with it, so nothing is
        // interpolated or swept across the jump to the next one.
        for (const auto& [b, e] : session_ranges(m_)) {
            for (std::size_t i = b; i + 1 < e; ++i) {
                current_ = i;
                interval(i);
            }
            flush_batch();
            remove_all_pending();
        }
        complete();
    }

    std::vector<ForceSample> rows;
    std::vector<RowExtra> extra;
    std::size_t steps = 0;

private:
    // One row per angle step plus one per motion sample: an upper bound that avoids regrowing rows.
    std::size_t expected_rows() const {
        double turned_deg = 0;
        for (std::size_t i = 0; i + 1 < m_.size(); ++i)
            turned_deg += std::abs(m_.spindle_angle_deg[i + 1] - m_.spindle_angle_deg[i]);
        return std::size_t(turned_deg / spec_.resolution.angle_step_deg) + m_.size() + 1;
    }

    Vec3 position(std::size_t i) const {
        return {m_.x_mm[i] + spec_.offset_mm[0], m_.y_mm[i] + spec_.offset_mm[1], m_.z_mm[i] + spec_.offset_mm[2]};
    }

    // ---- coarse stock map -------------------------------------------------------------------
    void refresh_tiles(int i0, int j0, int i1, int j1) {
        for (int tj = j0 / kTile; tj <= (j1 - 1) / kTile && tj < tiles_y_; ++tj)
            for (int ti = i0 / kTile; ti <= (i1 - 1) / kTile && ti < tiles_x_; ++ti) {
                float mx = kernels::kEmptyHi;
                for (int j = tj * kTile; j < std::min(g_.ny, (tj + 1) * kTile); ++j)
                    for (int i = ti * kTile; i < std::min(g_.nx, (ti + 1) * kTile); ++i)
                        mx = std::max(mx, top_.at(std::size_t(j) * g_.nx + i));
                tile_max_[std::size_t(tj) * tiles_x_ + ti] = mx;
            }
        ++tiles_version_;
    }

    // Cell rectangle [i0, i1) x [j0, j1) covering the world rectangle; false when off the grid.
    bool cell_rect(double x0, double y0, double x1, double y1, int& i0, int& j0, int& i1, int& j1) const {
        const double fi0 = std::floor((x0 - g_.x0_mm) / g_.cell_mm), fi1 = std::floor((x1 - g_.x0_mm) / g_.cell_mm);
        const double fj0 = std::floor((y0 - g_.y0_mm) / g_.cell_mm), fj1 = std::floor((y1 - g_.y0_mm) / g_.cell_mm);
        if (fi1 < 0 || fj1 < 0 || fi0 >= g_.nx || fj0 >= g_.ny) return false;
        i0 = int(std::max(0.0, fi0));
        j0 = int(std::max(0.0, fj0));
        i1 = int(std::min<double>(g_.nx - 1, fi1)) + 1;
        j1 = int(std::min<double>(g_.ny - 1, fj1)) + 1;
        return true;
    }

    // Highest stock top over the tiles the rectangle touches. The air check asks this for a square
    // the holder's size around every motion interval: hundreds of tiles, mostly the same ones as
    // for the interval before, so the last answer is kept until the tiles or the map change.
    float max_top(double x0, double y0, double x1, double y1) {
        int i0, j0, i1, j1;
        if (!cell_rect(x0, y0, x1, y1, i0, j0, i1, j1)) return kernels::kEmptyHi;
        const std::array<int, 4> tiles{i0 / kTile, j0 / kTile, (i1 - 1) / kTile, (j1 - 1) / kTile};
        if (tiles == memo_tiles_ && memo_version_ == tiles_version_) return memo_top_;
        float mx = kernels::kEmptyHi;
        for (int tj = tiles[1]; tj <= tiles[3]; ++tj)
            for (int ti = tiles[0]; ti <= tiles[2]; ++ti) mx = std::max(mx, tile_max_[std::size_t(tj) * tiles_x_ + ti]);
        memo_tiles_ = tiles;
        memo_version_ = tiles_version_;
        memo_top_ = mx;
        return mx;
    }

    float column_top(double x, double y) const {
        const double fi = std::floor((x - g_.x0_mm) / g_.cell_mm), fj = std::floor((y - g_.y0_mm) / g_.cell_mm);
        if (fi < 0 || fj < 0 || fi >= g_.nx || fj >= g_.ny) return kernels::kEmptyHi;
        return top_.at(std::size_t(fj) * g_.nx + std::size_t(fi));
    }

    // Any column inside the ring radii [r0, r1] around (x, y) whose top is above z.
    bool material_above(double x, double y, double r0, double r1, double z) const {
        const double dr = std::max(g_.cell_mm, 0.5);
        for (double r = r0; r <= r1 + 1e-9; r += dr) {
            const int n = std::max(1, int(std::ceil(2 * std::numbers::pi * r / dr)));
            for (int k = 0; k < n; ++k) {
                const double a = 2 * std::numbers::pi * k / n;
                if (column_top(x + r * std::cos(a), y + r * std::sin(a)) > z) return true;
            }
            if (r1 - r0 < 1e-9) break;
        }
        return false;
    }

    // ---- motion walk ------------------------------------------------------------------------
    void interval(std::size_t i) {
        const double t0 = m_.t_s[i], h = m_.t_s[i + 1] - t0;
        if (!(h > 0)) return;
        const Vec3 p0 = position(i), p1 = position(i + 1);
        const double r0 = m_.spindle_rpm[i], r1 = m_.spindle_rpm[i + 1];
        const double vmax = std::max(norm3(m_.vx_mm_s[i], m_.vy_mm_s[i], m_.vz_mm_s[i]),
                                     norm3(m_.vx_mm_s[i + 1], m_.vy_mm_s[i + 1], m_.vz_mm_s[i + 1]));
        // The Hermite curve can leave the chord by about |v| h / 4 between samples.
        const double slack = 0.05 + 0.25 * vmax * h;
        const double reach = tool_.holder_radius_mm + slack;
        const float top = max_top(std::min(p0.x, p1.x) - reach, std::min(p0.y, p1.y) - reach,
                                  std::max(p0.x, p1.x) + reach, std::max(p0.y, p1.y) + reach);
        if (top <= std::min(p0.z, p1.z) - slack) {
            flush_batch();
            remove_all_pending();
            coarse_row(i, false);
            return;
        }
        if (std::abs(r0) < 1 || std::abs(r1) < 1 || r0 * r1 < 0) {
            // No chip thickness without rotation: the cutter is pushed, not cutting. Flag it when
            // it is in material; the stock is still removed so later blocks see the crash's result.
            flush_batch();
            complete();
            add_pending(p0);
            add_pending(p1);
            const bool in_material = material_above(p0.x, p0.y, 0, tool_.radius_mm, p0.z + 1e-3) ||
                                     material_above(p1.x, p1.y, 0, tool_.radius_mm, p1.z + 1e-3);
            coarse_row(i, in_material);
            return;
        }
        angle_steps(i);
    }

    void coarse_row(std::size_t i, bool stopped_in_material) {
        ForceSample s;
        s.t_s = m_.t_s[i];
        s.spindle_angle_deg = m_.spindle_angle_deg[i];
        s.block = m_.block[i];
        rows.push_back(s);
        RowExtra x;
        x.feed_mm_min = float(norm3(m_.vx_mm_s[i], m_.vy_mm_s[i], m_.vz_mm_s[i]) * 60);
        x.stopped_in_material = stopped_in_material;
        x.spindle_rpm = float(m_.spindle_rpm[i]);
        extra.push_back(x);
    }

    void angle_steps(std::size_t i) {
        const double t0 = m_.t_s[i], h = m_.t_s[i + 1] - t0;
        const double a0 = m_.spindle_angle_deg[i], a1 = m_.spindle_angle_deg[i + 1];
        const double r0 = m_.spindle_rpm[i], r1 = m_.spindle_rpm[i + 1];
        const double step = spec_.resolution.angle_step_deg;
        const double spin = r0 > 0 ? 1.0 : -1.0;
        double k = spin > 0 ? std::ceil(a0 / step) : std::floor(a0 / step);
        if (spin > 0 ? k * step >= a1 : k * step <= a1) return;   // no step in this interval
        if (batch_.size() > 0 && spin != batch_.spin) flush_batch();
        // angle(dt) - a0 = qa dt^2 + qb dt (spindle speed linear between samples).
        const double qa = 3 * (r1 - r0) / h, qb = 6 * r0;
        const bool constant_speed = std::abs(qa) * h * h < 1e-9 * std::abs(qb) * h;
        // The motion's cubic Hermite as polynomials in u = dt / h:
        // position c0 + c1 u + c2 u^2 + c3 u^3, velocity d0 + d1 u + d2 u^2.
        const double inv_h = 1 / h;
        double c0[3], c1[3], c2[3], c3[3], d1[3], d2[3], d0[3];
        const std::vector<double>* P[3] = {&m_.x_mm, &m_.y_mm, &m_.z_mm};
        const std::vector<double>* V[3] = {&m_.vx_mm_s, &m_.vy_mm_s, &m_.vz_mm_s};
        for (int c = 0; c < 3; ++c) {
            const motion_io::HermiteSegment seg{(*P[c])[i] + spec_.offset_mm[c], (*V[c])[i],
                                                (*P[c])[i + 1] + spec_.offset_mm[c], (*V[c])[i + 1], h};
            const auto poly = seg.coefficients();
            c0[c] = poly[0];
            c1[c] = poly[1];
            c2[c] = poly[2];
            c3[c] = poly[3];
            d0[c] = seg.v0;
            d1[c] = 2 * c2[c] * inv_h;
            d2[c] = 3 * c3[c] * inv_h;
        }
        const double tooth_factor = 60.0 / spec_.tool.flutes;
        const double per_tooth_const = tooth_factor / std::abs(r0);
        // cos and sin of A = pi/2 - theta for successive steps by rotation: the steps are exactly one
        // angle step apart. Seeded in double from the reduced angle, so the error stays at rounding.
        const double a_start = std::remainder(std::numbers::pi / 2 - k * step * std::numbers::pi / 180, 2 * std::numbers::pi);
        double cos_a = std::cos(a_start), sin_a = std::sin(a_start);
        const double rot_c = std::cos(step * std::numbers::pi / 180), rot_s = -spin * std::sin(step * std::numbers::pi / 180);
        const double inv_qb = 1 / qb;
        const std::int32_t block0 = m_.block[i], block1 = m_.block[i + 1];
        for (;; k += spin) {
            const double ak = k * step;
            if (spin > 0 ? ak >= a1 : ak <= a1) break;
            const double da = ak - a0;
            double dt;
            if (constant_speed) {
                dt = da * inv_qb;
            } else {
                const double disc = std::max(0.0, qb * qb + 4 * qa * da);
                dt = 2 * da / (qb + std::copysign(std::sqrt(disc), qb));
            }
            dt = std::clamp(dt, 0.0, h);
            const double u = dt * inv_h;
            const Vec3 pos{((c3[0] * u + c2[0]) * u + c1[0]) * u + c0[0], ((c3[1] * u + c2[1]) * u + c1[1]) * u + c0[1],
                           ((c3[2] * u + c2[2]) * u + c1[2]) * u + c0[2]};
            const Vec3 vel{(d2[0] * u + d1[0]) * u + d0[0], (d2[1] * u + d1[1]) * u + d0[1],
                           (d2[2] * u + d1[2]) * u + d0[2]};
            const double rpm = r0 + (r1 - r0) * u;
            const std::int32_t block = u < 0.5 ? block0 : block1;
            const double speed = norm3(vel.x, vel.y, vel.z);
            // Batch boundaries: block change, full batch, or the feed direction turned (the stock
            // is only updated between batches; see docs/force_model.md, "Stock lag").
            if (batch_.size() > 0) {
                bool cut = block != batch_block_ || batch_.size() >= set_.max_batch_steps;
                // A turn only ends the batch once the tool has moved a grid cell since it began: the
                // flush could not change the stock before that (removal trails by several cells), so
                // a sharp corner does not splinter into one-step batches.
                if (!cut && speed > kMovingSpeed_mm_s && has_dir_ &&
                    vel.x * dir_.x + vel.y * dir_.y + vel.z * dir_.z < cos_turn_ * speed) {
                    const double dx = pos.x - batch_.tip_x.front(), dy = pos.y - batch_.tip_y.front(),
                                 dz = pos.z - batch_.tip_z.front();
                    cut = dx * dx + dy * dy + dz * dz >= g_.cell_mm * g_.cell_mm;
                }
                if (cut) flush_batch();
            }
            if (batch_.size() == 0) {
                batch_block_ = block;
                batch_.spin = spin;
                has_dir_ = false;
            }
            if (!has_dir_ && speed > kMovingSpeed_mm_s) {
                dir_ = {vel.x / speed, vel.y / speed, vel.z / speed};
                has_dir_ = true;
            }
            const double per_tooth = constant_speed ? per_tooth_const : tooth_factor / std::abs(rpm);
            batch_.tip_x.push_back(pos.x);
            batch_.tip_y.push_back(pos.y);
            batch_.tip_z.push_back(pos.z);
            batch_.feed_x.push_back(vel.x * per_tooth);
            batch_.feed_y.push_back(vel.y * per_tooth);
            batch_.feed_z.push_back(vel.z * per_tooth);
            batch_.theta_rad.push_back(ak * (std::numbers::pi / 180));
            batch_.cos_a.push_back(cos_a);
            batch_.sin_a.push_back(sin_a);
            const double c_next = cos_a * rot_c - sin_a * rot_s;
            sin_a = sin_a * rot_c + cos_a * rot_s;
            cos_a = c_next;
            meta_.push_back({t0 + dt, ak, speed * 60, rpm, block});
        }
    }

    // ---- batches ----------------------------------------------------------------------------
    // Queues the batch's engagement and the removal of the pending path up to the lag behind it,
    // after completing the batch before it.
    void flush_batch() {
        const std::size_t n = batch_.size();
        if (n == 0) return;
        complete();
        steps += n;
        InFlight& f = fly_;
        const double R = tool_.radius_mm;
        f.x0 = f.y0 = 1e300;
        f.x1 = f.y1 = -1e300;
        f.zmin = 1e300;
        for (std::size_t k = 0; k < n; ++k) {
            f.x0 = std::min(f.x0, batch_.tip_x[k]);
            f.x1 = std::max(f.x1, batch_.tip_x[k]);
            f.y0 = std::min(f.y0, batch_.tip_y[k]);
            f.y1 = std::max(f.y1, batch_.tip_y[k]);
            f.zmin = std::min(f.zmin, batch_.tip_z[k]);
        }
        // Elements higher than the highest material under the batch cannot engage: skip them.
        const double reach = double(max_top(f.x0 - R, f.y0 - R, f.x1 + R, f.y1 + R)) - f.zmin;
        const auto& zlo = tool_.edges.z_lo_mm;
        params_.element_end = reach > 0 ? int(std::lower_bound(zlo.begin(), zlo.end(), reach) - zlo.begin()) : 0;
        f.results.assign(n, kernels::StepResult{});
        if (params_.element_end > 0) {
            ++phases_.batches;
            PhaseTimer timer(phases_.queue_s);
            be_.engage(batch_, params_, f.results.data());
        }
        for (std::size_t k = 0; k < n; ++k) add_pending({batch_.tip_x[k], batch_.tip_y[k], batch_.tip_z[k]}, k + 1 == n);
        queue_removal(true);
        std::swap(f.steps, batch_);
        std::swap(f.meta, meta_);
        f.has_batch = true;
        f.active = true;
        batch_.clear();
        meta_.clear();
    }

    // Waits for the batch in flight and applies its results: rows, removed volume, stock tops,
    // holder checks.
    void complete() {
        InFlight& f = fly_;
        if (!f.active) return;
        {
            PhaseTimer timer(phases_.wait_s);
            be_.wait();
        }
        const std::size_t first_row = rows.size();
        if (f.has_batch) append_rows(f);
        const double removed = apply_removal(f);
        if (f.has_batch && f.steps.size() > 0) {
            const auto share = float(removed / double(f.steps.size()));
            for (std::size_t k = first_row; k < rows.size(); ++k) rows[k].removed_mm3 = share;
            PhaseTimer timer(phases_.holder_s);
            check_holder(f, first_row);
        } else if (!rows.empty()) {
            rows.back().removed_mm3 += float(removed);   // the tail of the path, removed at a stop
        }
        f.active = f.has_batch = false;
        f.steps.clear();
        f.meta.clear();
        f.calls.clear();
        f.segs.clear();
        report_progress();
    }

    void append_rows(const InFlight& f) {
        PhaseTimer timer(phases_.rows_s);
        const std::size_t n = f.steps.size();
        for (std::size_t k = 0; k < n; ++k) {
            const kernels::StepResult& r = f.results[k];
            const StepMeta& mt = f.meta[k];
            ForceSample s;
            s.t_s = mt.t_s;
            s.spindle_angle_deg = mt.angle_deg;
            s.block = mt.block;
            s.fx_N = r.fx_N;
            s.fy_N = r.fy_N;
            s.fz_N = r.fz_N;
            s.torque_Nm = r.torque_Nmm / 1000;
            s.power_kW = float(double(s.torque_Nm) * 2 * std::numbers::pi * std::abs(mt.rpm) / 60 / 1000);
            s.chip_mm = r.chip_mm;
            s.bending_MPa = float(std::sqrt(double(r.mx_Nmm) * r.mx_Nmm + double(r.my_Nmm) * r.my_Nmm) / section_modulus_mm3_);
            s.radial_engagement_mm = r.q_max_mm - r.q_min_mm;
            s.axial_engagement_mm = r.z_max_mm - r.z_min_mm;
            rows.push_back(s);
            RowExtra x;
            x.feed_mm_min = float(mt.feed_mm_min);
            x.engaged = r.engaged;
            x.spindle_rpm = float(mt.rpm);
            extra.push_back(x);
        }
    }

    void check_holder(const InFlight& f, std::size_t first_row) {
        const double Rh = tool_.holder_radius_mm;
        if (max_top(f.x0 - Rh, f.y0 - Rh, f.x1 + Rh, f.y1 + Rh) <= f.zmin + tool_.flute_length_mm) return;
        const std::size_t n = f.steps.size();
        for (std::size_t k = 0; k < n; k += kHolderCheckStride) {
            const double x = f.steps.tip_x[k], y = f.steps.tip_y[k], z = f.steps.tip_z[k];
            const bool contact =
                material_above(x, y, 0, tool_.radius_mm * 0.98, z + tool_.flute_length_mm + 1e-3) ||
                material_above(x, y, tool_.radius_mm, Rh, z + tool_.stickout_mm + 1e-3);
            if (!contact) continue;
            for (std::size_t r = k; r < std::min(n, k + kHolderCheckStride); ++r) rows[first_row + r].holder_contact = true;
        }
    }

    void report_progress() {
        if (opt_.cancel && opt_.cancel->load()) throw Cancelled();
        if (!opt_.progress) return;
        const double f = double(current_ + 1) / double(m_.size());
        if (f - last_progress_ >= 0.005 || f >= 1.0) {
            last_progress_ = f;
            opt_.progress(f);
        }
    }

    // ---- lagged removal ---------------------------------------------------------------------
    // The pending tip path, thinned to half a cell (the sweep is exact per segment anyway); s_mm is
    // the length along the thinned polyline.
    void add_pending(const Vec3& p, bool force = true) {
        if (pending_.empty()) {
            pending_.push_back({p, path_mm_});
            return;
        }
        const Vec3& q = pending_.back().p;
        const double d2 = (p.x - q.x) * (p.x - q.x) + (p.y - q.y) * (p.y - q.y) + (p.z - q.z) * (p.z - q.z);
        if (!force && d2 < 0.25 * g_.cell_mm * g_.cell_mm) return;
        path_mm_ += std::sqrt(d2);
        pending_.push_back({p, path_mm_});
    }

    // Completes what is in flight, then removes the whole pending path (the tool stops or leaves).
    void remove_all_pending() {
        complete();
        queue_removal(false);
        complete();
    }

    // Queues the removal of the swept volume of the pending path into the in-flight slot; with
    // keep_lag, the last lag_mm_ of travel stays pending.
    void queue_removal(bool keep_lag) {
        if (pending_.empty()) return;
        std::optional<PhaseTimer> timer(std::in_place, phases_.removal_s);
        std::size_t last = pending_.size() - 1;
        if (keep_lag) {
            const double s_cut = pending_.back().s_mm - lag_mm_;
            std::size_t m = 0;
            while (m + 1 < pending_.size() && pending_[m + 1].s_mm <= s_cut) ++m;
            if (m == 0) return;
            last = m;
        }
        InFlight& f = fly_;
        std::size_t call_begin = f.segs.size();
        double call_len = 0;
        auto emit = [&] {
            if (f.segs.size() > call_begin) add_call(call_begin);
            call_begin = f.segs.size();
            call_len = 0;
        };
        if (last == 0) {
            const Vec3& p = pending_[0].p;
            f.segs.push_back({p.x, p.y, p.z, p.x, p.y, p.z});
            emit();
        }
        std::size_t a = 0;
        while (a < last) {
            const std::size_t b = chord_end(a, last);
            const Vec3 &pa = pending_[a].p, &pb = pending_[b].p;
            f.segs.push_back({pa.x, pa.y, pa.z, pb.x, pb.y, pb.z});
            call_len += dist(pa, pb);
            if (call_len > 4 * tool_.radius_mm || f.segs.size() - call_begin >= 64) emit();
            a = b;
        }
        emit();
        if (keep_lag) pending_.erase(pending_.begin(), pending_.begin() + std::ptrdiff_t(last));
        else pending_.clear();
        if (f.calls.empty()) return;
        std::size_t cells = 0;
        for (const auto& c : f.calls) cells += c.cells();
        f.sweep_out.resize(cells);
        phases_.sweeps += f.calls.size();
        f.active = true;
        timer.emplace(phases_.queue_s);
        be_.sweep(f.segs, f.calls, sweep_, f.sweep_out.data());
    }

    // Segments [first, end) become one removal call over the cells they can reach, unless no
    // material there rises above the tip (by the stock tops as of the last completion).
    void add_call(std::size_t first) {
        InFlight& f = fly_;
        const double R = tool_.radius_mm + g_.cell_mm;
        double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300, zmin = 1e300;
        for (std::size_t k = first; k < f.segs.size(); ++k) {
            const auto& s = f.segs[k];
            x0 = std::min({x0, s.ax, s.bx});
            x1 = std::max({x1, s.ax, s.bx});
            y0 = std::min({y0, s.ay, s.by});
            y1 = std::max({y1, s.ay, s.by});
            zmin = std::min({zmin, s.az, s.bz});
        }
        int i0, j0, i1, j1;
        if (!cell_rect(x0 - R, y0 - R, x1 + R, y1 + R, i0, j0, i1, j1) ||
            max_top(x0 - R, y0 - R, x1 + R, y1 + R) <= zmin) {
            f.segs.resize(first);   // nothing there to cut
            return;
        }
        kernels::SweepCall c;
        c.first_segment = first;
        c.segments = f.segs.size() - first;
        c.i0 = i0;
        c.j0 = j0;
        c.width = i1 - i0;
        c.height = j1 - j0;
        f.calls.push_back(c);
    }

    // Applies the removal results to the top map and tiles; returns the volume removed.
    double apply_removal(const InFlight& f) {
        if (f.calls.empty()) return 0;
        PhaseTimer timer(phases_.removal_s);
        double removed_len = 0;
        const kernels::SweepCellResult* r = f.sweep_out.data();
        for (const kernels::SweepCall& c : f.calls) {
            for (int jj = 0; jj < c.height; ++jj)
                for (int ii = 0; ii < c.width; ++ii, ++r) {
                    removed_len += r->removed_mm;
                    top_.set(std::size_t(c.j0 + jj) * g_.nx + std::size_t(c.i0 + ii), r->top_mm);
                }
            refresh_tiles(c.i0, c.j0, c.i0 + c.width, c.j0 + c.height);
        }
        return removed_len * g_.cell_mm * g_.cell_mm;
    }

    // Simplification: the farthest point b <= last (at most kMaxChordPoints on) such that every
    // point between a and b stays within the chord tolerance of the chord and the chord is short
    // (tight cell rectangles). Binary search: a check costs O(b - a), so growing one point at a time
    // would be quadratic.
    std::size_t chord_end(std::size_t a, std::size_t last) const {
        std::size_t good = a + 1, bad = std::min(last, a + kMaxChordPoints) + 1;
        if (chord_ok(a, bad - 1)) return bad - 1;
        while (bad - good > 1) {
            const std::size_t mid = good + (bad - good) / 2;
            (chord_ok(a, mid) ? good : bad) = mid;
        }
        return good;
    }

    bool chord_ok(std::size_t a, std::size_t b) const {
        const Vec3 &pa = pending_[a].p, &pb = pending_[b].p;
        const double len = dist(pa, pb);
        if (len > 2 * tool_.radius_mm) return false;
        if (len < 1e-12) return true;
        const double tol = set_.chord_tolerance_cells * g_.cell_mm;
        const double ux = (pb.x - pa.x) / len, uy = (pb.y - pa.y) / len, uz = (pb.z - pa.z) / len;
        for (std::size_t k = a + 1; k < b; ++k) {
            const Vec3& p = pending_[k].p;
            const double wx = p.x - pa.x, wy = p.y - pa.y, wz = p.z - pa.z;
            const double along = wx * ux + wy * uy + wz * uz;
            const double off2 = wx * wx + wy * wy + wz * wz - along * along;
            if (off2 > tol * tol) return false;
        }
        return true;
    }

    const motion_io::MotionModel& m_;
    const RunSpec& spec_;
    const PredictOptions& opt_;
    const EngineSettings& set_;
    Backend& be_;
    const ToolGeometry& tool_;
    const kernels::GridInfo g_;
    EnginePhases& phases_;

    TopMap top_;
    std::vector<float> tile_max_;
    std::uint64_t tiles_version_ = 0;   // bumped whenever tile_max_ changes
    std::array<int, 4> memo_tiles_{-1, -1, -1, -1};
    std::uint64_t memo_version_ = 0;
    float memo_top_ = 0;
    int tiles_x_ = 0, tiles_y_ = 0;
    double lag_mm_ = 0.4, cos_turn_ = 1, section_modulus_mm3_ = 1;
    std::size_t current_ = 0;   // motion interval being walked (progress)
    double last_progress_ = -1;

    kernels::StepBatch batch_;   // the batch being walked
    std::vector<StepMeta> meta_;
    InFlight fly_;               // the batch (and removal) queued on the backend
    std::int32_t batch_block_ = -1;
    bool has_dir_ = false;
    Vec3 dir_;
    kernels::EngageParams params_;
    kernels::SweepParams sweep_;

    std::vector<PathPoint> pending_;
    double path_mm_ = 0;
};

void check_inputs(const motion_io::MotionModel& m, const RunSpec& spec) {
    const std::size_t n = m.size();
    for (const auto* v : {&m.x_mm, &m.y_mm, &m.z_mm, &m.vx_mm_s, &m.vy_mm_s, &m.vz_mm_s, &m.spindle_rpm,
                          &m.spindle_angle_deg})
        if (v->size() != n) throw std::invalid_argument("predict: motion model channels have different lengths");
    if (m.block.size() != n) throw std::invalid_argument("predict: motion model block channel has a different length");
    if (!(spec.resolution.angle_step_deg > 0) || !(spec.resolution.axial_step_mm > 0) || !(spec.resolution.grid_mm > 0))
        throw SpecError("resolution: steps must be > 0");
    if (spec.tool.flutes < 1) throw SpecError("tool.flutes: must be >= 1");
    for (std::size_t s = 0; s < m.session_start.size(); ++s) {
        const std::size_t i = m.session_start[s];
        if (i >= std::max<std::size_t>(n, 1) || (s > 0 && i <= m.session_start[s - 1]))
            throw std::invalid_argument("predict: motion model session_start[" + std::to_string(s) + "] = " +
                                        std::to_string(i) + " is out of order or past the " + std::to_string(n) +
                                        " samples");
    }
}


}  // namespace

Prediction predict_with(const motion_io::MotionModel& motion, const RunSpec& spec, const PredictOptions& opt,
                        const EngineSettings& settings, EnginePhases* phases_out) {
    check_inputs(motion, spec);
    const auto wall0 = Clock::now();
    EnginePhases phases;
    std::optional<PhaseTimer> setup_timer(std::in_place, phases.setup_s);
    const ToolGeometry tool = build_tool_geometry(spec.tool, spec.resolution.axial_step_mm);
    const bool fresh = opt.base_stock == nullptr;
    StockPtr stock = fresh ? make_stock(spec.stock, spec.resolution.grid_mm) : copy_stock(*opt.base_stock);
    std::unique_ptr<Backend> backend =
        opt.device == Device::OpenCL ? make_opencl_backend(*stock, tool) : make_cpu_backend(*stock, tool);
    Engine engine(motion, spec, opt, settings, *stock, fresh, *backend, tool, phases);
    setup_timer.reset();

    {
        PhaseTimer timer(phases.walk_s);
        engine.run();
    }
    Prediction p;
    {
        PhaseTimer timer(phases.finish_s);
        backend->download(*stock);
        p.block_names = motion.block_names;
        p.blocks = summarise_blocks(motion, engine.rows, engine.extra, spec.limits);
        p.samples = std::move(engine.rows);
        p.final_stock = std::move(stock);
        p.stats.simulated_s = simulated_seconds(motion);
        p.stats.steps = engine.steps;
        for (const RowExtra& x : engine.extra) p.stats.cutting_steps += x.engaged > 0 ? 1 : 0;
        p.stats.device = backend->name();
        backend.reset();
    }
    // The walk's own share: what the timed phases inside it leave over (step generation, batching,
    // air checks).
    phases.walk_s -= phases.queue_s + phases.wait_s + phases.rows_s + phases.removal_s + phases.holder_s;
    p.stats.wall_s = std::chrono::duration<double>(Clock::now() - wall0).count();
    phases.total_s = p.stats.wall_s;
    if (phases_out) *phases_out = phases;
    if (opt.progress) opt.progress(1.0);
    return p;
}

Prediction predict(const motion_io::MotionModel& motion, const RunSpec& spec, const PredictOptions& opt) {
    return predict_with(motion, spec, opt, EngineSettings{});
}

}  // namespace cutload::force_model
