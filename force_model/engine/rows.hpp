// Internal: the engine's output rows: one per angle step where it evaluated engagement, one per
// motion sample elsewhere (air, a stopped spindle), with what the block summaries need beyond the
// public ForceSample.
#pragma once

#include "engine/batcher.hpp"
#include "force_model/force_model.hpp"
#include "kernels/engine_kernels.hpp"

#include <limits>
#include <span>
#include <vector>

namespace cutload::force_model {

// No NaN or infinity reaches FORCES.csv, BLOCKS.csv or a JSON answer: throws std::runtime_error
// (an engine fault, nothing written) when a row's time, angle or any of its values from fx_N to
// removed_mm3 is not finite.
void check_finite_rows(std::span<const ForceSample> rows);

// What the engine knows about a row beyond the public ForceSample.
struct RowExtra {
    std::int32_t slot = 0;             // the cutter's slot in the tool plan; -1: unknown tool
    float feed_mm_min = 0;
    float engaged = 0;                 // engaged edge elements
    bool stopped_in_material = false;  // |rpm| < 1 with the cutter in material
    float spindle_rpm = 0;
    // Distance from the holder to the nearest stock where it is within the clearance shell
    // (Limits::holder_clearance_mm) without touching; infinity elsewhere.
    float holder_clearance_mm = std::numeric_limits<float>::infinity();
};

class RowTable {
public:
    RowTable() = default;
    // The cutter of the rows that follow: its slot, its T number and its shank (bending stress).
    void use_tool(std::int32_t slot, std::int32_t number, double shank_diameter_mm);
    void reserve(std::size_t rows);
    std::size_t size() const { return samples.size(); }

    // One row per step of a completed batch, from the kernel's results; the batch's removed volume
    // is spread evenly over its rows (with no rows, as attribute_removed).
    void append_steps(const std::vector<StepMeta>& meta, const std::vector<kernels::StepResult>& results,
                      double removed_mm3);
    // One zero-force row at motion sample i, of the current tool.
    void append_motion_sample(const motion_io::MotionModel& m, std::size_t i, bool stopped_in_material);
    // One zero-force row at motion sample i whose tool the run does not have (T number, -1: none).
    void append_unknown_tool(const motion_io::MotionModel& m, std::size_t i, std::int32_t number);
    // Volume removed with no rows of its own (the tail of the path, removed at a stop): added to the
    // last row written.
    void attribute_removed(double removed_mm3);

    std::vector<ForceSample> samples;
    std::vector<RowExtra> extra;

private:
    double section_modulus_mm3_ = 0;
    std::int32_t slot_ = 0, number_ = -1;
};

}  // namespace cutload::force_model
