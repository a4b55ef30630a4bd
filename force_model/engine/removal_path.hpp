// Internal: the tip path whose swept volume is still to be removed, and its simplification into
// removal calls. Removal trails the engagement test by a lag of travel (docs/force_model.md,
// "Stock lag"); the path is thinned to half a cell and cut into chords that stay within the chord
// tolerance of every tip position they replace ("Removal").
#pragma once

#include "engine/stock_map.hpp"
#include "engine/vec3.hpp"
#include "kernels/engine_kernels.hpp"

#include <vector>

namespace cutload::force_model {

class RemovalPath {
public:
    RemovalPath(double cell_mm, double cutter_radius_mm, double lag_mm, double chord_tolerance_mm);

    bool empty() const { return pending_.empty(); }
    // Another cutter follows (at a tool change, once the path is taken: empty()).
    void set_cutter_radius(double cutter_radius_mm) { cutter_radius_mm_ = cutter_radius_mm; }
    // Appends a tip position; with keep false it is dropped when within half a cell of the last one.
    void add(const Vec3& tip_mm, bool keep = true);
    // Appends every tip of a batch (thinned, the last one kept).
    void add_batch(const kernels::StepBatch& steps);
    // Moves the pending path into chords `segs` grouped into removal `calls`, skipping calls over
    // no material above the tip (by `map`). With keep_lag, the last lag of travel stays pending
    // (and nothing is taken while the path is shorter than that).
    void take(bool keep_lag, StockMap& map, std::vector<kernels::SweepSegment>& segs,
              std::vector<kernels::SweepCall>& calls);

private:
    struct PathPoint {
        Vec3 tip_mm;
        double s_mm;   // length along the thinned path
    };
    std::size_t chord_end(std::size_t a, std::size_t last) const;
    bool chord_ok(std::size_t a, std::size_t b) const;
    void add_call(std::size_t first, StockMap& map, std::vector<kernels::SweepSegment>& segs,
                  std::vector<kernels::SweepCall>& calls) const;

    double cell_mm_, cutter_radius_mm_, lag_mm_, chord_tolerance_mm_;
    std::vector<PathPoint> pending_;
    double path_mm_ = 0;
};

}  // namespace cutload::force_model
