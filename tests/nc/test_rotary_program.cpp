// Five-axis NC programs in machine-axis form (docs/nc_program.md, "Rotary axes"): A/B/C words read
// with a machine's rotary axes, every axis linear between block end points, G93 inverse time and
// the G94 rotary feed rules; the commanded motion's rotary channels; the generator's a/b/c columns;
// and the clear refusals (no machine, an axis the machine lacks, tool-centre-point mode without the
// machine's kinematics).
#include "nc_fixtures.hpp"
#include "nc_read.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>

using namespace cutload;
using namespace cutload::motion_io;
using namespace cutload::nctest;

namespace {

NcReadOptions ac_options(RotaryFeed feed = RotaryFeed::Combined, std::array<double, 3> start_mm = {0, 0, 0}) {
    NcReadOptions o;
    o.work_offsets_mm["G54"] = {0, 0, 0};
    o.start_mm = start_mm;
    o.rotary_axes = "AC";
    o.rotary_feed = feed;
    return o;
}

NcProgram parse(const std::string& text, const NcReadOptions& o = ac_options()) { return read_text(text, o); }
std::string error_of(const std::string& text, const NcReadOptions& o) { return read_error(text, o); }

}  // namespace

TEST_CASE("rotary program: A/B/C words are machine angles, each axis linear between block ends", "[parser][rotary]") {
    const NcProgram p = parse("N1 G00 X10. Y0 Z5. A0 C0\n"
                              "N2 G01 C90. F1800\n"
                              "N3 G91 C-30. A-10.\n"
                              "N4 G90 X20. C0\n"
                              "N5 G01 Z0 F600\n");
    CHECK(p.rotary_axes == "ac");
    CHECK(named(p, "N2").start_deg == std::array<double, 3>{0, 0, 0});
    CHECK(named(p, "N2").end_deg == std::array<double, 3>{0, 0, 90});
    CHECK(named(p, "N3").end_deg == std::array<double, 3>{-10, 0, 60});   // incremental
    CHECK(named(p, "N4").end_deg == std::array<double, 3>{-10, 0, 0});
    CHECK(block_turns(named(p, "N2")));
    CHECK(block_moves(named(p, "N2")));                   // a pure turn moves, with no X/Y/Z travel
    CHECK(block_length_mm(named(p, "N2")) == 0);
    CHECK_FALSE(block_turns(named(p, "N5")));
    // G94 combined (FANUC): F1800 over sqrt(90^2) "mm" is 3 s; over sqrt(10^2 + 30^2) 1.054 s.
    CHECK(block_time_s(named(p, "N2"), 30000) == Approx(3.0).epsilon(1e-12));
    CHECK(block_time_s(named(p, "N3"), 30000) == Approx(std::hypot(10.0, 30.0) / 1800 * 60).epsilon(1e-12));
    // X 10 mm with C 60 deg: sqrt(10^2 + 60^2) / 1800 min.
    CHECK(block_time_s(named(p, "N4"), 30000) == Approx(std::hypot(10.0, 60.0) / 1800 * 60).epsilon(1e-12));
    // A plain three-axis block keeps its length over F.
    CHECK(named(p, "N5").feed_time_s == 0);
    CHECK(block_time_s(named(p, "N5"), 30000) == Approx(5.0 / 600 * 60).epsilon(1e-12));
    // A rapid that turns: the combined length at the rapid rate.
    CHECK(block_time_s(named(p, "N1"), 30000) == Approx(std::hypot(10.0, 5.0) / 30000 * 60).epsilon(1e-12));
}

TEST_CASE("rotary program: linear_only applies F to X/Y/Z, a pure turn reads F in deg/min", "[parser][rotary]") {
    const NcProgram p = parse("N1 G00 X0 Y0 Z0 C0\nN2 G01 X10. C60. F600\nN3 C0 F1800\n", ac_options(RotaryFeed::LinearOnly));
    CHECK(block_time_s(named(p, "N2"), 30000) == Approx(1.0).epsilon(1e-12));   // 10 mm at 600 mm/min
    CHECK(block_time_s(named(p, "N3"), 30000) == Approx(2.0).epsilon(1e-12));   // 60 deg at 1800 deg/min
    CHECK(parse_rotary_feed("linear_only") == RotaryFeed::LinearOnly);
    CHECK(parse_rotary_feed("combined") == RotaryFeed::Combined);
    CHECK_FALSE(parse_rotary_feed("fanuc").has_value());
}

TEST_CASE("rotary program: G93 takes 1/F minutes per block, G94 brings the feed back", "[parser][rotary]") {
    const NcProgram p = parse("N1 G00 X35. Y0 Z0 C0\nN2 G01 Z-2. F300\nN3 G93 C360. F13.642\nN4 X38. F120\nN5 G94 C0 F3600\n"
                              "N6 Z0\n");
    CHECK(named(p, "N3").inverse_time);
    CHECK(block_time_s(named(p, "N3"), 30000) == Approx(60.0 / 13.642).epsilon(1e-12));
    CHECK(block_time_s(named(p, "N4"), 30000) == Approx(0.5).epsilon(1e-12));   // a linear G93 move too
    CHECK_FALSE(named(p, "N5").inverse_time);
    CHECK(block_time_s(named(p, "N5"), 30000) == Approx(6.0).epsilon(1e-12));   // 360 deg at 3600
    // The G93 F words were not feeds: N6 runs at the last G94 F.
    CHECK(named(p, "N6").feed_mm_min == 3600);
    // Inch: the combined rule counts degrees as inches; 1 in and 3 deg at F10 in/min.
    const NcProgram inch = parse("N1 G20 G00 X0 Y0 Z0 C0\nN2 G01 X1. C3. F10.\n");
    CHECK(block_time_s(named(inch, "N2"), 30000) == Approx(std::hypot(1.0, 3.0) / 10 * 60).epsilon(1e-12));
}

TEST_CASE("rotary program: refusals name the line, the word and why", "[parser][rotary][errors]") {
    NcReadOptions three_axis = ac_options();
    three_axis.rotary_axes.clear();
    CHECK(error_of("N1 G00 X0 Y0 Z0\nN2 G01 C90. F100\n", three_axis) ==
          "t.nc:2: word 'C90.': rotary axis C needs a machine definition with that axis (--machine FILE): without one the program is "
          "read as three-axis, and a rotary move cannot be left out");
    CHECK_THAT(error_of("N1 G93 G01 X1. F2.\n", three_axis), Catch::StartsWith("t.nc:1: word 'G93': inverse time feed (G93) is read only"));
    CHECK(error_of("N1 G00 X0 Y0 Z0 B10.\n", ac_options()) == "t.nc:1: word 'B10.': the machine has no rotary axis B (its rotary axes: AC)");
    CHECK_THAT(error_of("N1 G00 X0 Y0 Z0\nN2 G43.4 H1\n", ac_options()),
               Catch::StartsWith("t.nc:2: word 'G43.4': tool-centre-point control (G43.4) needs the machine's kinematics"));
    CHECK_THAT(error_of("N1 G00 X0 Y0 Z0\nN2 G43.5 H1\n", ac_options()),
               Catch::StartsWith("t.nc:2: word 'G43.5': tool-centre-point control (G43.5) needs the machine's kinematics"));
    CHECK_THAT(error_of("N1 G00 X0 Y0 Z0\nN2 G93 G01 C10.\n", ac_options()), Catch::StartsWith("t.nc:2: word 'N2': in inverse time (G93) every feed move needs its own F"));
    CHECK_THAT(error_of("N1 G00 X0 Y0 Z0\nN2 G02 X10. I5. C10. F100\n", ac_options()), Catch::StartsWith("t.nc:2: word 'C10.': a rotary axis cannot move in an arc block"));
    CHECK_THAT(error_of("N1 G00 X0 Y0 Z10.\nN2 G81 X5. Z-1. R1. C10. F100\n", ac_options()), Catch::StartsWith("t.nc:2: word 'C10.': a rotary word in a canned cycle"));
    CHECK_THAT(error_of("N1 G00 X0 Y0 Z0\nN2 G01 C2000000. F100\n", ac_options()), Catch::Contains("outside the physical range"));
}

TEST_CASE("rotary program: the commanded motion turns each axis linearly in its block's time", "[commanded][rotary]") {
    const NcProgram p = parse("N1 G00 X35. Y0 Z0 A0 C0\nN2 G93 G01 C90. F20.\nN3 G94 X40. C0 F1000\n",
                              ac_options(RotaryFeed::Combined, {35, 0, 0}));
    CommandedOptions co;
    co.step_s = 0.001;
    const MotionModel m = commanded_motion(p, co);
    REQUIRE(m.has_rotary(0));
    REQUIRE(m.has_rotary(2));
    CHECK_FALSE(m.has_rotary(1));
    // N1 is a zero-length rapid (no motion); N2 takes 3 s (1/20 min), N3 sqrt(5^2 + 90^2)/1000 min.
    const double n3_s = std::hypot(5.0, 90.0) / 1000 * 60;
    CHECK(m.t_s.back() == Approx(3.0 + n3_s).margin(0.0011));
    const std::size_t mid = 1500;   // 1.5 s into N2
    CHECK(m.rot_deg[2][mid] == Approx(45.0).margin(1e-9));
    CHECK(m.rot_vel_deg_s[2][mid] == Approx(30.0).margin(1e-9));
    CHECK(m.x_mm[mid] == Approx(35.0).margin(1e-12));
    CHECK(m.vx_mm_s[mid] == 0);
    const std::size_t in_n3 = 3000 + 100;
    CHECK(m.rot_vel_deg_s[2][in_n3] == Approx(-90.0 / n3_s).epsilon(1e-9));
    CHECK(m.vx_mm_s[in_n3] == Approx(5.0 / n3_s).epsilon(1e-9));
    CHECK(m.rot_deg[2].back() == Approx(0).margin(1e-9));
    CHECK(m.rot_vel_deg_s[2].back() == 0);   // at rest at the end
}

TEST_CASE("generator: a program that turns rotary axes gets a, c columns with lag and 0.001 deg readings", "[synth][rotary]") {
    NcDryRunSpec spec;
    spec.program = parse("N1 G00 X35. Y0 Z0 A0 C0\nN2 G93 G01 C90. F20.\nN3 G94 X40. F1000\n",
                         ac_options(RotaryFeed::Combined, {35, 0, 0}));
    spec.start_mm[0] = 35;
    spec.machine.max_accel_mm_s2 = 2500;
    spec.seed = 7;
    std::ostringstream csv;
    synthesize_nc_dry_run(spec, csv);
    std::istringstream in(csv.str());
    std::string header;
    std::getline(in, header);
    CHECK(header == "t_spindle [s],spindle [rpm],t_feed [s],feed [mm/min],t_pos [s],x [mm],y [mm],z [mm],a [deg],c [deg],tool,block");
    // Per row: the C reading, the block, and the time.
    double c_at_n3_start = -1, c_last = 0, t_c45 = -1, t_c60 = -1;
    bool quantised = true;
    for (std::string line; std::getline(in, line);) {
        std::vector<std::string> f;
        std::stringstream ss(line);
        for (std::string cell; std::getline(ss, cell, ',');) f.push_back(cell);
        if (line.back() == ',') f.emplace_back();
        REQUIRE(f.size() == 12);
        const double t = std::stod(f[4]), c = std::stod(f[9]);
        quantised = quantised && f[9].size() - f[9].find('.') == 4 && f[8] == "0.000";
        if (f[11] == "N3" && c_at_n3_start < 0) c_at_n3_start = c;
        if (t_c45 < 0 && c >= 45) t_c45 = t;
        if (t_c60 < 0 && c >= 60) t_c60 = t;
        c_last = c;
    }
    CHECK(quantised);
    // Servo lag and acc/dec: when the interpolator passes on to N3, C has not arrived yet; it
    // gets there after.
    CHECK(c_at_n3_start < 89.9);
    CHECK(c_at_n3_start > 80);
    CHECK(c_last == 90.0);
    // Mid-turn, C runs at the G93 rate: 90 deg in 3 s.
    CHECK((60.0 - 45.0) / (t_c60 - t_c45) == Approx(30.0).epsilon(0.01));
}
