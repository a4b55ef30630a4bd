// Internal: the in-process workpiece behind the opaque force_model::Stock.
#pragma once

#include "force_model/force_model.hpp"
#include "kernels/engine_kernels.hpp"

#include <vector>

namespace cutload::force_model {

class Stock {
public:
    StockBox box;
    kernels::GridInfo grid;
    std::vector<float> cells;   // kDexelFloats per ray, row-major (j * nx + i)

    float* ray(int i, int j) { return cells.data() + (std::size_t(j) * grid.nx + i) * kernels::kDexelFloats; }
    const float* ray(int i, int j) const {
        return cells.data() + (std::size_t(j) * grid.nx + i) * kernels::kDexelFloats;
    }
};

}  // namespace cutload::force_model
