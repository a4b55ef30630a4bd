#include "tool_geometry.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace cutload::force_model {

namespace {

void add_element(kernels::EdgeTable& t, double r, double z, double nr, double nz, double db, double z_lo,
                 double z_hi, double lag) {
    t.r_mm.push_back(r);
    t.z_mm.push_back(z);
    t.nr.push_back(nr);
    t.nz.push_back(nz);
    t.db_mm.push_back(db);
    t.z_lo_mm.push_back(z_lo);
    t.z_hi_mm.push_back(z_hi);
    t.lag_rad.push_back(lag);
}

}  // namespace

ToolGeometry build_tool_geometry(const ToolSpec& tool, double axial_step_mm) {
    if (!(axial_step_mm > 0)) throw std::invalid_argument("axial step must be > 0");
    ToolGeometry g;
    const double R = tool.diameter_mm / 2;
    double rc = 0;
    switch (tool.shape) {
        case ToolShape::Flat: rc = 0; break;
        case ToolShape::Ball: rc = R; break;
        case ToolShape::Bull: rc = tool.corner_radius_mm; break;
    }
    g.radius_mm = R;
    g.corner_radius_mm = rc;
    g.flute_length_mm = tool.flute_length_mm;
    g.stickout_mm = tool.stickout_mm;
    g.holder_radius_mm = std::max(tool.holder.diameter_mm / 2, R);
    g.holder_length_mm = tool.holder.length_mm;

    kernels::EdgeTable& t = g.edges;
    t.flutes = tool.flutes;
    const double lead = std::tan(tool.helix_deg * std::numbers::pi / 180) / R;   // lag per mm of height
    const double a = R - rc;   // radius where the flat bottom meets the corner arc

    if (a > 1e-9) {
        const int n = std::max(1, int(std::ceil(a / axial_step_mm - 1e-9)));
        const double dr = a / n;
        for (int k = 0; k < n; ++k) add_element(t, (k + 0.5) * dr, 0, 0, -1, dr, 0, 0, 0);
        t.bottom_count = n;
    }
    if (rc > 1e-9) {
        const double quarter = std::numbers::pi / 2;
        const int n = std::max(1, int(std::ceil(rc * quarter / axial_step_mm - 1e-9)));
        const double dk = quarter / n;
        for (int k = 0; k < n; ++k) {
            const double kappa = (k + 0.5) * dk;   // angle of the normal from the tool axis (-z)
            const double z = rc * (1 - std::cos(kappa));
            add_element(t, a + rc * std::sin(kappa), z, std::sin(kappa), -std::cos(kappa), rc * dk,
                        rc * (1 - std::cos(k * dk)), rc * (1 - std::cos((k + 1) * dk)), z * lead);
        }
    }
    const double cyl = tool.flute_length_mm - rc;
    if (cyl > 1e-9) {
        const int n = std::max(1, int(std::ceil(cyl / axial_step_mm - 1e-9)));
        const double dz = cyl / n;
        for (int k = 0; k < n; ++k) {
            const double z = rc + (k + 0.5) * dz;
            add_element(t, R, z, 1, 0, dz, rc + k * dz, rc + (k + 1) * dz, z * lead);
        }
    }

    constexpr int kLowerSamples = 513;
    g.lower_mm.resize(kLowerSamples);
    for (int k = 0; k < kLowerSamples; ++k) {
        const double d = R * k / (kLowerSamples - 1);
        const double u = d - a;
        g.lower_mm[k] = u <= 0 ? 0.0 : rc - std::sqrt(std::max(0.0, rc * rc - u * u));
    }
    return g;
}

}  // namespace cutload::force_model
