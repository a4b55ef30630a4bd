#include "engine/holder_check.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace cutload::force_model {

namespace {

constexpr std::size_t kHolderCheckStride = 16;   // steps per check; a hit marks all of them

}  // namespace

double holder_clearance_mm(const StockMap& map, double x_mm, double y_mm, double holder_radius_mm,
                           double holder_face_z_mm, double reach_mm) {
    // In the (rho, z) half-plane of the tool axis the holder is rho <= Rh, z >= face; a stock
    // column at rho with its top at zt is nearest it at (rho, min(zt, face)).
    const double Rh = holder_radius_mm, face = holder_face_z_mm;
    const double dr = std::max(map.grid().cell_mm, 0.5);
    double best = std::numeric_limits<double>::infinity();
    for (double r = 0; r <= Rh + reach_mm + 1e-9; r += dr) {
        const int n = r == 0 ? 1 : std::max(1, int(std::ceil(2 * std::numbers::pi * r / dr)));
        for (int k = 0; k < n; ++k) {
            const double a = 2 * std::numbers::pi * k / n;
            const double top = map.column_top(x_mm + r * std::cos(a), y_mm + r * std::sin(a));
            const double below = face - top;   // > 0: the top is under the face
            double d;
            if (r <= Rh) d = below;
            else if (below <= 0) d = r - Rh;
            else d = std::hypot(r - Rh, below);
            best = std::min(best, d);
        }
    }
    return best <= reach_mm ? best : std::numeric_limits<double>::infinity();
}

void mark_holder_contact(StockMap& map, const ToolGeometry& tool, const kernels::StepBatch& steps,
                         const TipBounds& b, ForceSample* rows, RowExtra* extra) {
    const double Rh = tool.holder_radius_mm, c = tool.holder_clearance_mm;
    // Nothing rises to the flutes' top (contact) or into the shell below the holder's face (near miss).
    const double reach = Rh + c;
    const double lowest = std::min(b.z_min_mm + tool.flute_length_mm, b.z_min_mm + tool.stickout_mm - c);
    if (map.max_top(b.x0_mm - reach, b.y0_mm - reach, b.x1_mm + reach, b.y1_mm + reach) <= lowest) return;
    const std::size_t n = steps.size();
    for (std::size_t k = 0; k < n; k += kHolderCheckStride) {
        const double x = steps.tip_x[k], y = steps.tip_y[k], z = steps.tip_z[k];
        const std::size_t end = std::min(n, k + kHolderCheckStride);
        const bool contact = map.material_above(x, y, 0, tool.radius_mm * 0.98, z + tool.flute_length_mm + 1e-3) ||
                             map.material_above(x, y, tool.radius_mm, Rh, z + tool.stickout_mm + 1e-3);
        if (contact) {
            for (std::size_t r = k; r < end; ++r) rows[r].holder_contact = true;
            continue;
        }
        if (c <= 0) continue;
        const double clearance = holder_clearance_mm(map, x, y, Rh, z + tool.stickout_mm, c);
        if (clearance < c)
            for (std::size_t r = k; r < end; ++r) extra[r].holder_clearance_mm = static_cast<float>(clearance);
    }
}

}  // namespace cutload::force_model
