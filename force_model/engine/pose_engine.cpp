#include "engine/pose_engine.hpp"

#include <algorithm>
#include <cmath>

namespace cutload::force_model {

namespace {

using Mat = std::array<std::array<double, 3>, 3>;

// Angle of the rotation between two orientations: acos((trace(A^T B) - 1) / 2).
double turn_between_rad(const Mat& a, const Mat& b) {
    double trace = 0;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) trace += a[r][c] * b[r][c];
    return std::acos(std::clamp((trace - 1) / 2, -1.0, 1.0));
}

double distance_mm(const std::array<double, 3>& a, const std::array<double, 3>& b) {
    return std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
}

// Distance of p from the segment a-b.
double off_segment_mm(const std::array<double, 3>& p, const std::array<double, 3>& a, const std::array<double, 3>& b) {
    const std::array<double, 3> d{b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w{p[0] - a[0], p[1] - a[1], p[2] - a[2]};
    const double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    const double s = dd > 0 ? std::clamp((w[0] * d[0] + w[1] * d[1] + w[2] * d[2]) / dd, 0.0, 1.0) : 0.0;
    return std::hypot(w[0] - s * d[0], w[1] - s * d[1], w[2] - s * d[2]);
}

}  // namespace

PoseEngine::PoseEngine(kernels::TriDexel stock, const ToolGeometry& tool, kernels::ConvexToolSolid solid,
                       kernels::EngageParams params, PoseEngineSettings settings)
    : cell_mm_(stock.cell_mm),
      backend_(settings.opencl ? make_opencl_pose_backend(std::move(stock), tool.edges, std::move(solid), params)
                               : make_cpu_pose_backend(std::move(stock), tool.edges, std::move(solid), params)),
      settings_(settings),
      reach_mm_(std::hypot(tool.flute_length_mm, tool.radius_mm)) {
    body_.flute_length_mm = tool.flute_length_mm;
    body_.stickout_mm = tool.stickout_mm;
    // A spec without a holder ("no holder beyond the shank") still has something above the face
    // up to the spindle: taken as the cutter's width (ToolGeometry's holder radius then) for
    // another stickout, as the Z-map engine's check takes everything above the face.
    body_.holder_length_mm = tool.holder_length_mm > 0 ? tool.holder_length_mm : tool.stickout_mm;
    body_.shank_radius_mm = tool.shank_diameter_mm / 2;
    body_.holder_radius_mm = tool.holder_radius_mm;
    shell_mm_ = std::max(tool.holder_clearance_mm, 0.0);
    body_reach_mm_ = std::hypot(body_.stickout_mm + body_.holder_length_mm, body_.holder_radius_mm);
}

kernels::BodyClearance PoseEngine::body_at(const kernels::PoseStep& s) {
    const double every_mm = shell_mm_ > 0 ? std::min(settings_.holder_check_mm, shell_mm_ / 4) : settings_.holder_check_mm;
    // Within the spacing of the last check its result holds. Removal only takes material away, so
    // a result kept across a removal errs toward a flag, never past one.
    if (!checked_at_ || distance_mm(checked_at_->tip_mm, s.tip_mm) +
                                turn_between_rad(checked_at_->rot, s.rot) * body_reach_mm_ >= every_mm) {
        last_check_ = backend_->body_clearance(s.tip_mm, s.rot, body_, shell_mm_);
        checked_at_ = s;
        ++body_checks_;
    }
    return last_check_;
}

void PoseEngine::check_body(const std::vector<kernels::PoseStep>& steps, std::size_t b0, std::size_t b1,
                            std::vector<kernels::BodyClearance>& body) {
    for (std::size_t i = b0; i < b1; ++i) body[i] = body_at(steps[i]);
}

void PoseEngine::run(const std::vector<kernels::PoseStep>& steps, std::vector<kernels::StepResult>& out, double spin,
                     std::vector<kernels::BodyClearance>* body) {
    out.resize(steps.size());
    if (body) body->assign(steps.size(), {});
    const double lag_mm = settings_.lag_cells * cell_mm_;
    const double keep_mm = cell_mm_ / 20;
    std::size_t b0 = 0;
    while (b0 < steps.size()) {
        // A batch ends at batch_steps or at half the lag of travel, whichever comes first: every step
        // is engaged against a stock its own batch has not swept.
        std::size_t b1 = b0 + 1;
        double batch_travel = 0;
        while (b1 < steps.size() && b1 - b0 < settings_.batch_steps) {
            batch_travel += distance_mm(steps[b1 - 1].tip_mm, steps[b1].tip_mm) +
                            turn_between_rad(steps[b1 - 1].rot, steps[b1].rot) * reach_mm_;
            if (batch_travel > lag_mm / 2) break;
            ++b1;
        }
        // Against the stock the batch's engagement sees: the removal trails, so material the
        // flutes are still cutting is there, as it is for the Z-map engine's check.
        if (body) check_body(steps, b0, b1, *body);
        backend_->engage(steps.data() + b0, b1 - b0, spin, out.data() + b0);
        for (std::size_t i = b0; i < b1; ++i) {
            const kernels::PoseStep& s = steps[i];
            if (pending_.empty()) {
                pending_.push_back(s);
                travel_mm_.push_back(0);
                continue;
            }
            // Where both the last pose and this one lie within a twentieth of a cell of the one
            // before the last, this one replaces the last: the sweep keeps its shape (chords are
            // good to half a cell; a turning point dropped lies that close to a kept pose), and the
            // pending path holds about 20 poses a cell of travel however slowly the tool moves, or
            // while it dwells.
            const std::size_t n = pending_.size();
            if (n > 1) {
                const auto apart_mm = [&](const kernels::PoseStep& a, const kernels::PoseStep& b) {
                    return distance_mm(a.tip_mm, b.tip_mm) + turn_between_rad(a.rot, b.rot) * reach_mm_;
                };
                const double from_before = apart_mm(pending_[n - 2], s);
                if (from_before <= keep_mm && apart_mm(pending_[n - 2], pending_.back()) <= keep_mm) {
                    pending_.back() = s;
                    travel_mm_.back() = travel_mm_[n - 2] + from_before;
                    continue;
                }
            }
            const double step = distance_mm(pending_.back().tip_mm, s.tip_mm) + turn_between_rad(pending_.back().rot, s.rot) * reach_mm_;
            pending_.push_back(s);
            travel_mm_.push_back(travel_mm_.back() + step);
        }
        // Remove up to the last pose at least a lag of travel behind the batch's end.
        const double upto = travel_mm_.back() - lag_mm;
        // Each removal re-sweeps the tool's whole reach, whatever the travel it covers: it waits
        // until it covers removal_cells of travel.
        if (upto < settings_.removal_cells * cell_mm_) {
            b0 = b1;
            continue;
        }
        std::size_t last = 0;
        while (last + 1 < pending_.size() && travel_mm_[last + 1] <= upto) ++last;
        if (last > 0) remove_through(last);
        b0 = b1;
    }
}

void PoseEngine::finish() {
    if (pending_.size() > 1) remove_through(pending_.size() - 1);
    // The tool leaves (air, a stop, the session's end): the next path starts afresh, never swept
    // to from here.
    pending_.clear();
    travel_mm_.clear();
}

void PoseEngine::remove_through(std::size_t last) {
    const double tol_mm = settings_.chord_tolerance_cells * cell_mm_;
    std::vector<kernels::ToolChord> chords;
    std::size_t a = 0;
    while (a < last) {
        // Extend the chord while its orientation (the start's) and its straight tip stay within the
        // tolerance of every pose it covers.
        // At most 512 poses a chord: the straightness check looks at every pose it covers.
        std::size_t c = a + 1;
        while (c + 1 <= last && c + 1 - a <= 512) {
            const std::size_t next = c + 1;
            if (turn_between_rad(pending_[a].rot, pending_[next].rot) * reach_mm_ > tol_mm) break;
            bool straight = true;
            for (std::size_t k = a + 1; k < next && straight; ++k)
                straight = off_segment_mm(pending_[k].tip_mm, pending_[a].tip_mm, pending_[next].tip_mm) <= tol_mm;
            if (!straight) break;
            c = next;
        }
        kernels::ToolChord chord;
        chord.from_mm = pending_[a].tip_mm;
        chord.to_mm = pending_[c].tip_mm;
        chord.rot = pending_[a].rot;
        chords.push_back(chord);
        a = c;
    }
    const auto removed = backend_->sweep(chords.data(), chords.size());
    removed_mm3_ += removed[2];
    chords_ += chords.size();
    pending_.erase(pending_.begin(), pending_.begin() + std::ptrdiff_t(last));
    const double base = travel_mm_[last];
    travel_mm_.erase(travel_mm_.begin(), travel_mm_.begin() + std::ptrdiff_t(last));
    for (double& t : travel_mm_) t -= base;
}

}  // namespace cutload::force_model
