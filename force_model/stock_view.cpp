// The stock seen from above, for display: the top of the material per cell of a coarser grid.
#include "stock.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace cutload::force_model {

StockHeightField stock_height_field(const Stock& s, std::size_t max_cells) {
    if (max_cells == 0) throw std::invalid_argument("stock_height_field: max_cells must be > 0");
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
