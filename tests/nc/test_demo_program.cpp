// data/demo_program.nc is the demo log's program: generated from demo_dry_run_spec() (the
// definition data/demo_dryrun.csv comes from), checked here, and regenerated with
//   CUTLOAD_UPDATE_DEMO_PROGRAM=1 build/tests/test_nc "[demo]"
#include "nc_fixtures.hpp"

#include "motion_io/commanded.hpp"

#include <catch2/catch.hpp>

#include <cstdlib>

using namespace cutload;
using namespace cutload::nctest;

namespace {

std::array<double, 3> demo_work_zero() {
    const force_model::RunSpec spec = force_model::load_run_spec(source_path("data/demo_run.json"));
    return {-spec.offset_mm[0], -spec.offset_mm[1], -spec.offset_mm[2]};
}

std::string demo_program_text() {
    NcStyle style;
    style.header_comment = "CUTLOAD DEMO: POCKET IN 2 LEVELS, CONTOUR FINISH. WORK ZERO G54 = STOCK MIN CORNER";
    return program_text(motion_io::demo_dry_run_spec(), demo_work_zero(), style);
}

}  // namespace

TEST_CASE("demo: data/demo_program.nc is the program of demo_dry_run_spec()", "[demo]") {
    const std::string path = source_path("data/demo_program.nc");
    const std::string expected = demo_program_text();
    if (const char* update = std::getenv("CUTLOAD_UPDATE_DEMO_PROGRAM"); update && std::string(update) == "1") {
        std::ofstream(path, std::ios::binary) << expected;
        WARN("rewrote " << path);
    }
    CHECK(read_text(path) == expected);
}

TEST_CASE("demo: the parsed demo program reproduces the generator's blocks in machine coordinates", "[demo]") {
    const motion_io::DryRunSpec spec = motion_io::demo_dry_run_spec();
    const force_model::RunSpec run = force_model::load_run_spec(source_path("data/demo_run.json"));
    motion_io::NcReadOptions opt;
    opt.work_offsets_mm = motion_io::default_work_offsets(run.offset_mm);
    opt.start_mm = std::array<double, 3>{spec.start_mm[0], spec.start_mm[1], spec.start_mm[2]};
    const motion_io::NcProgram prog = motion_io::read_nc_program(source_path("data/demo_program.nc"), opt);
    std::vector<const motion_io::NcBlock*> moving;
    for (const auto& b : prog.blocks)
        if (motion_io::block_moves(b)) moving.push_back(&b);
    REQUIRE(moving.size() == spec.program.size());
    for (std::size_t i = 0; i < moving.size(); ++i) {
        const auto& want = spec.program[i];
        const auto& got = *moving[i];
        INFO(want.name << " at line " << got.line);
        CHECK(got.name == want.name);
        CHECK((got.motion == motion_io::NcMotion::Rapid) == want.rapid);
        for (int a = 0; a < 3; ++a) CHECK(got.end_mm[a] == Approx(want.target_mm[a]).margin(1e-9));
        if (!want.rapid) CHECK(got.feed_mm_min == want.feed_mm_min);
        CHECK(got.spindle_rpm == spec.machine.spindle_rpm);
    }
    CHECK(prog.blocks.back().spindle_rpm == 0);   // M05 before M30
    CHECK(moving.front()->name == "N10");
    CHECK(moving.back()->name == "N610");
}
