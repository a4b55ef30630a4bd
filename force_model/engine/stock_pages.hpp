// Internal: the rays a batch is about to read and cut, made writable first, for the backends whose
// kernels work in the host's stock arrays (ZeroPages::prepare_writable says why). Not the walls:
// the removal reads a ray's stored wall only once the ray is marked as having one (remove.cl), so
// a wall's page is written before it is read, and walls stay where the cut's sides are. The OpenCL
// backend's per-ray tops (read before a lookup, rewritten after a removal) go the same way.
#pragma once

#include "stock.hpp"

#include <algorithm>
#include <cstddef>
#include <cstdint>

namespace cutload::force_model {

class StockPages {
public:
    explicit StockPages(Stock& stock, ZeroPages* tops = nullptr) : stock_(stock), tops_(tops) {}
    // The rays [i0, i1) x [j0, j1), clipped to the grid.
    void prepare(int i0, int j0, int i1, int j1) {
        i0 = std::max(i0, 0), j0 = std::max(j0, 0);
        i1 = std::min(i1, stock_.grid.nx), j1 = std::min(j1, stock_.grid.ny);
        if (i0 >= i1 || j0 >= j1) return;
        constexpr std::size_t ray = kernels::kDexelFloats * sizeof(float);
        const std::size_t nx = std::size_t(stock_.grid.nx);
        stock_.storage.prepare_writable_rows(nx * ray, std::size_t(i0) * ray, std::size_t(i1) * ray, std::size_t(j0),
                                             std::size_t(j1));
        prepare_tops(i0, j0, i1, j1);
    }
    // The tops alone (rays only read around a removal, or not at all).
    void prepare_tops(int i0, int j0, int i1, int j1) {
        i0 = std::max(i0, 0), j0 = std::max(j0, 0);
        i1 = std::min(i1, stock_.grid.nx), j1 = std::min(j1, stock_.grid.ny);
        if (!tops_ || i0 >= i1 || j0 >= j1) return;
        constexpr std::size_t top = sizeof(std::uint32_t);
        tops_->prepare_writable_rows(std::size_t(stock_.grid.nx) * top, std::size_t(i0) * top, std::size_t(i1) * top,
                                     std::size_t(j0), std::size_t(j1));
    }

private:
    Stock& stock_;
    ZeroPages* tops_;
};

}  // namespace cutload::force_model
