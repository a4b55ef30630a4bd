// Block mapping: a log without a block channel gets the blocks of the same log with one.
#include "nc_fixtures.hpp"

#include "motion_io/block_mapping.hpp"

#include <catch2/catch.hpp>

using namespace cutload;
using namespace cutload::nctest;


TEST_CASE("mapping: the demo log without its block column gets back its blocks", "[mapping]") {
    const std::array<double, 3> work_zero{200, -300, -350};   // data/demo_run.json: offset [-200, 300, 350]
    const motion_io::DryRunSpec demo = motion_io::demo_dry_run_spec();

    // Calibrate the block lead once per machine, on a different program's log with blocks.
    const double lead_s = calibrated_lead_s();
    motion_io::BlockMappingOptions mo;

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

namespace {

// A hand-made motion model: `n` samples at 1 ms moving from `from` at `speed_mm_min` along `dir`
// (unit vector; zero speed: at rest at `from`).
void append_stretch(motion_io::MotionModel& m, std::size_t n, std::array<double, 3> from, std::array<double, 3> dir, double speed_mm_min) {
    const double v = speed_mm_min / 60.0;
    for (std::size_t k = 0; k < n; ++k) {
        const double t = double(k) * m.step_s;
        m.t_s.push_back(double(m.t_s.size()) * m.step_s);
        m.x_mm.push_back(from[0] + dir[0] * v * t);
        m.y_mm.push_back(from[1] + dir[1] * v * t);
        m.z_mm.push_back(from[2] + dir[2] * v * t);
        m.vx_mm_s.push_back(dir[0] * v);
        m.vy_mm_s.push_back(dir[1] * v);
        m.vz_mm_s.push_back(dir[2] * v);
        m.spindle_rpm.push_back(10000);
        m.spindle_angle_deg.push_back(0);
        m.block.push_back(-1);
    }
}

}  // namespace

TEST_CASE("mapping: samples at rest and rapids away from the cuts do not count against the match", "[mapping]") {
    // 1 s cutting along the program's line (matched), 1 s at rest far away, 0.5 s of rapid far
    // from the cut, then 0.5 s at cutting feed far away (the only samples that count against).
    motion_io::MotionModel m;
    m.step_s = 0.001;
    m.session_start = {0};
    append_stretch(m, 1000, {0, 0, 0}, {1, 0, 0}, 1200);
    append_stretch(m, 1000, {500, 500, 500}, {0, 0, 0}, 0);
    append_stretch(m, 500, {0, 100, 0}, {1, 0, 0}, 20000);
    append_stretch(m, 500, {0, 200, 0}, {1, 0, 0}, 1200);
    app::ProgramSettings settings;
    settings.work_offsets_mm["G54"] = {0, 0, 0};
    force_model::RunSpec run;
    const std::string text = "N1 G90 G01 X0 Y0 Z0 F1200\nN2 X20.\n";
    auto read = [&] {
        return motion_io::parse_nc_program(text, "line.nc", app::program_read_options(settings, run, app::log_start_mm(m)));
    };
    motion_io::MotionModel copy = m;
    const app::ProgramRun r = app::prepare_program_run(read(), settings, copy);
    const auto& q = r.mapping.quality;
    CHECK(q.matched == 1000);
    CHECK(q.matched_fraction == Approx(1.0 / 3));
    CHECK(q.excluded_at_rest == 1000);
    CHECK(q.excluded_away == 500);
    CHECK(q.excluded_tool_change == 0);
    CHECK(q.excluded_fraction == Approx(0.5));
    CHECK(q.counted_matched_fraction == Approx(2.0 / 3));

    // The threshold is an option; a refused program names the fractions.
    settings.min_match = 0.7;
    copy = m;
    CHECK_THROWS_WITH(app::prepare_program_run(read(), settings, copy),
                      Catch::StartsWith("line.nc: only 66.7 % of the log's counted samples lie within 5 mm of the program's path "
                                        "(at least 70 % must; 33.3 % of all samples matched, 50.0 % not counted: 33.3 % at rest, "
                                        "16.7 % rapids away from the cutting moves, 0.0 % tool changes;"));
}
