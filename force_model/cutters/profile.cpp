#include "cutters/profile.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

namespace cutload::force_model {

namespace {

// Joints and ranges match within this: profile points come from sums of radii and heights.
constexpr double kJoinMm = 1e-9;

[[noreturn]] void reject(std::size_t index, const std::string& why) {
    throw std::invalid_argument("cutter profile, segment " + std::to_string(index) + ": " + why);
}

void check_segment(const ProfileSegment& s, std::size_t index) {
    if (const auto* line = std::get_if<LineSegment>(&s)) {
        if (line->to.z_mm < line->from.z_mm) reject(index, "z falls along the profile");
        if (std::hypot(line->to.r_mm - line->from.r_mm, line->to.z_mm - line->from.z_mm) <= kJoinMm)
            reject(index, "empty line");
    } else {
        const auto& arc = std::get<ArcSegment>(s);
        if (!(arc.radius_mm > 0)) reject(index, "arc radius must be > 0");
        // z = centre_z - radius cos(kappa) rises only for kappa in [0, pi].
        if (!(arc.from_rad >= 0 && arc.from_rad < arc.to_rad && arc.to_rad <= std::numbers::pi + 1e-12))
            reject(index, "arc angles must satisfy 0 <= from < to <= pi (z falls otherwise)");
    }
    for (const ProfilePoint& p : {segment_start(s), segment_end(s)})
        if (p.r_mm < -kJoinMm) reject(index, "negative radius");
}

// Lowest height of the segment at distance r_mm from the axis; false when it does not reach r_mm.
bool segment_lowest_at(const ProfileSegment& s, double r_mm, double& z_mm) {
    if (const auto* line = std::get_if<LineSegment>(&s)) {
        const ProfilePoint a = line->from, b = line->to;
        if (r_mm < std::min(a.r_mm, b.r_mm) - kJoinMm || r_mm > std::max(a.r_mm, b.r_mm) + kJoinMm) return false;
        const double dr = b.r_mm - a.r_mm;
        z_mm = std::abs(dr) < kJoinMm ? std::min(a.z_mm, b.z_mm) : a.z_mm + (r_mm - a.r_mm) * (b.z_mm - a.z_mm) / dr;
        return true;
    }
    const auto& arc = std::get<ArcSegment>(s);
    const double half = std::numbers::pi / 2, rho = arc.radius_mm, u = r_mm - arc.centre_r_mm;
    const double off_z = std::sqrt(std::max(0.0, rho * rho - u * u));   // height off the centre at r_mm
    bool found = false;
    double lowest = std::numeric_limits<double>::infinity();
    // Below the centre (kappa up to pi/2) r grows with kappa; above it r shrinks.
    if (arc.from_rad <= half) {
        const double r0 = arc.at(arc.from_rad).r_mm, r1 = arc.at(std::min(arc.to_rad, half)).r_mm;
        if (r_mm >= r0 - kJoinMm && r_mm <= r1 + kJoinMm) {
            lowest = arc.centre_z_mm - off_z;
            found = true;
        }
    }
    if (arc.to_rad > half) {
        const double r0 = arc.at(arc.to_rad).r_mm, r1 = arc.at(std::max(arc.from_rad, half)).r_mm;
        if (r_mm >= r0 - kJoinMm && r_mm <= r1 + kJoinMm) {
            lowest = std::min(lowest, arc.centre_z_mm + off_z);
            found = true;
        }
    }
    if (found) z_mm = lowest;
    return found;
}

// An arc's ends at quarter turns exactly (cos(pi/2) is 6e-17 in doubles): a ball nose then ends
// exactly at its radius's height.
ProfilePoint arc_end_point(const ArcSegment& arc, double kappa_rad) {
    if (kappa_rad == std::numbers::pi / 2) return {arc.centre_r_mm + arc.radius_mm, arc.centre_z_mm};
    if (kappa_rad == std::numbers::pi) return {arc.centre_r_mm, arc.centre_z_mm + arc.radius_mm};
    return arc.at(kappa_rad);
}

}  // namespace

ProfilePoint ArcSegment::at(double kappa_rad) const {
    // Written from the arc's lowest point so that an arc starting at the tip (centre_z = radius)
    // gives exactly radius (1 - cos kappa).
    return {centre_r_mm + radius_mm * std::sin(kappa_rad), (centre_z_mm - radius_mm) + radius_mm * (1 - std::cos(kappa_rad))};
}

ProfilePoint segment_start(const ProfileSegment& s) {
    if (const auto* line = std::get_if<LineSegment>(&s)) return line->from;
    const auto& arc = std::get<ArcSegment>(s);
    return arc_end_point(arc, arc.from_rad);
}

ProfilePoint segment_end(const ProfileSegment& s) {
    if (const auto* line = std::get_if<LineSegment>(&s)) return line->to;
    const auto& arc = std::get<ArcSegment>(s);
    return arc_end_point(arc, arc.to_rad);
}

double segment_length_mm(const ProfileSegment& s) {
    if (const auto* line = std::get_if<LineSegment>(&s))
        return std::hypot(line->to.r_mm - line->from.r_mm, line->to.z_mm - line->from.z_mm);
    const auto& arc = std::get<ArcSegment>(s);
    return arc.radius_mm * (arc.to_rad - arc.from_rad);
}

CutterProfile::CutterProfile(std::vector<ProfileSegment> segments) : segments_(std::move(segments)) {
    if (segments_.empty()) throw std::invalid_argument("cutter profile: no segments");
    const ProfilePoint tip = segment_start(segments_.front());
    if (std::abs(tip.r_mm) > kJoinMm || std::abs(tip.z_mm) > kJoinMm)
        reject(0, "the profile must start at the tip, on the axis (r = 0, z = 0)");
    for (std::size_t k = 0; k < segments_.size(); ++k) {
        check_segment(segments_[k], k);
        if (k > 0) {
            const ProfilePoint end = segment_end(segments_[k - 1]), start = segment_start(segments_[k]);
            if (std::abs(end.r_mm - start.r_mm) > kJoinMm || std::abs(end.z_mm - start.z_mm) > kJoinMm)
                reject(k, "does not start where the segment before ends");
        }
        for (const ProfilePoint& p : {segment_start(segments_[k]), segment_end(segments_[k])})
            radius_mm_ = std::max(radius_mm_, p.r_mm);
        if (const auto* arc = std::get_if<ArcSegment>(&segments_[k]); arc && arc->from_rad < std::numbers::pi / 2 &&
                                                                      arc->to_rad > std::numbers::pi / 2)
            radius_mm_ = std::max(radius_mm_, arc->centre_r_mm + arc->radius_mm);   // a barrel's bulge
    }
    length_mm_ = segment_end(segments_.back()).z_mm;
    if (!(radius_mm_ > 0)) throw std::invalid_argument("cutter profile: no point off the axis (radius 0)");
}

double CutterProfile::lower_surface_mm(double r_mm) const {
    const double r = std::clamp(r_mm, 0.0, radius_mm_);
    double lowest = std::numeric_limits<double>::infinity();
    for (const ProfileSegment& s : segments_) {
        double z = 0;
        if (segment_lowest_at(s, r, z)) lowest = std::min(lowest, z);
    }
    // A chain from the axis reaches every radius up to its largest; rounding aside, nothing is left.
    return std::isfinite(lowest) ? lowest : length_mm_;
}

std::vector<ProfilePoint> profile_polyline(const CutterProfile& profile, double sagitta_mm) {
    if (!(sagitta_mm > 0)) throw std::invalid_argument("profile polyline: the sagitta must be > 0 mm");
    std::vector<ProfilePoint> points{segment_start(profile.segments().front())};
    for (const ProfileSegment& s : profile.segments()) {
        if (const auto* arc = std::get_if<ArcSegment>(&s)) {
            // A chord over the angle d strays rho (1 - cos(d / 2)) from its arc.
            const double ratio = std::clamp(1 - sagitta_mm / arc->radius_mm, -1.0, 1.0);
            const double max_step = std::max(2 * std::acos(ratio), 1e-6);
            const int pieces = std::max(1, int(std::ceil((arc->to_rad - arc->from_rad) / max_step)));
            for (int k = 1; k < pieces; ++k)
                points.push_back(arc->at(arc->from_rad + (arc->to_rad - arc->from_rad) * k / pieces));
        }
        points.push_back(segment_end(s));
    }
    return points;
}

}  // namespace cutload::force_model
