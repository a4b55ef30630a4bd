// Stage "resample": the cubic Hermite (motion_io/hermite.hpp) between knots, on the uniform grid.
#include "stage_rig.hpp"
#include "stages/resample.hpp"

#include <catch2/catch.hpp>

#include <cmath>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;

namespace {

struct ResampleRig {
    explicit ResampleRig(double step_s)
        : rig{std::make_unique<detail::Resample>(diag, step_s), Flow::Sessions | Flow::Knots,
              Flow::Sessions | Flow::Grid} {}
    detail::Diagnostics diag{"log.csv"};
    StageRig rig;
    const std::vector<detail::GridSample>& samples() const { return rig.out->samples; }
    void session(const std::vector<detail::Knot>& knots, std::size_t reads = 1) {
        rig.feeder->begin();
        for (const auto& k : knots) rig.feeder->knot(k);
        detail::SessionSummary s;
        s.position_reads = reads;
        s.first_line = 9;
        rig.feeder->end(s);
    }
};

// x(t) = 2 + 30 t - 400 t^2 + 9000 t^3 and its derivative.
double cubic(double t) { return 2 + 30 * t - 400 * t * t + 9000 * t * t * t; }
double cubic_v(double t) { return 30 - 800 * t + 27000 * t * t; }

detail::Knot knot_at(double t) {
    detail::Knot k;
    k.t_s = t;
    k.p_mm[0] = cubic(t), k.v_mm_s[0] = cubic_v(t);
    k.p_mm[2] = -1, k.v_mm_s[2] = 0;
    return k;
}

}  // namespace

TEST_CASE("resample: knots of a cubic with exact slopes give the cubic itself on the grid", "[resample]") {
    ResampleRig r(0.001);
    // Uneven knots: 4 and 8 ms apart.
    r.session({knot_at(0.010), knot_at(0.014), knot_at(0.022), knot_at(0.026), knot_at(0.034)});
    REQUIRE(r.samples().size() == 25);   // 10 ms to 34 ms inclusive: the last grid time is on the last knot
    for (const auto& s : r.samples()) {
        CHECK(s.p_mm[0] == Approx(cubic(s.t_s)).margin(1e-12));
        CHECK(s.v_mm_s[0] == Approx(cubic_v(s.t_s)).margin(1e-9));
        CHECK(s.p_mm[2] == -1);
    }
    CHECK(r.samples().front().t_s == 0.010);
    CHECK(r.samples().back().t_s == Approx(0.034).margin(1e-15));
}

TEST_CASE("resample: the grid starts at each session's first knot and steps evenly", "[resample]") {
    ResampleRig r(0.0025);
    r.session({knot_at(0.0), knot_at(0.0101)});
    r.session({knot_at(5.0003), knot_at(5.0103)});
    REQUIRE(r.samples().size() == 5 + 5);   // 0, 2.5, 5, 7.5, 10 ms; the last knot is off the grid
    CHECK(r.samples()[5].t_s == 5.0003);
    CHECK(r.samples()[6].t_s - r.samples()[5].t_s == Approx(0.0025));
    CHECK(r.rig.out->sessions_begun == 2);
}

TEST_CASE("resample: a session with a single knot yields nothing and says so", "[resample]") {
    ResampleRig r(0.001);
    r.session({knot_at(0.5)}, 3);
    CHECK(r.samples().empty());
    const IngestWarning w = warning_of(r.diag, "session_too_short");
    CHECK(w.count == 1);
    CHECK_THAT(w.message, Catch::Contains("log.csv:9"));
}

TEST_CASE("resample: the report has the repaired feed's range and the first position", "[resample]") {
    ResampleRig r(0.001);
    r.session({knot_at(0.010), knot_at(0.020), knot_at(0.030)});
    IngestReport rep;
    r.rig.under_test->report(rep);
    double lo = 1e9, hi = 0;
    for (const auto& s : r.samples()) lo = std::min(lo, std::fabs(cubic_v(s.t_s)) * 60), hi = std::max(hi, std::fabs(cubic_v(s.t_s)) * 60);
    CHECK(rep.feed_repaired_min_mm_min == Approx(lo).epsilon(1e-9));
    CHECK(rep.feed_repaired_max_mm_min == Approx(hi).epsilon(1e-9));
    REQUIRE(rep.first_position_mm);
    CHECK((*rep.first_position_mm)[0] == Approx(cubic(0.010)));
    CHECK((*rep.first_position_mm)[2] == -1);
}
