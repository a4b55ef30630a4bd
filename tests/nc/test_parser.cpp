// The ISO 6983 reader: geometry of lines and arcs (I/J/K, R, planes, helix), modal words, units,
// work offsets, and errors that name the line and the word.
#include "nc_fixtures.hpp"
#include "nc_read.hpp"

#include <catch2/catch.hpp>

#include <numbers>

using namespace cutload;
using namespace cutload::motion_io;

namespace {

NcReadOptions options(std::array<double, 3> g54 = {0, 0, 0}) {
    NcReadOptions o;
    o.work_offsets_mm["G54"] = g54;
    o.start_mm = std::array<double, 3>{0, 0, 0};
    return o;
}

NcProgram parse(const std::string& text, const NcReadOptions& o = options()) { return nctest::read_text(text, o); }
std::string error_of(const std::string& text, const NcReadOptions& o = options()) { return nctest::read_error(text, o); }
using nctest::named;

}  // namespace

TEST_CASE("parser: lines, modal feed, work offset, incremental and machine coordinates", "[parser]") {
    const NcProgram p = parse(
        "%\nO0001 (LINES)\nN1 G90 G54 G00 X10. Y20. Z5.\nN2 G01 Z-1. F300 S8000 M03 ; plunge\n"
        "N3 X30.\nN4 G91 Y-5. F600\nN5 G90 G53 G00 Z0.\nM05\nM30\n%\n",
        options({100, 200, -50}));
    CHECK(named(p, "N1").end_mm == std::array<double, 3>{110, 220, -45});
    const NcBlock& n2 = named(p, "N2");
    CHECK(n2.motion == NcMotion::Linear);
    CHECK(n2.feed_mm_min == 300);
    CHECK(n2.spindle_rpm == 8000);
    CHECK(n2.end_mm[2] == -51);
    CHECK(named(p, "N3").feed_mm_min == 300);   // modal F
    CHECK(named(p, "N3").end_mm[0] == 130);
    CHECK(named(p, "N4").end_mm == std::array<double, 3>{130, 215, -51});
    CHECK(named(p, "N4").feed_mm_min == 600);
    CHECK(named(p, "N5").end_mm == std::array<double, 3>{130, 215, 0});   // G53: machine position
    CHECK(named(p, "N5").motion == NcMotion::Rapid);
    CHECK(p.blocks.back().spindle_rpm == 0);
    CHECK(p.blocks.front().name == "L2");   // O line: a block without N is named by its line
}

TEST_CASE("parser: arcs by I/J/K and R in all planes, full circle, helix, inch", "[parser]") {
    // G17 quarter circle counter-clockwise about (10, 0) from (20, 0) to (10, 10).
    const NcProgram p = parse(
        "N1 G00 X20. Y0. Z0.\nN2 G17 G03 X10. Y10. I-10. J0. F500\nN3 G02 X20. Y0. R10.\nN4 G02 X20. Y0. I-10.\n"
        "N5 G18 G02 X30. Z10. K10.\nN6 G19 G02 Y0. Z20. R-5.\nN7 G17 G03 X30. Y0. Z10. I-10.\n");
    const NcBlock& n2 = named(p, "N2");
    CHECK(n2.center_mm[0] == Approx(10));
    CHECK(n2.sweep_rad == Approx(std::numbers::pi / 2));
    CHECK(block_length_mm(n2) == Approx(10 * std::numbers::pi / 2));
    double pos[3], t[3];
    block_point(n2, 0.5, pos, t);
    CHECK(pos[0] == Approx(10 + 10 * std::cos(std::numbers::pi / 4)));
    CHECK(pos[1] == Approx(10 * std::sin(std::numbers::pi / 4)));
    CHECK(t[0] == Approx(-std::sqrt(0.5)));   // counter-clockwise: heading up-left at 45 deg
    // R10 clockwise from (10, 10) back to (20, 0): the short way, centre (10, 0) again.
    const NcBlock& n3 = named(p, "N3");
    CHECK(n3.center_mm[0] == Approx(10).margin(1e-9));
    CHECK(n3.center_mm[1] == Approx(0).margin(1e-9));
    CHECK(n3.sweep_rad == Approx(-std::numbers::pi / 2));
    CHECK(named(p, "N4").sweep_rad == Approx(-2 * std::numbers::pi));   // full circle
    // G18: plane (Z, X), seen from +Y: centre (20, 0, 10); from (20, 0, 0) to (30, 0, 10) is a clockwise quarter.
    const NcBlock& n5 = named(p, "N5");
    CHECK(n5.center_mm[2] == Approx(10));
    CHECK(n5.center_mm[0] == Approx(20));
    CHECK(std::abs(n5.sweep_rad) == Approx(std::numbers::pi / 2));
    block_point(n5, 0.5, pos, t);
    CHECK(std::hypot(pos[0] - 20, pos[2] - 10) == Approx(10));
    // R-5 over a 10 mm chord: exactly a half circle either way.
    CHECK(std::abs(named(p, "N6").sweep_rad) == Approx(std::numbers::pi));
    // Helix: full circle in XY while Z drops 10 mm.
    const NcBlock& n7 = named(p, "N7");
    CHECK(block_length_mm(n7) == Approx(std::hypot(2 * std::numbers::pi * 10, 10)));
    const NcProgram inch = parse("N1 G20 G00 X1. Y0 Z0\nN2 G01 X2. F10.\n");
    CHECK(named(inch, "N2").end_mm[0] == Approx(50.8));
    CHECK(named(inch, "N2").feed_mm_min == Approx(254));
}

TEST_CASE("parser: errors name the file, the line and the word", "[parser][errors]") {
    CHECK(error_of("N1 G00 X0 Y0 Z0\nN2 G41 D1 X10.\n") == "t.nc:2: word 'G41': cutter radius compensation is not supported (the path would be offset by the tool radius)");
    CHECK_THAT(error_of("N1 G00 X0 Y0 Z0\n\nN3 G76 X1. Y1. Z-3. R1. Q0.1 F100\n"), Catch::StartsWith("t.nc:3: word 'G76': this canned cycle is not supported"));
    CHECK_THAT(error_of("N1 G00 X#1\n"), Catch::StartsWith("t.nc:1: word 'X#1': macro variables"));
    CHECK_THAT(error_of("N1 G00 X0 Y0 Z0\nN2 M98 P1000\n"), Catch::StartsWith("t.nc:2: word 'M98': subprograms"));
    CHECK_THAT(error_of("N1 G01 X10. Y0 Z0\n"), Catch::StartsWith("t.nc:1: word 'N1': no feed rate"));
    CHECK_THAT(error_of("N1 G00 X0 Y0 Z0\nN2 G02 X10. Y0. I3. F100\n"), Catch::StartsWith("t.nc:2: word 'G02': end point is not on the arc"));
    CHECK_THAT(error_of("N1 G00 X0 Y0 Z0\nN2 G03 X30. Y0. R10. F100\n"), Catch::StartsWith("t.nc:2: word 'R10.': radius"));
    CHECK_THAT(error_of("N1 G00 X0 Y0 Z0 A90.\n"), Catch::StartsWith("t.nc:1: word 'A90.': rotary axis A needs a machine definition"));
    CHECK_THAT(error_of("N1 G00 X0 Y0 Z0 U90.\n"), Catch::StartsWith("t.nc:1: word 'U90.': only the linear axes"));
    CHECK_THAT(error_of("N1 G00 X0 X1.\n"), Catch::StartsWith("t.nc:1: word 'X1.': appears twice"));
    CHECK_THAT(error_of("N1 G55 G00 X0\n"), Catch::StartsWith("t.nc:1: word 'G55': no offset is set"));
    CHECK_THAT(error_of("N1 G00 X0 Y0 Z0 (open comment\n"), Catch::StartsWith("t.nc:1: word '(open comment': comment without ')'"));
    CHECK_THAT(error_of("N1 G00 X0 Y0 Z0\nN2 M06\n"), Catch::StartsWith("t.nc:2: word 'M06': tool change without a tool selected"));
    CHECK_THAT(error_of("N1 G00 X[1+2]\n"), Catch::StartsWith("t.nc:1: word 'X': expected a number"));
    NcReadOptions unknown_start = options();
    unknown_start.start_mm.reset();
    CHECK_THAT(error_of("N1 G91 G00 X10.\n", unknown_start), Catch::StartsWith("t.nc:1: word 'X10.': incremental move before"));
}

TEST_CASE("parser: --ignore drops named words, the rest of the block runs", "[parser]") {
    const std::string text = "N1 G00 X0 Y0 Z50.\nN2 G91 G28 Z0.\nN3 G90 G43 H1 Z10.\n";
    CHECK_THAT(error_of(text), Catch::StartsWith("t.nc:2: word 'G28': reference position return"));
    NcReadOptions o = options();
    o.ignore_words = {"G28"};
    const NcProgram p = parse(text, o);
    CHECK(named(p, "N2").end_mm[2] == 50);   // G91 Z0: no motion
    CHECK(named(p, "N3").end_mm[2] == 10);
}

TEST_CASE("parser: without a start position, axes sit where the program first puts them", "[parser]") {
    NcReadOptions o = options();
    o.start_mm.reset();
    const NcProgram p = parse("N1 G00 Z50.\nN2 X10. Y20.\nN3 G01 Z-1. F100\n", o);
    CHECK(named(p, "N1").start_mm == std::array<double, 3>{10, 20, 50});
    CHECK(named(p, "N1").end_mm == std::array<double, 3>{10, 20, 50});
    CHECK(named(p, "N2").start_mm == std::array<double, 3>{10, 20, 50});
    CHECK(named(p, "N3").end_mm == std::array<double, 3>{10, 20, -1});
}

TEST_CASE("parser: decimal-less numbers follow FANUC parameter 3401#0 when asked", "[parser]") {
    NcReadOptions o = options();
    CHECK(named(parse("N1 G00 X10 Y0 Z0\n", o), "N1").end_mm[0] == 10);
    o.decimal_less_is_increment = true;
    CHECK(named(parse("N1 G00 X10 Y0 Z0\n", o), "N1").end_mm[0] == Approx(0.01));
    CHECK(named(parse("N1 G00 X10. Y0 Z0\n", o), "N1").end_mm[0] == 10);
}

TEST_CASE("parser: dwell by X seconds or P milliseconds", "[parser]") {
    const NcProgram p = parse("N1 G00 X0 Y0 Z0\nN2 G04 X1.5\nN3 G04 P250\n");
    CHECK(named(p, "N2").motion == NcMotion::Dwell);
    CHECK(named(p, "N2").dwell_s == 1.5);
    CHECK(named(p, "N3").dwell_s == Approx(0.25));
    CHECK(named(p, "N2").end_mm == std::array<double, 3>{0, 0, 0});
}
