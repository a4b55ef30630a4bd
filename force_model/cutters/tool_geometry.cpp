#include "cutters/tool_geometry.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace cutload::force_model {

namespace {

// Samples of the lower surface over [0, R] for the removal kernels (linear interpolation between).
constexpr int kLowerSamples = 513;

struct Element {
    double r_mm, z_mm, nr, nz, db_mm, z_lo_mm, z_hi_mm;
};

void add_element(kernels::EdgeTable& t, const Element& e, double lag_per_mm) {
    t.r_mm.push_back(e.r_mm);
    t.z_mm.push_back(e.z_mm);
    t.nr.push_back(e.nr);
    t.nz.push_back(e.nz);
    t.db_mm.push_back(e.db_mm);
    t.z_lo_mm.push_back(e.z_lo_mm);
    t.z_hi_mm.push_back(e.z_hi_mm);
    t.lag_rad.push_back(e.z_mm * lag_per_mm);
}

// Pieces of about step_mm along the segment (at least one).
int piece_count(double length_mm, double step_mm) { return std::max(1, int(std::ceil(length_mm / step_mm - 1e-9))); }

void add_line(kernels::EdgeTable& t, const LineSegment& s, double step_mm, double lag_per_mm) {
    const double dr_total = s.to.r_mm - s.from.r_mm, dz_total = s.to.z_mm - s.from.z_mm;
    const double length = std::hypot(dr_total, dz_total);
    const int n = piece_count(length, step_mm);
    const double dr = dr_total / n, dz = dz_total / n;
    // Outward normal: the tangent (dr, dz) turned clockwise; 0.0 - x keeps a vertical piece's nz +0.
    const double nr = dz_total / length, nz = 0.0 - dr_total / length;
    for (int k = 0; k < n; ++k)
        add_element(t,
                    {s.from.r_mm + (k + 0.5) * dr, s.from.z_mm + (k + 0.5) * dz, nr, nz, length / n,
                     s.from.z_mm + k * dz, s.from.z_mm + (k + 1) * dz},
                    lag_per_mm);
}

void add_arc(kernels::EdgeTable& t, const ArcSegment& s, double step_mm, double lag_per_mm) {
    const double sweep_rad = s.to_rad - s.from_rad;
    const int n = piece_count(s.radius_mm * sweep_rad, step_mm);
    const double dk = sweep_rad / n;
    for (int k = 0; k < n; ++k) {
        const double kappa = s.from_rad + (k + 0.5) * dk;
        const ProfilePoint p = s.at(kappa);
        add_element(t,
                    {p.r_mm, p.z_mm, std::sin(kappa), -std::cos(kappa), s.radius_mm * dk,
                     s.at(s.from_rad + k * dk).z_mm, s.at(s.from_rad + (k + 1) * dk).z_mm},
                    lag_per_mm);
    }
}

}  // namespace

int ToolGeometry::elements_reaching(double height_mm) const {
    if (!(height_mm > 0)) return 0;
    const auto& z_lo = edges.z_lo_mm;
    return int(std::lower_bound(z_lo.begin(), z_lo.end(), height_mm) - z_lo.begin());
}

ToolGeometry build_tool_geometry(const Cutter& cutter, double axial_step_mm) {
    if (!(axial_step_mm > 0)) throw std::invalid_argument("axial step must be > 0");
    const CutterProfile& profile = cutter.profile;
    const double R = profile.radius_mm();
    ToolGeometry g;
    g.radius_mm = R;
    g.flute_length_mm = profile.length_mm();
    g.stickout_mm = cutter.stickout_mm;
    g.holder_radius_mm = std::max(cutter.holder_diameter_mm / 2, R);
    g.holder_length_mm = cutter.holder_length_mm;
    g.shank_diameter_mm = 2 * R;

    kernels::EdgeTable& t = g.edges;
    t.flutes = cutter.flutes;
    const double lag_per_mm = std::tan(cutter.helix_deg * std::numbers::pi / 180) / R;
    for (const ProfileSegment& s : profile.segments()) {
        if (const auto* line = std::get_if<LineSegment>(&s)) add_line(t, *line, axial_step_mm, lag_per_mm);
        else add_arc(t, std::get<ArcSegment>(s), axial_step_mm, lag_per_mm);
    }
    // The leading flat bottom (downward normal, no height): it cuts only while the tool descends.
    while (std::size_t(t.bottom_count) < t.size() && t.nz[t.bottom_count] == -1 && t.z_hi_mm[t.bottom_count] == 0)
        ++t.bottom_count;

    g.lower_mm.resize(kLowerSamples);
    for (int k = 0; k < kLowerSamples; ++k) g.lower_mm[k] = profile.lower_surface_mm(R * k / (kLowerSamples - 1));
    return g;
}

}  // namespace cutload::force_model
