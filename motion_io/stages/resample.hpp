// Internal: stage "resample" - the motion on the uniform grid.
#pragma once

#include "stages/stage.hpp"

#include <array>
#include <optional>
#include <vector>

namespace cutload::motion_io::detail {

// Accepts sessions and knots; emits sessions and grid samples (position and velocity; the
// spindle and block stages fill in the rest). Between knots the motion is the cubic Hermite
// segment with the knot velocities as end slopes (motion_io/hermite.hpp), C1 everywhere; each
// sample stores its value and derivative, so sample_between()'s Hermite over the grid is C1 too
// and matches the stored velocities. The grid starts at the session's first knot and steps by
// step_s; a grid time on the session's last knot is included. Warns `session_too_short` for a
// session whose positions never make a segment.
class Resample final : public Stage {
public:
    Resample(Diagnostics& diag, double step_s);
    Flows accepts() const override { return Flow::Sessions | Flow::Knots; }
    Flows emits() const override { return Flow::Sessions | Flow::Grid; }
    void begin_session() override;
    void knot(const Knot& k) override;
    void end_session(SessionSummary& s) override;
    void report(IngestReport& report) const override;

private:
    void emit_until(const Knot& a, const Knot& b, bool include_end);
    void note_feed(const GridSample& s);
    void flush_batch();

    Diagnostics& diag_;
    double step_s_;
    // ---- per session ----
    std::optional<Knot> prev_, before_prev_;   // the last segment
    std::uint8_t rotary_mask_ = 0;             // GridSample::rotary
    bool have_grid_ = false;
    double grid_t0_ = 0;
    std::size_t grid_i_ = 0;
    std::vector<GridSample> batch_;   // samples of the current segment, handed on together
    // ---- whole log ----
    bool have_feed_ = false;
    double feed_min_ = 0, feed_max_ = 0;
    std::array<double, 3> first_position_mm_{};
};

}  // namespace cutload::motion_io::detail
