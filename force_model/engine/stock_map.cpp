#include "engine/stock_map.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace cutload::force_model {

namespace {

constexpr int kTile = 16;   // cells per side of a tile of the coarse max-top map

}  // namespace

TopMap::TopMap(const Stock& stock, bool fresh)
    : base_(std::bit_cast<std::uint32_t>(stock.codec.base_top())), bits_(stock.rays() * sizeof(std::uint32_t)) {
    if (fresh) return;
    for (std::size_t r = 0; r < stock.rays(); ++r)
        if (!stock.untouched(r)) set(r, kernels::ray_top(stock.ray(r)));
}

StockMap::StockMap(const Stock& stock, bool fresh) : grid_(stock.grid), tops_(stock, fresh) {
    tiles_x_ = (grid_.nx + kTile - 1) / kTile;
    tiles_y_ = (grid_.ny + kTile - 1) / kTile;
    tile_max_mm_.assign(std::size_t(tiles_x_) * tiles_y_, stock.codec.base_top());
    if (!fresh) refresh_tiles({0, 0, grid_.nx, grid_.ny});
}

void StockMap::refresh_tiles(const CellRect& c) {
    for (int tj = c.j0 / kTile; tj <= (c.j1 - 1) / kTile && tj < tiles_y_; ++tj)
        for (int ti = c.i0 / kTile; ti <= (c.i1 - 1) / kTile && ti < tiles_x_; ++ti) {
            float mx = kernels::kEmptyHi;
            for (int j = tj * kTile; j < std::min(grid_.ny, (tj + 1) * kTile); ++j)
                for (int i = ti * kTile; i < std::min(grid_.nx, (ti + 1) * kTile); ++i)
                    mx = std::max(mx, tops_.at(std::size_t(j) * grid_.nx + i));
            tile_max_mm_[std::size_t(tj) * tiles_x_ + ti] = mx;
        }
    ++tiles_version_;
}

bool StockMap::cells_covering(double x0_mm, double y0_mm, double x1_mm, double y1_mm, CellRect& cells) const {
    const kernels::GridInfo& g = grid_;
    const double fi0 = std::floor((x0_mm - g.x0_mm) / g.cell_mm), fi1 = std::floor((x1_mm - g.x0_mm) / g.cell_mm);
    const double fj0 = std::floor((y0_mm - g.y0_mm) / g.cell_mm), fj1 = std::floor((y1_mm - g.y0_mm) / g.cell_mm);
    if (fi1 < 0 || fj1 < 0 || fi0 >= g.nx || fj0 >= g.ny) return false;
    cells.i0 = int(std::max(0.0, fi0));
    cells.j0 = int(std::max(0.0, fj0));
    cells.i1 = int(std::min<double>(g.nx - 1, fi1)) + 1;
    cells.j1 = int(std::min<double>(g.ny - 1, fj1)) + 1;
    return true;
}

float StockMap::max_top(double x0_mm, double y0_mm, double x1_mm, double y1_mm) {
    CellRect c;
    if (!cells_covering(x0_mm, y0_mm, x1_mm, y1_mm, c)) return kernels::kEmptyHi;
    const std::array<int, 4> tiles{c.i0 / kTile, c.j0 / kTile, (c.i1 - 1) / kTile, (c.j1 - 1) / kTile};
    if (tiles == memo_tiles_ && memo_version_ == tiles_version_) return memo_top_mm_;
    float mx = kernels::kEmptyHi;
    for (int tj = tiles[1]; tj <= tiles[3]; ++tj)
        for (int ti = tiles[0]; ti <= tiles[2]; ++ti) mx = std::max(mx, tile_max_mm_[std::size_t(tj) * tiles_x_ + ti]);
    memo_tiles_ = tiles;
    memo_version_ = tiles_version_;
    memo_top_mm_ = mx;
    return mx;
}

float StockMap::column_top(double x_mm, double y_mm) const {
    const kernels::GridInfo& g = grid_;
    const double fi = std::floor((x_mm - g.x0_mm) / g.cell_mm), fj = std::floor((y_mm - g.y0_mm) / g.cell_mm);
    if (fi < 0 || fj < 0 || fi >= g.nx || fj >= g.ny) return kernels::kEmptyHi;
    return tops_.at(std::size_t(fj) * g.nx + std::size_t(fi));
}

bool StockMap::material_above(double x_mm, double y_mm, double r0_mm, double r1_mm, double z_mm) const {
    const double dr = std::max(grid_.cell_mm, 0.5);
    for (double r = r0_mm; r <= r1_mm + 1e-9; r += dr) {
        const int n = std::max(1, int(std::ceil(2 * std::numbers::pi * r / dr)));
        for (int k = 0; k < n; ++k) {
            const double a = 2 * std::numbers::pi * k / n;
            if (column_top(x_mm + r * std::cos(a), y_mm + r * std::sin(a)) > z_mm) return true;
        }
        if (r1_mm - r0_mm < 1e-9) break;
    }
    return false;
}

double StockMap::apply_sweep(const std::vector<kernels::SweepCall>& calls, const kernels::SweepCellResult* results) {
    double removed_len_mm = 0;
    const kernels::SweepCellResult* r = results;
    for (const kernels::SweepCall& c : calls) {
        if (c.width > 0 && c.height > 0)
            tops_.will_set(std::size_t(grid_.nx), std::size_t(c.i0), std::size_t(c.i0 + c.width), std::size_t(c.j0),
                           std::size_t(c.j0 + c.height));
        for (int jj = 0; jj < c.height; ++jj)
            for (int ii = 0; ii < c.width; ++ii, ++r) {
                removed_len_mm += r->removed_mm;
                tops_.set(std::size_t(c.j0 + jj) * grid_.nx + std::size_t(c.i0 + ii), r->top_mm);
            }
        refresh_tiles({c.i0, c.j0, c.i0 + c.width, c.j0 + c.height});
    }
    return removed_len_mm * grid_.cell_mm * grid_.cell_mm;
}

}  // namespace cutload::force_model
