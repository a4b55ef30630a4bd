// Seed 001, figs. 4.16-4.17: at a corner the machine's actual motion departs from the program, and
// the force predicted from the program (the CAM-side, "conventional" prediction) is wrong there.
// Here: finishing an inner pocket corner (radial 1 mm, axial 3 mm, F6000, S10000: the seed's
// conditions) on the demo's machine model, whose acceleration/deceleration rounds the corner.
#include "corner_fixture.hpp"

#include "force_model/program_compare.hpp"

#include <catch2/catch.hpp>

using namespace cutload;
using namespace cutload::nctest;

TEST_CASE("corner: actual and commanded motion give different forces, and the block comparison quantifies it",
          "[corner]") {
    const CornerCase c = corner_case();
    motion_io::CommandedOptions co;
    co.step_s = c.actual.step_s;
    co.rapid_mm_min = c.dry_run.machine.rapid_mm_min;
    const motion_io::MotionModel commanded = motion_io::commanded_motion(c.program, co);
    force_model::PredictOptions opt = predict_options(c);
    const force_model::Prediction cmd = force_model::predict(commanded, c.spec, opt);
    const force_model::Prediction act = force_model::predict(c.actual, c.spec, opt);
    const motion_io::BlockMapping mapping = motion_io::map_blocks(c.actual, c.program, {});
    const auto rows = force_model::compare_program(c.program, c.actual, mapping, cmd, act, co);

    auto row = [&](const std::string& name) {
        const auto it = std::find_if(rows.begin(), rows.end(), [&](const auto& r) { return r.block == name; });
        REQUIRE(it != rows.end());
        return *it;
    };
    const auto along = row("N30");   // along the first wall, into the corner
    const auto down = row("N40");    // out of the corner along the second wall
    for (const auto& r : {along, down})
        WARN(fmt::format("{}: F{:.0f}, deviation max {:.3f} mean {:.3f} mm, feed {:.0f}..{:.0f} (deficit {:.1f}%, surge {:.1f}%), "
                         "peak force commanded {:.1f} N, actual {:.1f} N, difference {:+.1f} N ({:+.1f}%)",
                         r.block, r.programmed_feed_mm_min, r.max_deviation_mm, r.mean_deviation_mm, r.actual_min_feed_mm_min,
                         r.actual_max_feed_mm_min, r.feed_deficit_pct, r.feed_surge_pct, r.commanded_peak_force_N,
                         r.actual_peak_force_N, r.force_difference_N, r.force_difference_pct));
    // The path: the machine cuts inside the corner by a few tenths of a mm, on straight stretches
    // it follows the program to the micrometre.
    CHECK(down.max_deviation_mm > 0.1);
    CHECK(down.max_deviation_mm < 2.0);
    CHECK(along.mean_deviation_mm < 0.05);
    // The feed: it drops well below F6000 through the corner and does not surge above it.
    CHECK(down.feed_deficit_pct > 20);
    CHECK(down.feed_surge_pct < 1);
    // The force: at the corner the program predicts far more than the machine will see.
    CHECK(down.commanded_peak_force_N > 0);
    CHECK(down.force_difference_pct < -10);
    CHECK(down.force_difference_N == Approx(down.actual_peak_force_N - down.commanded_peak_force_N));
    // Before the corner both predictions agree (same straight cut).
    CHECK(std::abs(row("N20").force_difference_pct) < 3);
}
