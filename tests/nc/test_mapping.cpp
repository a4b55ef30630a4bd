// Block mapping: a log without a block channel gets the blocks of the same log with one.
#include "nc_fixtures.hpp"

#include "motion_io/block_mapping.hpp"

#include <catch2/catch.hpp>

using namespace cutload;
using namespace cutload::nctest;

namespace {

// A small zig-zag with corners at two feeds and rapids: calibrates the machine's block lead.
motion_io::DryRunSpec calibration_spec() {
    motion_io::DryRunSpec spec;
    spec.start_mm[0] = 0, spec.start_mm[1] = 0, spec.start_mm[2] = 50;
    auto add = [&](const char* name, bool rapid, double x, double y, double z, double f) {
        motion_io::ProgramBlock b;
        b.name = name;
        b.rapid = rapid;
        b.target_mm[0] = x, b.target_mm[1] = y, b.target_mm[2] = z;
        b.feed_mm_min = f;
        spec.program.push_back(b);
    };
    add("N1", true, 10, 0, 50, 0);
    add("N2", true, 10, 0, 5, 0);
    add("N3", false, 40, 0, 5, 6000);
    add("N4", false, 40, 20, 5, 6000);
    add("N5", false, 10, 20, 5, 3000);
    add("N6", false, 10, 40, 5, 3000);
    add("N7", true, 10, 40, 50, 0);
    spec.machine.spindle_ramp_s = 0;
    spec.seed = 99;
    return spec;
}

}  // namespace

TEST_CASE("mapping: the demo log without its block column gets back its blocks", "[mapping]") {
    const std::array<double, 3> work_zero{200, -300, -350};   // data/demo_run.json: offset [-200, 300, 350]
    const motion_io::DryRunSpec demo = motion_io::demo_dry_run_spec();

    // Calibrate the block lead once per machine, on a different program's log with blocks.
    const motion_io::DryRunSpec cal = calibration_spec();
    const motion_io::MotionModel cal_log = dry_run_motion(cal, "cal");
    const motion_io::NcProgram cal_prog = motion_io::parse_nc_program(program_text(cal, {0, 0, 0}), "cal.nc", read_options_for(cal, {0, 0, 0}));
    motion_io::BlockMappingOptions mo;
    const double lead_s = motion_io::estimate_block_lead_s(cal_log, cal_prog, mo);

    const motion_io::MotionModel with_blocks = dry_run_motion(demo, "demo_blocks");
    const motion_io::MotionModel without = dry_run_motion(demo, "demo_noblocks", 1.0, false);
    REQUIRE(with_blocks.size() == without.size());
    REQUIRE(std::all_of(without.block.begin(), without.block.end(), [](std::int32_t b) { return b < 0; }));
    const motion_io::NcProgram prog =
        motion_io::read_nc_program(source_path("data/demo_program.nc"), read_options_for(demo, work_zero));

    mo.lead_s = 0;
    const motion_io::BlockMapping geometric = motion_io::map_blocks(without, prog, mo);
    const double geometric_agreement = motion_io::block_agreement(with_blocks, geometric.block, geometric.block_names);
    mo.lead_s = lead_s;
    const motion_io::BlockMapping m = motion_io::map_blocks(without, prog, mo);
    const double agreement = motion_io::block_agreement(with_blocks, m.block, m.block_names);
    const auto& q = m.quality;
    WARN(fmt::format("demo log ({} samples): calibrated lead {:.0f} ms; agreement {:.2f}% with it, {:.2f}% without; "
                     "matched {:.2f}%, deviation mean {:.3f} p95 {:.3f} max {:.3f} mm, coverage {:.2f}%, {} blocks without samples",
                     without.size(), lead_s * 1e3, 100 * agreement, 100 * geometric_agreement, 100 * q.matched_fraction,
                     q.mean_distance_mm, q.p95_distance_mm, q.max_distance_mm, 100 * q.coverage, q.blocks_without_samples.size()));
    CHECK(lead_s > 0.005);
    CHECK(lead_s < 0.1);
    CHECK(agreement > 0.98);
    CHECK(agreement > geometric_agreement);
    CHECK(q.matched_fraction == 1.0);
    CHECK(q.coverage > 0.999);
    CHECK(q.blocks_without_samples.empty());
    CHECK(!q.agreement.has_value());   // the mapped log had no blocks to agree with

    // The log that has blocks reports the agreement itself.
    const motion_io::BlockMapping checked = motion_io::map_blocks(with_blocks, prog, mo);
    REQUIRE(checked.quality.agreement.has_value());
    CHECK(*checked.quality.agreement == Approx(agreement).margin(1e-12));
}

TEST_CASE("mapping: samples far from the program stay unmatched", "[mapping]") {
    const motion_io::DryRunSpec cal = calibration_spec();
    const motion_io::MotionModel log = dry_run_motion(cal, "far");
    motion_io::NcReadOptions ro = read_options_for(cal, {0, 0, 0});
    ro.work_offsets_mm["G54"] = {0, 100, 0};   // the program sits 100 mm away from where the log ran
    ro.start_mm.reset();
    const motion_io::NcProgram prog = motion_io::parse_nc_program(program_text(cal, {0, 0, 0}), "far.nc", ro);
    const motion_io::BlockMapping m = motion_io::map_blocks(log, prog, {});
    CHECK(m.quality.matched_fraction < 0.05);
    CHECK(m.quality.coverage < 0.05);
}
