// The force engine's driver: walks the motion model, cuts it into batches of angle steps, runs the
// engagement backend on each batch, removes the swept volume with a lag, and collects rows.
//
// Time steps: one per angle_step_deg of spindle rotation (the log's own spindle angle). Intervals
// where the tool cannot reach material (coarse tile map of stock tops) are written one row per
// motion sample and never evaluated per angle step. See docs/force_model.md.
#include "force_model/engine.hpp"
#include "force_model/summary.hpp"
#include "kernels/opencl_runtime.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>

namespace cutload::force_model {

namespace {

using kernels::kDexelFloats;

constexpr int kTile = 16;                 // cells per side of a tile of the coarse max-top map
constexpr double kMovingSpeed_mm_s = 0.5; // slower moves have no meaningful direction
constexpr std::size_t kHolderCheckStride = 16;
constexpr std::size_t kMaxChordPoints = 128;   // bounds the quadratic chord check

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

class Engine {
public:
    Engine(const motion_io::MotionModel& m, const RunSpec& spec, const PredictOptions& opt, const EngineSettings& set,
           Stock& stock, Backend& backend, const ToolGeometry& tool)
        : m_(m), spec_(spec), opt_(opt), set_(set), stock_(stock), be_(backend), tool_(tool), g_(stock.grid) {
        top_.resize(std::size_t(g_.nx) * g_.ny);
        for (std::size_t r = 0; r < top_.size(); ++r) top_[r] = kernels::ray_top(stock.cells.data() + r * kDexelFloats);
        tiles_x_ = (g_.nx + kTile - 1) / kTile;
        tiles_y_ = (g_.ny + kTile - 1) / kTile;
        tile_max_.assign(std::size_t(tiles_x_) * tiles_y_, kernels::kEmptyHi);
        refresh_tiles(0, 0, g_.nx, g_.ny);
        lag_mm_ = set.removal_lag_cells * g_.cell_mm;
        cos_turn_ = std::cos(set.batch_turn_deg * std::numbers::pi / 180);
        params_.k = {spec.material.Ktc_N_mm2, spec.material.Krc_N_mm2, spec.material.Kac_N_mm2,
                     spec.material.Kte_N_mm,  spec.material.Kre_N_mm,  spec.material.Kae_N_mm};
        params_.holder_face_z_mm = tool.stickout_mm;
        params_.min_chip_mm = set.min_chip_mm;
        sweep_.lower_mm = tool.lower_mm;
        sweep_.radius_mm = tool.radius_mm;
        sweep_.cut_length_mm = tool.flute_length_mm;
        batch_.reserve(set.max_batch_steps);
        const double d = 2 * tool.radius_mm;
        section_modulus_mm3_ = std::numbers::pi * d * d * d / 32;
    }

    void run() {
        if (m_.size() < 2) return;
        t_begin_ = m_.t_s.front();
        t_span_ = std::max(1e-9, m_.t_s.back() - t_begin_);
        std::vector<std::size_t> starts = m_.session_start;
        if (starts.empty() || starts.front() != 0) starts.insert(starts.begin(), 0);
        for (std::size_t s = 0; s < starts.size(); ++s) {
            const std::size_t b = starts[s], e = s + 1 < starts.size() ? starts[s + 1] : m_.size();
            for (std::size_t i = b; i + 1 < e; ++i) interval(i);
            flush_batch();
            remove_pending(false);
        }
    }

    std::vector<ForceSample> rows;
    std::vector<RowExtra> extra;
    std::size_t steps = 0;

private:
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
                        mx = std::max(mx, top_[std::size_t(j) * g_.nx + i]);
                tile_max_[std::size_t(tj) * tiles_x_ + ti] = mx;
            }
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

    float max_top(double x0, double y0, double x1, double y1) const {
        int i0, j0, i1, j1;
        if (!cell_rect(x0, y0, x1, y1, i0, j0, i1, j1)) return kernels::kEmptyHi;
        float mx = kernels::kEmptyHi;
        for (int tj = j0 / kTile; tj <= (j1 - 1) / kTile; ++tj)
            for (int ti = i0 / kTile; ti <= (i1 - 1) / kTile; ++ti)
                mx = std::max(mx, tile_max_[std::size_t(tj) * tiles_x_ + ti]);
        return mx;
    }

    float column_top(double x, double y) const {
        const double fi = std::floor((x - g_.x0_mm) / g_.cell_mm), fj = std::floor((y - g_.y0_mm) / g_.cell_mm);
        if (fi < 0 || fj < 0 || fi >= g_.nx || fj >= g_.ny) return kernels::kEmptyHi;
        return top_[std::size_t(fj) * g_.nx + std::size_t(fi)];
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
        const double vmax = std::max(std::hypot(m_.vx_mm_s[i], m_.vy_mm_s[i], m_.vz_mm_s[i]),
                                     std::hypot(m_.vx_mm_s[i + 1], m_.vy_mm_s[i + 1], m_.vz_mm_s[i + 1]));
        // The Hermite curve can leave the chord by about |v| h / 4 between samples.
        const double slack = 0.05 + 0.25 * vmax * h;
        const double reach = tool_.holder_radius_mm + slack;
        const float top = max_top(std::min(p0.x, p1.x) - reach, std::min(p0.y, p1.y) - reach,
                                  std::max(p0.x, p1.x) + reach, std::max(p0.y, p1.y) + reach);
        if (top <= std::min(p0.z, p1.z) - slack) {
            flush_batch();
            remove_pending(false);
            coarse_row(i, false);
            return;
        }
        if (std::abs(r0) < 1 || std::abs(r1) < 1 || r0 * r1 < 0) {
            // No chip thickness without rotation: the cutter is pushed, not cutting. Flag it when
            // it is in material; the stock is still removed so later blocks see the crash's result.
            flush_batch();
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
        x.feed_mm_min = float(std::hypot(m_.vx_mm_s[i], m_.vy_mm_s[i], m_.vz_mm_s[i]) * 60);
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
        const double qa = 3 * (r1 - r0) / h, qb = 6 * r0;   // angle(dt) - a0 = qa dt^2 + qb dt
        double p0[3], p1[3], v0[3], v1[3];
        const std::vector<double>* P[3] = {&m_.x_mm, &m_.y_mm, &m_.z_mm};
        const std::vector<double>* V[3] = {&m_.vx_mm_s, &m_.vy_mm_s, &m_.vz_mm_s};
        for (int k = 0; k < 3; ++k) {
            p0[k] = (*P[k])[i] + spec_.offset_mm[k];
            p1[k] = (*P[k])[i + 1] + spec_.offset_mm[k];
            v0[k] = (*V[k])[i];
            v1[k] = (*V[k])[i + 1];
        }
        const double tooth_factor = 60.0 / spec_.tool.flutes;
        double k = spin > 0 ? std::ceil(a0 / step) : std::floor(a0 / step);
        for (;; k += spin) {
            const double ak = k * step;
            if (spin > 0 ? ak >= a1 : ak <= a1) break;
            const double da = ak - a0;
            double dt;
            if (std::abs(qa) * h * h < 1e-9 * std::abs(qb) * h) {
                dt = da / qb;
            } else {
                const double disc = std::max(0.0, qb * qb + 4 * qa * da);
                dt = 2 * da / (qb + std::copysign(std::sqrt(disc), qb));
            }
            dt = std::clamp(dt, 0.0, h);
            // Same cubic Hermite as motion_io::sample_between, evaluated with the interval's data
            // hoisted out of the loop.
            const double u = dt / h, u2 = u * u, u3 = u2 * u;
            const double h00 = 2 * u3 - 3 * u2 + 1, h10 = u3 - 2 * u2 + u, h01 = -2 * u3 + 3 * u2, h11 = u3 - u2;
            const double d00 = 6 * u2 - 6 * u, d10 = 3 * u2 - 4 * u + 1, d01 = -6 * u2 + 6 * u, d11 = 3 * u2 - 2 * u;
            Vec3 pos, vel;
            double* pp[3] = {&pos.x, &pos.y, &pos.z};
            double* vv[3] = {&vel.x, &vel.y, &vel.z};
            for (int c = 0; c < 3; ++c) {
                *pp[c] = h00 * p0[c] + h10 * h * v0[c] + h01 * p1[c] + h11 * h * v1[c];
                *vv[c] = (d00 * p0[c] + d01 * p1[c]) / h + d10 * v0[c] + d11 * v1[c];
            }
            const double rpm = r0 + (r1 - r0) * u;
            const std::int32_t block = u < 0.5 ? m_.block[i] : m_.block[i + 1];
            const double speed = norm3(vel.x, vel.y, vel.z);
            // Batch boundaries: block change, full batch, or the feed direction turned (the stock
            // is only updated between batches; see docs/force_model.md, "Stock lag").
            if (batch_.size() > 0) {
                bool cut = block != batch_block_ || batch_.size() >= set_.max_batch_steps;
                if (!cut && speed > kMovingSpeed_mm_s && has_dir_)
                    cut = (vel.x * dir_.x + vel.y * dir_.y + vel.z * dir_.z) / speed < cos_turn_;
                if (cut) flush_batch();
            }
            if (batch_.size() == 0) {
                batch_block_ = block;
                has_dir_ = false;
            }
            if (!has_dir_ && speed > kMovingSpeed_mm_s) {
                dir_ = {vel.x / speed, vel.y / speed, vel.z / speed};
                has_dir_ = true;
            }
            const double per_tooth = tooth_factor / std::abs(rpm);
            batch_.tip_x.push_back(pos.x);
            batch_.tip_y.push_back(pos.y);
            batch_.tip_z.push_back(pos.z);
            batch_.feed_x.push_back(vel.x * per_tooth);
            batch_.feed_y.push_back(vel.y * per_tooth);
            batch_.feed_z.push_back(vel.z * per_tooth);
            batch_.theta_rad.push_back(ak * std::numbers::pi / 180);
            batch_.spin.push_back(spin);
            meta_.push_back({t0 + dt, ak, speed * 60, rpm, block});
        }
    }

    // ---- batches ----------------------------------------------------------------------------
    void flush_batch() {
        const std::size_t n = batch_.size();
        if (n == 0) return;
        steps += n;
        const double R = tool_.radius_mm;
        double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300, zmin = 1e300;
        for (std::size_t k = 0; k < n; ++k) {
            x0 = std::min(x0, batch_.tip_x[k]);
            x1 = std::max(x1, batch_.tip_x[k]);
            y0 = std::min(y0, batch_.tip_y[k]);
            y1 = std::max(y1, batch_.tip_y[k]);
            zmin = std::min(zmin, batch_.tip_z[k]);
        }
        // Elements higher than the highest material under the batch cannot engage: skip them.
        const double reach = double(max_top(x0 - R, y0 - R, x1 + R, y1 + R)) - zmin;
        const auto& zlo = tool_.edges.z_lo_mm;
        params_.element_end = reach > 0 ? int(std::lower_bound(zlo.begin(), zlo.end(), reach) - zlo.begin()) : 0;
        results_.assign(n, kernels::StepResult{});
        if (params_.element_end > 0) be_.engage(batch_, params_, results_.data());

        const std::size_t first_row = rows.size();
        for (std::size_t k = 0; k < n; ++k) {
            const kernels::StepResult& r = results_[k];
            const StepMeta& mt = meta_[k];
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
        for (std::size_t k = 0; k < n; ++k)
            add_pending({batch_.tip_x[k], batch_.tip_y[k], batch_.tip_z[k]}, k + 1 == n);
        const double removed = remove_pending(true);
        for (std::size_t k = first_row; k < rows.size(); ++k) rows[k].removed_mm3 = float(removed / double(n));

        check_holder(first_row, x0, y0, x1, y1, zmin);
        batch_.clear();
        meta_.clear();
        report_progress(rows.back().t_s);
    }

    void check_holder(std::size_t first_row, double x0, double y0, double x1, double y1, double zmin) {
        const double Rh = tool_.holder_radius_mm;
        if (max_top(x0 - Rh, y0 - Rh, x1 + Rh, y1 + Rh) <= zmin + tool_.flute_length_mm) return;
        const std::size_t n = batch_.size();
        for (std::size_t k = 0; k < n; k += kHolderCheckStride) {
            const double x = batch_.tip_x[k], y = batch_.tip_y[k], z = batch_.tip_z[k];
            const bool contact =
                material_above(x, y, 0, tool_.radius_mm * 0.98, z + tool_.flute_length_mm + 1e-3) ||
                material_above(x, y, tool_.radius_mm, Rh, z + tool_.stickout_mm + 1e-3);
            if (!contact) continue;
            for (std::size_t r = k; r < std::min(n, k + kHolderCheckStride); ++r) rows[first_row + r].holder_contact = true;
        }
    }

    void report_progress(double t_s) {
        if (opt_.cancel && opt_.cancel->load()) throw Cancelled();
        if (!opt_.progress) return;
        const double f = std::clamp((t_s - t_begin_) / t_span_, 0.0, 1.0);
        if (f - last_progress_ >= 0.005 || f >= 1.0) {
            last_progress_ = f;
            opt_.progress(f);
        }
    }

    // ---- lagged removal ---------------------------------------------------------------------
    void add_pending(const Vec3& p, bool force = true) {
        if (pending_.empty()) {
            pending_.push_back({p, path_mm_});
            last_point_ = p;
            return;
        }
        path_mm_ += dist(p, last_point_);
        last_point_ = p;
        // Thin the polyline to half a cell: the sweep is exact per segment anyway.
        if (force || dist(p, pending_.back().p) >= 0.5 * g_.cell_mm) pending_.push_back({p, path_mm_});
    }

    // Removes the swept volume of the pending path; with keep_lag, the last lag_mm_ of travel stays
    // pending. Returns the volume removed.
    double remove_pending(bool keep_lag) {
        if (pending_.empty()) return 0;
        std::size_t last = pending_.size() - 1;
        if (keep_lag) {
            const double s_cut = pending_.back().s_mm - lag_mm_;
            std::size_t m = 0;
            while (m + 1 < pending_.size() && pending_[m + 1].s_mm <= s_cut) ++m;
            if (m == 0) return 0;
            last = m;
        }
        double removed = 0;
        std::vector<kernels::SweepSegment> call;
        double call_len = 0;
        std::size_t a = 0;
        auto emit = [&] {
            if (!call.empty()) removed += sweep(call);
            call.clear();
            call_len = 0;
        };
        if (last == 0) {
            const Vec3& p = pending_[0].p;
            call.push_back({p.x, p.y, p.z, p.x, p.y, p.z});
            emit();
        }
        while (a < last) {
            // Greedy simplification: extend the chord while every point in between stays within a
            // quarter cell of it and the chord stays short (tight cell rectangles).
            std::size_t b = a + 1;
            while (b + 1 <= last && b + 1 - a <= kMaxChordPoints && chord_ok(a, b + 1)) ++b;
            const Vec3 &pa = pending_[a].p, &pb = pending_[b].p;
            call.push_back({pa.x, pa.y, pa.z, pb.x, pb.y, pb.z});
            call_len += dist(pa, pb);
            if (call_len > 4 * tool_.radius_mm || call.size() >= 64) emit();
            a = b;
        }
        emit();
        if (keep_lag) pending_.erase(pending_.begin(), pending_.begin() + std::ptrdiff_t(last));
        else pending_.clear();
        return removed;
    }

    bool chord_ok(std::size_t a, std::size_t b) const {
        const Vec3 &pa = pending_[a].p, &pb = pending_[b].p;
        const double len = dist(pa, pb);
        if (len > 2 * tool_.radius_mm) return false;
        if (len < 1e-12) return true;
        const double tol = 0.25 * g_.cell_mm;
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

    double sweep(const std::vector<kernels::SweepSegment>& segs) {
        const double R = tool_.radius_mm + g_.cell_mm;
        double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300, zmin = 1e300;
        for (const auto& s : segs) {
            x0 = std::min({x0, s.ax, s.bx});
            x1 = std::max({x1, s.ax, s.bx});
            y0 = std::min({y0, s.ay, s.by});
            y1 = std::max({y1, s.ay, s.by});
            zmin = std::min({zmin, s.az, s.bz});
        }
        int i0, j0, i1, j1;
        if (!cell_rect(x0 - R, y0 - R, x1 + R, y1 + R, i0, j0, i1, j1)) return 0;
        if (max_top(x0 - R, y0 - R, x1 + R, y1 + R) <= zmin) return 0;   // nothing above the tip
        sweep_.i0 = i0;
        sweep_.j0 = j0;
        sweep_.width = i1 - i0;
        sweep_.height = j1 - j0;
        sweep_out_.resize(std::size_t(sweep_.width) * sweep_.height);
        be_.sweep(segs, sweep_, sweep_out_.data());
        double removed_len = 0;
        for (int jj = 0; jj < sweep_.height; ++jj)
            for (int ii = 0; ii < sweep_.width; ++ii) {
                const auto& r = sweep_out_[std::size_t(jj) * sweep_.width + ii];
                removed_len += r.removed_mm;
                top_[std::size_t(j0 + jj) * g_.nx + std::size_t(i0 + ii)] = r.top_mm;
            }
        refresh_tiles(i0, j0, i1, j1);
        return removed_len * g_.cell_mm * g_.cell_mm;
    }

    const motion_io::MotionModel& m_;
    const RunSpec& spec_;
    const PredictOptions& opt_;
    const EngineSettings& set_;
    Stock& stock_;
    Backend& be_;
    const ToolGeometry& tool_;
    const kernels::GridInfo g_;

    std::vector<float> top_, tile_max_;
    int tiles_x_ = 0, tiles_y_ = 0;
    double lag_mm_ = 0.4, cos_turn_ = 1, section_modulus_mm3_ = 1;
    double t_begin_ = 0, t_span_ = 1, last_progress_ = -1;

    kernels::StepBatch batch_;
    std::vector<StepMeta> meta_;
    std::vector<kernels::StepResult> results_;
    std::int32_t batch_block_ = -1;
    bool has_dir_ = false;
    Vec3 dir_;
    kernels::EngageParams params_;
    kernels::SweepParams sweep_;
    std::vector<kernels::SweepCellResult> sweep_out_;

    std::vector<PathPoint> pending_;
    Vec3 last_point_;
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
}

}  // namespace

Prediction predict_with(const motion_io::MotionModel& motion, const RunSpec& spec, const PredictOptions& opt,
                        const EngineSettings& settings) {
    check_inputs(motion, spec);
    const auto wall0 = std::chrono::steady_clock::now();
    const ToolGeometry tool = build_tool_geometry(spec.tool, spec.resolution.axial_step_mm);
    StockPtr stock = opt.base_stock ? copy_stock(*opt.base_stock) : make_stock(spec.stock, spec.resolution.grid_mm);
    std::unique_ptr<Backend> backend =
        opt.device == Device::OpenCL ? make_opencl_backend(*stock, tool) : make_cpu_backend(*stock, tool);

    Engine engine(motion, spec, opt, settings, *stock, *backend, tool);
    engine.run();
    backend->download(*stock);

    Prediction p;
    p.block_names = motion.block_names;
    p.blocks = summarise_blocks(motion, engine.rows, engine.extra, spec.limits, settings);
    p.samples = std::move(engine.rows);
    p.final_stock = std::move(stock);
    p.stats.simulated_s = motion.size() > 1 ? motion.t_s.back() - motion.t_s.front() : 0.0;
    p.stats.steps = engine.steps;
    for (const RowExtra& x : engine.extra) p.stats.cutting_steps += x.engaged > 0 ? 1 : 0;
    p.stats.device = backend->name();
    p.stats.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    if (opt.progress) opt.progress(1.0);
    return p;
}

Prediction predict(const motion_io::MotionModel& motion, const RunSpec& spec, const PredictOptions& opt) {
    return predict_with(motion, spec, opt, EngineSettings{});
}

}  // namespace cutload::force_model
