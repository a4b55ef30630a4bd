// Internal: the in-process workpiece behind the opaque force_model::Stock.
//
// The rays are stored encoded (kernels::RayCodec: XOR-ed with the box's full column), so a ray that
// was never cut is zero bytes, in anonymous zero pages from the OS (ZeroPages). A fresh stock then
// costs neither a fill nor page faults: a run only touches the pages of the rays it cuts.
#pragma once

#include "force_model/force_model.hpp"
#include "kernels/engine_kernels.hpp"

#include <cstddef>
#include <cstdint>
#include <vector>

namespace cutload::force_model {

// Page-aligned, zero-filled memory mapped from the OS; pages are faulted in on first write. Copies
// copy only the pages that are not all zero, so a copy stays as lazy as its source. A released
// mapping is kept (up to CUTLOAD_ZERO_POOL_MB, default 256) for the next request of the same size,
// which gets it cleared, its pages already mapped (zero_pages.cpp).
class ZeroPages {
public:
    ZeroPages() = default;
    explicit ZeroPages(std::size_t bytes);
    ZeroPages(const ZeroPages& other);
    ZeroPages& operator=(const ZeroPages&) = delete;
    ZeroPages(ZeroPages&& other) noexcept;
    ZeroPages& operator=(ZeroPages&& other) noexcept;
    ~ZeroPages();

    void* data() const { return data_; }
    std::size_t bytes() const { return bytes_; }

    // Maps bytes [begin, end) writable before anything reads them (zero_pages.cpp says why). Pages
    // already made so, by this object or by an earlier owner of its pooled mapping, cost nothing.
    void prepare_writable(std::size_t begin, std::size_t end);
    // The same for bytes [begin, end) of each row j0 <= j < j1 of `row_bytes`.
    void prepare_writable_rows(std::size_t row_bytes, std::size_t begin, std::size_t end, std::size_t j0, std::size_t j1);

private:
    void release() noexcept;

    void* data_ = nullptr;
    std::size_t bytes_ = 0;
    std::vector<std::uint64_t> writable_;   // a bit per page already made writable
};

// Makes a page-aligned anonymous mapping of `len` bytes (whole pages) all zero again, touching only
// the pages it holds; false when the kernel refused a call. `machine_has_swap`: pages the kernel
// reports absent may be in swap and are dropped too. The pool calls it with what sysinfo says.
bool clear_zero_pages(void* mapping, std::size_t len, bool machine_has_swap);

class Stock {
public:
    // The box the grid covers, in grid coordinates: for a turned stock (make_turned_stock) the
    // box around the turned stock box, which source_box keeps in stock coordinates.
    StockBox box;
    StockBox source_box;
    Rotation3 grid_from_stock;   // identity: the grid is in stock coordinates
    kernels::GridInfo grid;
    kernels::RayCodec codec;   // base column: the box's full height
    ZeroPages storage;         // encoded rays, kDexelFloats floats each, row-major (j * nx + i)
    ZeroPages walls;           // encoded sub-cell walls, kWallSlots * kWallFloats floats per ray, same order

    std::size_t rays() const { return std::size_t(grid.nx) * std::size_t(grid.ny); }
    float* stored() const { return static_cast<float*>(storage.data()); }
    float* stored_walls() const { return static_cast<float*>(walls.data()); }
    kernels::DexelView view() const { return {stored(), stored_walls(), grid, codec}; }
    kernels::Ray ray(std::size_t r) const { return codec.decode(stored() + r * kernels::kDexelFloats); }
    kernels::Ray ray(int i, int j) const { return ray(std::size_t(j) * std::size_t(grid.nx) + std::size_t(i)); }
    // True when ray r was never cut (still the box's full column).
    bool untouched(std::size_t r) const;
};

}  // namespace cutload::force_model
