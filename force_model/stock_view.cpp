// The stock seen from above, for display: the top of the material per cell of a coarser grid.
#include "stock.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace cutload::force_model {

namespace {

// A turned stock's rays run along the tool's axis, not +Z. Each ray's material is walked in steps
// of at most half a field cell seen from above, every point turned back into stock coordinates and
// put in the field's cell under it, the highest one kept: rays that lie flat (a horizontal tool)
// cross many cells, rays along +Z hit one. The top between rays is not interpolated.
StockHeightField turned_height_field(const Stock& s, std::size_t max_cells) {
    const StockBox& b = s.source_box;
    const double g = s.grid.cell_mm;
    const double sx = std::max(1.0, std::ceil((b.max_mm[0] - b.min_mm[0]) / g)),
                 sy = std::max(1.0, std::ceil((b.max_mm[1] - b.min_mm[1]) / g));
    // Where the rays are steep, a face across them is sampled at their ends, a pitch / |cos(lean)|
    // apart: a cell that wide holds one. Where they lie flatter than about 78 deg from +Z the walk
    // finds the top within a pitch in any cell.
    const double cos_lean = std::abs(s.grid_from_stock.m[8]);
    int k = std::max({1, int(std::ceil(std::sqrt(sx * sy / double(max_cells)))),
                      cos_lean > 0.2 ? int(std::ceil(1 / cos_lean - 1e-9)) : 1});
    while (std::size_t(std::ceil(sx / k)) * std::size_t(std::ceil(sy / k)) > max_cells) ++k;
    StockHeightField f;
    f.box = b;
    f.nx = int(std::ceil(sx / k));
    f.ny = int(std::ceil(sy / k));
    f.cell_mm = g * k;
    f.x0_mm = b.min_mm[0];
    f.y0_mm = b.min_mm[1];
    f.rays_per_cell = k;
    f.top_mm.assign(std::size_t(f.nx) * std::size_t(f.ny), std::numeric_limits<float>::quiet_NaN());
    const auto& G = s.grid_from_stock.m;
    const double across = std::hypot(G[6], G[7]);   // a ray's run seen from above, per mm along it
    const auto put = [&](double x, double y, double z) {
        // p_stock = G^T p_grid
        const double px = G[0] * x + G[3] * y + G[6] * z, py = G[1] * x + G[4] * y + G[7] * z,
                     pz = G[2] * x + G[5] * y + G[8] * z;
        const int i = int(std::floor((px - f.x0_mm) / f.cell_mm)), j = int(std::floor((py - f.y0_mm) / f.cell_mm));
        if (i < 0 || j < 0 || i >= f.nx || j >= f.ny) return;
        float& cell = f.top_mm[std::size_t(j) * std::size_t(f.nx) + std::size_t(i)];
        if (std::isnan(cell) || pz > cell) cell = float(pz);
    };
    for (int j = 0; j < s.grid.ny; ++j)
        for (int i = 0; i < s.grid.nx; ++i) {
            const kernels::Ray ray = s.ray(i, j);
            const double x = s.grid.x0_mm + (i + 0.5) * g, y = s.grid.y0_mm + (j + 0.5) * g;
            for (int m = 0; m < kernels::kDexelIntervals; ++m) {
                const double lo = ray[m], hi = ray[kernels::kDexelIntervals + m];
                if (!(hi > lo)) continue;
                const int steps = std::max(1, int(std::ceil((hi - lo) * across / (0.5 * f.cell_mm))));
                for (int q = 0; q <= steps; ++q) put(x, y, lo + (hi - lo) * q / steps);
            }
        }
    return f;
}

}  // namespace

StockHeightField stock_height_field(const Stock& s, std::size_t max_cells) {
    if (max_cells == 0) throw std::invalid_argument("stock_height_field: max_cells must be > 0");
    if (!s.grid_from_stock.is_identity()) return turned_height_field(s, max_cells);
    // Blocks of k x k rays: the smallest k that fits the field into max_cells.
    const double rays = double(s.grid.nx) * double(s.grid.ny);
    int k = std::max(1, int(std::ceil(std::sqrt(rays / double(max_cells)))));
    while ((std::size_t((s.grid.nx + k - 1) / k) * std::size_t((s.grid.ny + k - 1) / k)) > max_cells) ++k;
    StockHeightField f;
    f.nx = (s.grid.nx + k - 1) / k;
    f.ny = (s.grid.ny + k - 1) / k;
    f.cell_mm = s.grid.cell_mm * k;
    f.x0_mm = s.grid.x0_mm;
    f.y0_mm = s.grid.y0_mm;
    f.rays_per_cell = k;
    for (int a = 0; a < 3; ++a) {
        f.box.min_mm[a] = s.box.min_mm[a];
        f.box.max_mm[a] = s.box.max_mm[a];
    }
    const float box_top = s.codec.base_top();
    const float none = std::numeric_limits<float>::quiet_NaN();
    f.top_mm.assign(std::size_t(f.nx) * std::size_t(f.ny), none);
    for (int j = 0; j < s.grid.ny; ++j)
        for (int i = 0; i < s.grid.nx; ++i) {
            const std::size_t r = std::size_t(j) * std::size_t(s.grid.nx) + std::size_t(i);
            const float top = s.untouched(r) ? box_top : kernels::ray_top(s.ray(r));
            if (top <= kernels::kEmptyHi) continue;   // no material left in this ray
            // The highest ray of the block: the field never shows material removed that is there.
            float& cell = f.top_mm[std::size_t(j / k) * std::size_t(f.nx) + std::size_t(i / k)];
            if (std::isnan(cell) || top > cell) cell = top;
        }
    return f;
}

}  // namespace cutload::force_model
