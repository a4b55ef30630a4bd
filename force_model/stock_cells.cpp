// The stock's cell count on its own, apart from stock.cpp: the run-spec parser bounds the grid with
// it, and the parser is built without the engine for the fuzz targets (tests/fuzz).
#include "force_model/force_model.hpp"

#include <algorithm>
#include <cmath>

namespace cutload::force_model {

double stock_cells(const StockBox& box, double grid_mm) {
    // Rounded to whole cells as make_stock lays them out (a box that is a multiple of the grid
    // exactly); at least one per axis.
    const auto along = [&](int k) { return std::max(1.0, std::round((box.max_mm[k] - box.min_mm[k]) / grid_mm)); };
    return along(0) * along(1);
}

}  // namespace cutload::force_model
