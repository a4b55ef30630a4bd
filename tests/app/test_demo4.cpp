// The 3+2 demo (data/demo4_*): the AC table-table machine indexes its table to A-20 in the air,
// then a D10 ball-end mill finishes three passes along the part's X on the top face with its axis
// leaning 20 deg toward the part's +Y. The bundled program and log are the generator's (regenerate
// with CUTLOAD_UPDATE_DEMO4=1 build/tests/test_app "[demo4]"), and the prediction through the
// machine, with the program, removes what the three tilted balls sweep: the reference below
// integrates the union of their sections below the top face, written from the geometry, not from
// the engine.
#include "app/inputs.hpp"
#include "app/predict_run.hpp"
#include "app_fixtures.hpp"
#include "motion_io/synth.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <numbers>
#include <sstream>

using namespace cutload;

namespace {

constexpr double kLeanDeg = 20, kBallRadiusMm = 5, kTipZmm = 29.5, kTopZmm = 30, kLengthMm = 100;
constexpr double kPassYmm[3] = {20, 22, 24};   // the tips' stock y (data/README.md, demo4)

// Section of the material the three balls leave gone below the top face, mm^2: each ball's centre
// is its tip plus the radius up the leaning axis, (y + r sin 20, z + r cos 20); at each y the cut
// reaches the lowest of the balls there. Midpoint rule on 1 um strips.
double swept_section_mm2() {
    const double s = std::sin(kLeanDeg * std::numbers::pi / 180), c = std::cos(kLeanDeg * std::numbers::pi / 180);
    const double y0 = kPassYmm[0] - kBallRadiusMm, y1 = kPassYmm[2] + 2 * kBallRadiusMm, dy = 1e-3;
    double area = 0;
    for (double y = y0 + dy / 2; y < y1; y += dy) {
        double depth = 0;
        for (const double tip_y : kPassYmm) {
            const double yc = tip_y + kBallRadiusMm * s, zc = kTipZmm + kBallRadiusMm * c;
            const double d = y - yc;
            if (std::abs(d) < kBallRadiusMm) depth = std::max(depth, kTopZmm - (zc - std::sqrt(kBallRadiusMm * kBallRadiusMm - d * d)));
        }
        area += depth * dy;
    }
    return area;
}

}  // namespace

TEST_CASE("demo4: the bundled program and log are the generator's", "[demo4]") {
    const std::string program = motion_io::demo4_program_text();
    std::ostringstream csv;
    const std::size_t rows = motion_io::synthesize_nc_dry_run(motion_io::demo4_dry_run_spec(), csv);
    if (const char* u = std::getenv("CUTLOAD_UPDATE_DEMO4"); u && std::string(u) == "1") {
        apptest::write_text(apptest::source_path("data/demo4_program.nc"), program);
        apptest::write_text(apptest::source_path("data/demo4_dryrun.csv"), csv.str());
    }
    CHECK(apptest::read_text(apptest::source_path("data/demo4_program.nc")) == program);
    CHECK(apptest::read_text(apptest::source_path("data/demo4_dryrun.csv")) == csv.str());
    CHECK(rows > 1000);
}

TEST_CASE("demo4: the tilted ball-end passes through the AC machine remove the swept section, with the program compared",
          "[demo4][five_axis][fixed_tilt]") {
    app::RunInput in;
    in.log_path = apptest::source_path("data/demo4_dryrun.csv");
    in.read = app::read_options(app::LogFormat{});
    in.spec = force_model::load_run_spec(apptest::source_path("data/demo4_run.json"));
    in.machine = app::load_machine_definition(apptest::source_path("data/machines/ac_table_table.json"));
    app::ProgramSource program;
    program.path = apptest::source_path("data/demo4_program.nc");
    program.settings.work_offsets_mm["G54"] = {-350, -275, -560};
    in.program = program;
    const app::RunResult r = app::predict_run(in);

    CHECK(r.fixed_tilt);
    CHECK(r.tool_lean_deg == Approx(kLeanDeg).margin(1e-3));
    CHECK(r.tool_axis[0] == Approx(0).margin(1e-6));
    CHECK(r.tool_axis[1] == Approx(std::sin(kLeanDeg * std::numbers::pi / 180)).margin(1e-5));

    double removed_mm3 = 0;
    for (const auto& b : r.prediction.blocks) {
        removed_mm3 += b.removed_mm3;
        CHECK(b.flags.empty());
    }
    const double reference_mm3 = swept_section_mm2() * kLengthMm;
    INFO("removed " << removed_mm3 << " mm^3, reference " << reference_mm3 << " mm^3");
    CHECK(reference_mm3 == Approx(602.4).margin(0.5));   // the section worked out above, 6.024 mm^2
    CHECK(removed_mm3 == Approx(reference_mm3).epsilon(0.005));

    // The three passes cut; the commanded prediction of the same program agrees block by block.
    REQUIRE(r.commanded);
    int passes = 0;
    for (const auto& b : r.commanded->blocks) {
        if (b.block != "N60" && b.block != "N100" && b.block != "N140") continue;
        ++passes;
        INFO(b.block << ": actual peak " << b.actual_peak_force_N << " N, commanded " << b.commanded_peak_force_N << " N");
        CHECK(b.actual_peak_force_N > 100);
        CHECK(std::abs(b.force_difference_pct) < 3);
        CHECK(b.max_deviation_mm < 0.1);
    }
    CHECK(passes == 3);
}
