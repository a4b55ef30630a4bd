// Internal: the host's view of the stock for the engine's decisions (air, elements that can reach
// material, removal calls worth queuing, holder contact): the top of every ray and a coarse map of
// the highest top per tile. Updated from the removal results when a batch completes, so every
// decision is taken at the same point of the walk on every backend (docs/force_model.md,
// "Pipeline"). This is the one part of the walk that knows the stock is a Z-map (tops along +Z).
#pragma once

#include "kernels/engine_kernels.hpp"
#include "stock.hpp"

#include <array>
#include <bit>
#include <cstdint>
#include <vector>

namespace cutload::force_model {

// The top of every ray, encoded like the rays (XOR with the box top), so the map of a fresh stock is
// zero pages that are only faulted in where the tool cuts.
class TopMap {
public:
    TopMap(const Stock& stock, bool fresh);
    // Rays [i0, i1) of rows [j0, j1) (nx rays a row) are about to be compared and set: their
    // pages are made writable first (ZeroPages::prepare_writable).
    void will_set(std::size_t nx, std::size_t i0, std::size_t i1, std::size_t j0, std::size_t j1) {
        bits_.prepare_writable_rows(nx * sizeof(std::uint32_t), i0 * sizeof(std::uint32_t), i1 * sizeof(std::uint32_t),
                                    j0, j1);
    }
    float at(std::size_t ray) const { return std::bit_cast<float>(data()[ray] ^ base_); }
    void set(std::size_t ray, float top_mm) {
        const std::uint32_t v = std::bit_cast<std::uint32_t>(top_mm) ^ base_;
        if (data()[ray] != v) data()[ray] = v;   // no write, no page fault, where nothing changed
    }

private:
    std::uint32_t* data() const { return static_cast<std::uint32_t*>(bits_.data()); }
    std::uint32_t base_;
    ZeroPages bits_;
};

// A rectangle of cells [i0, i1) x [j0, j1).
struct CellRect {
    int i0 = 0, j0 = 0, i1 = 0, j1 = 0;
};

class StockMap {
public:
    StockMap(const Stock& stock, bool fresh);

    const kernels::GridInfo& grid() const { return grid_; }
    // The cells covering the world rectangle; false when it lies off the grid.
    bool cells_covering(double x0_mm, double y0_mm, double x1_mm, double y1_mm, CellRect& cells) const;
    // Highest stock top over the tiles the rectangle touches (kernels::kEmptyHi off the grid).
    float max_top(double x0_mm, double y0_mm, double x1_mm, double y1_mm);
    // Top of the ray under (x, y).
    float column_top(double x_mm, double y_mm) const;
    // Whether any ray inside the ring of radii [r0, r1] around (x, y) rises above z.
    bool material_above(double x_mm, double y_mm, double r0_mm, double r1_mm, double z_mm) const;
    // Takes in the removal results of `calls` (in order, call.cells() each); returns the volume
    // removed.
    double apply_sweep(const std::vector<kernels::SweepCall>& calls, const kernels::SweepCellResult* results);

private:
    void refresh_tiles(const CellRect& cells);

    kernels::GridInfo grid_;
    TopMap tops_;
    std::vector<float> tile_max_mm_;
    int tiles_x_ = 0, tiles_y_ = 0;
    std::uint64_t tiles_version_ = 0;   // bumped whenever tile_max_mm_ changes
    // The air check asks max_top for a square the holder's size around every motion interval:
    // hundreds of tiles, mostly the same ones as for the interval before, so the last answer is
    // kept until the tiles or the map change.
    std::array<int, 4> memo_tiles_{-1, -1, -1, -1};
    std::uint64_t memo_version_ = 0;
    float memo_top_mm_ = 0;
};

}  // namespace cutload::force_model
