// Commanded time onto actual time: each block's commanded span stretched onto the span the
// machine took for it, so the two predictions line up block by block in one plot.
#include "force_model/feed_optimizer.hpp"
#include "app/program_run.hpp"

#include <catch2/catch.hpp>

using namespace cutload;

TEST_CASE("time warp: a block the machine took twice as long for is stretched onto its actual span", "[nc][warp]") {
    motion_io::NcReadOptions ro;
    ro.start_mm = std::array<double, 3>{0, 0, 0};
    // Without a G54 offset the first move is an error naming it, not an exception from a lookup.
    CHECK_THROWS_WITH(motion_io::parse_nc_program("N10 G01 X10. F600\n", "warp.nc", ro),
                      Catch::Contains("warp.nc:1") && Catch::Contains("G54"));
    ro.work_offsets_mm["G54"] = {0, 0, 0};
    motion_io::NcProgram program =
        motion_io::parse_nc_program("%\nN10 G90 G01 X10. F600 S1000 M03\nN20 X20.\nN30 X30.\nM30\n%\n", "warp.nc", ro);
    motion_io::CommandedOptions co;
    co.step_s = 0.001;
    const motion_io::MotionModel commanded = motion_io::commanded_motion(program, co);
    REQUIRE(commanded.t_s.back() == Approx(3.0).margin(0.002));   // 3 x 10 mm at 10 mm/s

    // The "machine": N20 at half speed, so it ends at 4 s instead of 3 s.
    std::vector<double> scale(commanded.block_names.size(), 1.0), programmed(commanded.block_names.size(), 600.0);
    for (std::size_t k = 0; k < commanded.block_names.size(); ++k)
        if (commanded.block_names[k] == "N20") scale[k] = 0.5;
    motion_io::MotionModel actual = force_model::retime_motion(commanded, scale, programmed);
    REQUIRE(actual.t_s.back() == Approx(4.0).margin(0.003));

    app::ProgramSettings settings;
    const app::ProgramRun run = app::prepare_program_run(program, settings, actual);
    REQUIRE_FALSE(run.mapped);   // the motion names the program's blocks
    const app::TimeWarp warp = app::commanded_to_actual_time(run, actual);
    REQUIRE(warp.commanded_s.size() >= 3);
    for (std::size_t k = 1; k < warp.commanded_s.size(); ++k) {
        CHECK(warp.commanded_s[k] > warp.commanded_s[k - 1]);
        CHECK(warp.actual_s[k] > warp.actual_s[k - 1]);
    }
    CHECK(warp(0.5) == Approx(0.5).margin(0.003));    // N10: as commanded
    CHECK(warp(1.0) == Approx(1.0).margin(0.003));    // N20 starts together
    CHECK(warp(1.5) == Approx(2.0).margin(0.003));    // half of N20 is at 2 s in the machine's time
    CHECK(warp(2.0) == Approx(3.0).margin(0.003));    // N30 starts a second late
    CHECK(warp(2.5) == Approx(3.5).margin(0.003));
    CHECK(warp(3.0) == Approx(4.0).margin(0.003));
    CHECK(warp(3.5) == Approx(4.5).margin(0.003));    // past the end: shifted
    CHECK(warp(-1.0) == Approx(-1.0).margin(0.003));
}
