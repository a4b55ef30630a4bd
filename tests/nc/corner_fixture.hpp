// The inner-corner finishing case shared by the corner and optimizer tests: a pocket roughed to
// leave 1 mm on two walls meeting at a corner, then finished by a program run on the demo's
// machine model (acceleration/deceleration after interpolation, servo lag).
#pragma once

#include "nc_fixtures.hpp"

#include "motion_io/commanded.hpp"

#include <algorithm>

namespace cutload::nctest {

struct CornerCase {
    motion_io::DryRunSpec dry_run;
    motion_io::NcProgram program;
    motion_io::MotionModel actual;      // the dry-run log, ingested at 1 ms
    force_model::RunSpec spec;
    force_model::StockPtr roughed;      // pocket x < 19, y < 19 cleared to z 2 (stock coordinates)
};

inline force_model::RunSpec corner_spec() {
    force_model::RunSpec s;
    s.tool.diameter_mm = 8;
    s.tool.flutes = 2;
    s.tool.helix_deg = 30;
    s.tool.flute_length_mm = 20;
    s.tool.stickout_mm = 30;
    s.material = {"Al7075-T6", 767.0, 168.8, 222.0, 27.7, 26.6, 0.7};
    s.stock.max_mm[0] = 30, s.stock.max_mm[1] = 30, s.stock.max_mm[2] = 6;
    s.offset_mm[0] = -100, s.offset_mm[1] = -100, s.offset_mm[2] = -100;   // work zero at machine (100, 100, 100)
    s.resolution = {4, 0.2, 0.1};
    return s;
}

inline CornerCase corner_case() {
    CornerCase c;
    c.spec = corner_spec();
    const std::array<double, 3> zero{100, 100, 100};
    // Tool-tip path in stock coordinates: along the wall y = 20 into the corner (16, 16), then out
    // along the wall x = 20; tip at z 3 (axial 3 mm), 1 mm radial.
    auto& p = c.dry_run.program;
    auto add = [&](const char* name, bool rapid, double x, double y, double z, double f) {
        motion_io::ProgramBlock b;
        b.name = name;
        b.rapid = rapid;
        b.target_mm[0] = zero[0] + x, b.target_mm[1] = zero[1] + y, b.target_mm[2] = zero[2] + z;
        b.feed_mm_min = f;
        p.push_back(b);
    };
    add("N10", true, -6, 16, 3, 0);
    add("N20", false, 6, 16, 3, 6000);
    add("N30", false, 16, 16, 3, 6000);
    add("N40", false, 16, -6, 3, 6000);
    add("N50", true, 16, -6, 20, 0);
    c.dry_run.start_mm[0] = zero[0] - 6, c.dry_run.start_mm[1] = zero[1] + 16, c.dry_run.start_mm[2] = zero[2] + 20;
    c.dry_run.machine.spindle_ramp_s = 0;
    c.dry_run.seed = 4242;
    c.program = motion_io::parse_nc_program(program_text(c.dry_run, zero), "corner.nc", read_options_for(c.dry_run, zero));
    c.actual = dry_run_motion(c.dry_run, "corner");

    // Roughing, exactly as programmed: rows at y 15, 8, 1 to x 15 leave 1 mm on the walls x = 20
    // and y = 20 down to z 2.
    motion_io::NcReadOptions ro;
    ro.work_offsets_mm["G54"] = zero;
    ro.start_mm = std::array<double, 3>{zero[0] - 6, zero[1] + 15, zero[2] + 20};
    const motion_io::NcProgram rough = motion_io::parse_nc_program(
        "N1 G00 X-6. Y15. Z2. S10000 M03\nN2 G01 X15. F6000\nN3 G00 Y8.\nN4 G01 X-6.\nN5 G00 Y1.\nN6 G01 X15.\n", "rough.nc", ro);
    motion_io::CommandedOptions co;
    force_model::PredictOptions opt;
    opt.device = force_model::Device::Cpu;
    c.roughed = std::move(force_model::predict(motion_io::commanded_motion(rough, co), c.spec, opt).final_stock);
    return c;
}

inline force_model::PredictOptions predict_options(const CornerCase& c) {
    force_model::PredictOptions opt;
    opt.device = force_model::Device::Cpu;
    opt.base_stock = c.roughed.get();
    return opt;
}

}  // namespace cutload::nctest
