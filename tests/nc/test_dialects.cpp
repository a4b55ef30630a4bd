// Issue 12, NC dialects of whole shop programs: arc-centre modes (G90.1/G91.1 and the default),
// the unit of a program without G20/G21, a control-like arc end tolerance (3-decimal inch posts),
// canned drilling cycles expanded into motion (checked against motion worked out by hand from
// the cycle definitions in docs/nc_program.md), G53, tape marks, program numbers, block skip,
// bytes that are not UTF-8, and tool selection carried into blocks and the commanded motion.
#include "nc_fixtures.hpp"
#include "nc_read.hpp"

#include "motion_io/commanded.hpp"

#include <catch2/catch.hpp>

#include <numbers>
#include <random>

using namespace cutload;
using namespace cutload::motion_io;
using cutload::nctest::nc_number;

namespace {

NcReadOptions options() {
    NcReadOptions o;
    o.work_offsets_mm["G54"] = {0, 0, 0};
    o.start_mm = std::array<double, 3>{0, 0, 50};
    return o;
}

NcProgram parse(const std::string& text, const NcReadOptions& o = options()) { return nctest::read_text(text, o); }
std::string error_of(const std::string& text, const NcReadOptions& o = options()) { return nctest::read_error(text, o); }

std::vector<const NcBlock*> named(const NcProgram& p, const std::string& name) {
    std::vector<const NcBlock*> out;
    for (const auto& b : p.blocks)
        if (b.name == name) out.push_back(&b);
    return out;
}

// One expected piece of a canned cycle: kind and end point (the start is the previous end).
struct Piece {
    NcMotion motion;
    double x, y, z;
    double dwell_s = 0;
};

void check_pieces(const NcProgram& p, const std::string& name, std::array<double, 3> from, const std::vector<Piece>& want,
                  int cycle) {
    const auto got = named(p, name);
    REQUIRE(got.size() == want.size());
    for (std::size_t k = 0; k < want.size(); ++k) {
        INFO(name << " piece " << k);
        const NcBlock& b = *got[k];
        CHECK(b.motion == want[k].motion);
        CHECK(b.cycle == cycle);
        for (int a = 0; a < 3; ++a) CHECK(b.start_mm[a] == Approx(from[a]).margin(1e-9));
        const std::array<double, 3> end{want[k].x, want[k].y, want[k].z};
        for (int a = 0; a < 3; ++a) CHECK(b.end_mm[a] == Approx(end[a]).margin(1e-9));
        CHECK(b.dwell_s == Approx(want[k].dwell_s));
        from = end;
    }
}

constexpr NcMotion R = NcMotion::Rapid, L = NcMotion::Linear, D = NcMotion::Dwell;

}  // namespace

TEST_CASE("dialects: arc centres incremental (G91.1, default) or absolute (G90.1, or the option)", "[dialects]") {
    // The same quarter circle about (10, 0) from (20, 0) to (10, 10), written both ways.
    const std::string incremental = "N1 G00 X20. Y0 Z0\nN2 G03 X10. Y10. I-10. J0 F500\n";
    const std::string absolute = "N1 G00 X20. Y0 Z0\nN2 G90.1 G03 X10. Y10. I10. J0 F500\n";
    for (const NcProgram& p : {parse(incremental), parse(absolute)}) {
        const NcBlock& n2 = *named(p, "N2").front();
        CHECK(n2.center_mm[0] == Approx(10));
        CHECK(n2.center_mm[1] == Approx(0).margin(1e-12));
        CHECK(n2.sweep_rad == Approx(std::numbers::pi / 2));
    }
    // The default can be absolute; G91.1 in the program turns it back.
    NcReadOptions o = options();
    o.arc_centers = ArcCenters::Absolute;
    CHECK(named(parse("N1 G00 X20. Y0 Z0\nN2 G03 X10. Y10. I10. J0 F500\n", o), "N2").front()->center_mm[0] == Approx(10));
    CHECK(named(parse("N1 G00 X20. Y0 Z0\nN2 G91.1 G03 X10. Y10. I-10. J0 F500\n", o), "N2").front()->center_mm[0] == Approx(10));
    // Absolute centres are work coordinates: the work offset applies to them as to X/Y.
    o.work_offsets_mm["G54"] = {100, 200, 0};
    const NcBlock& shifted = *named(parse("N1 G00 X20. Y0 Z0\nN2 G03 X10. Y10. I10. J0 F500\n", o), "N2").front();
    CHECK(shifted.center_mm[0] == Approx(110));
    CHECK(shifted.center_mm[1] == Approx(200));
    // The wrong mode is an arc whose end is off its circle, and the message says which mode was in force.
    CHECK_THAT(error_of(absolute.substr(0, absolute.find("G90.1")) + "G03 X10. Y10. I10. J0 F500\n"),
               Catch::Contains("end point is not on the arc") && Catch::Contains("incremental (G91.1)"));
}

TEST_CASE("dialects: a program without G20/G21 takes the unit option, G20/G21 override it", "[dialects]") {
    NcReadOptions o = options();
    o.program_units = ProgramUnits::Inch;
    const NcProgram p = parse("N1 G00 X1. Y0 Z0\nN2 G01 X2. F10.\nN3 G21 X50.\n", o);
    CHECK(named(p, "N1").front()->end_mm[0] == Approx(25.4));
    CHECK(named(p, "N2").front()->end_mm[0] == Approx(50.8));
    CHECK(named(p, "N2").front()->feed_mm_min == Approx(254));
    CHECK(named(p, "N2").front()->inch);
    CHECK(named(p, "N3").front()->end_mm[0] == Approx(50));
    CHECK(named(p, "N3").front()->feed_mm_min == Approx(254));   // the modal feed is a speed, not a number
    CHECK(named(parse("N1 G00 X1. Y0 Z0\n"), "N1").front()->end_mm[0] == Approx(1));   // default mm
}

TEST_CASE("dialects: absolute arcs of a 3-decimal inch post are accepted, a real error is not", "[dialects]") {
    // 300 counter-clockwise arcs with random centres, radii (0.05-3 in) and sweeps (6-180 deg),
    // start, end and centre each rounded to 0.001 in as a post writes them. Seeded: the same arcs
    // on every run.
    std::mt19937_64 rng(20250212);
    auto uniform = [&](double lo, double hi) { return lo + (hi - lo) * double(rng() >> 11) * 0x1.0p-53; };
    auto r3 = [](double v) { return std::round(v * 1000) / 1000; };
    std::string text = "G17 G90 G90.1\nN1 G00 X0 Y0 Z0\n";
    double worst_mm = 0;
    struct Want {
        double cx, cy, ex, ey;
    };
    std::vector<Want> want;
    for (int k = 0; k < 300; ++k) {
        const double cx = uniform(-5, 5), cy = uniform(-5, 5), r = uniform(0.05, 3), a0 = uniform(0, 2 * std::numbers::pi);
        const double a1 = a0 + uniform(0.1, std::numbers::pi);
        const double sx = r3(cx + r * std::cos(a0)), sy = r3(cy + r * std::sin(a0)), ex = r3(cx + r * std::cos(a1)),
                     ey = r3(cy + r * std::sin(a1)), icx = r3(cx), icy = r3(cy);
        worst_mm = std::max(worst_mm, 25.4 * std::abs(std::hypot(ex - icx, ey - icy) - std::hypot(sx - icx, sy - icy)));
        text += fmt::format("G00 X{} Y{}\nN{} G03 X{} Y{} I{} J{} F20.\n", nc_number(sx), nc_number(sy), 10 + k, nc_number(ex),
                            nc_number(ey), nc_number(icx), nc_number(icy));
        want.push_back({icx, icy, ex, ey});
    }
    NcReadOptions o = options();
    o.program_units = ProgramUnits::Inch;   // no G20 in the text
    const NcProgram p = parse(text, o);
    WARN("300 rounded arcs: the worst end lies " << worst_mm << " mm off the circle through its start");
    CHECK(worst_mm > 0.02);   // the rounding is real: the old 0.01 mm limit refused these
    CHECK(worst_mm < o.arc_tolerance_mm);
    for (int k = 0; k < 300; ++k) {
        const NcBlock& b = *named(p, fmt::format("N{}", 10 + k)).front();
        INFO("arc " << k);
        CHECK(b.center_mm[0] == Approx(25.4 * want[k].cx).margin(1e-9));
        CHECK(b.center_mm[1] == Approx(25.4 * want[k].cy).margin(1e-9));
        double pos[3], t[3];
        block_point(b, 1.0, pos, t);   // the path ends exactly at the programmed end
        CHECK(pos[0] == Approx(25.4 * want[k].ex).margin(1e-9));
        CHECK(pos[1] == Approx(25.4 * want[k].ey).margin(1e-9));
    }
    // An end 0.004 in (0.10 mm) off its circle is refused, and the tolerance is an option.
    const std::string off = "G90.1\nN1 G00 X1. Y0 Z0\nN2 G03 X0 Y1.004 I0 J0 F20.\n";
    CHECK_THAT(error_of(off, o), Catch::StartsWith("t.nc:3: word 'G03': end point is not on the arc: radius 25.4000 mm at the start, 25.5016 mm"));
    o.arc_tolerance_mm = 0.11;
    CHECK_NOTHROW(parse(off, o));
    // The tolerance grows with the radius (0.01 %): a 2540 mm radius takes 0.254 mm more.
    o.arc_tolerance_mm = 0.075;
    CHECK_NOTHROW(parse("G90.1\nN1 G00 X100. Y0 Z0\nN2 G03 X0 Y100.01 I0 J0 F20.\n", o));
}

TEST_CASE("dialects: G81 and G82 drill to Z, G82 dwells, G98 returns to the initial level", "[dialects][cycles]") {
    const NcProgram p = parse(
        "N1 G90 G00 X10. Y20. Z30.\n"
        "N2 G98 G81 X40. Y20. Z-5. R2. F100\n"
        "N3 G82 X50. P500\n"
        "N4 G80\nN5 G00 X0\n");
    check_pieces(p, "N2", {10, 20, 30}, {{R, 40, 20, 30}, {R, 40, 20, 2}, {L, 40, 20, -5}, {R, 40, 20, 30}}, 81);
    // Modal hole data: N3 repeats Z-5 R2 at X50 and dwells 0.5 s at the bottom.
    check_pieces(p, "N3", {40, 20, 30}, {{R, 50, 20, 30}, {R, 50, 20, 2}, {L, 50, 20, -5}, {D, 50, 20, -5, 0.5}, {R, 50, 20, 30}}, 82);
    // G80 ends the cycle: N5 is an ordinary rapid again.
    REQUIRE(named(p, "N5").size() == 1);
    CHECK(named(p, "N5").front()->cycle == 0);
    CHECK(named(p, "N5").front()->end_mm == std::array<double, 3>{0, 20, 30});
    for (const NcBlock* b : named(p, "N2"))
        if (b->motion == L) CHECK(b->feed_mm_min == 100);
}

TEST_CASE("dialects: G83 pecks with a full retract to R, G73 with a small retract", "[dialects][cycles]") {
    // R 2, bottom -5, Q 2: pecks to 0, -2, -4, -5. G83 comes back by rapid to 0.5 mm above the
    // last depth (peck_clearance_mm); G73 retracts 0.5 mm (peck_retract_mm) and feeds on.
    const NcProgram g83 = parse("N1 G90 G00 X10. Y20. Z30.\nN2 G98 G83 Z-5. R2. Q2. F100\n");
    check_pieces(g83, "N2", {10, 20, 30},
                 {{R, 10, 20, 2}, {L, 10, 20, 0}, {R, 10, 20, 2}, {R, 10, 20, 0.5}, {L, 10, 20, -2}, {R, 10, 20, 2},
                  {R, 10, 20, -1.5}, {L, 10, 20, -4}, {R, 10, 20, 2}, {R, 10, 20, -3.5}, {L, 10, 20, -5}, {R, 10, 20, 30}},
                 83);
    const NcProgram g73 = parse("N1 G90 G00 X10. Y20. Z30.\nN2 G99 G73 Z-5. R2. Q2. F100\n");
    check_pieces(g73, "N2", {10, 20, 30},
                 {{R, 10, 20, 2}, {L, 10, 20, 0}, {R, 10, 20, 0.5}, {L, 10, 20, -2}, {R, 10, 20, -1.5}, {L, 10, 20, -4},
                  {R, 10, 20, -3.5}, {L, 10, 20, -5}, {R, 10, 20, 2}},   // G99: back to R
                 73);
    // The retract and clearance are machine parameters (FANUC 5114, 5115).
    NcReadOptions o = options();
    o.peck_clearance_mm = 1;
    const NcProgram wide = parse("N1 G90 G00 X10. Y20. Z30.\nN2 G83 Z-5. R2. Q2. F100\n", o);
    CHECK(named(wide, "N2")[3]->end_mm[2] == Approx(1));   // R, feed, up, down to 1 mm above 0
    // Commanded time: feeds 2 + 2.5 + 2.5 + 1.5 mm at 100 mm/min; rapids 30 of N1, 28 down to R,
    // 2 + 4 + 6 up, 1.5 + 3.5 + 5.5 down, 35 out, at 30000 mm/min.
    const auto d = commanded_durations_s(g83, CommandedOptions{});
    double total = 0;
    for (double v : d) total += v;
    CHECK(total == Approx(8.5 / 100 * 60 + (30 + 28 + 12 + 10.5 + 35) / 30000.0 * 60));
}

TEST_CASE("dialects: G85 and G89 feed out, G86 rapids out with the spindle stopped", "[dialects][cycles]") {
    const NcProgram p = parse(
        "N1 G90 G00 X10. Y20. Z30. S1000 M03\n"
        "N2 G99 G85 Z-5. R2. F100\n"
        "N3 G98 G89 X20. P250\n"
        "N4 G86 X30.\n"
        "N5 G80 G00 X0\n");
    check_pieces(p, "N2", {10, 20, 30}, {{R, 10, 20, 2}, {L, 10, 20, -5}, {L, 10, 20, 2}}, 85);
    check_pieces(p, "N3", {10, 20, 2}, {{R, 20, 20, 2}, {L, 20, 20, -5}, {D, 20, 20, -5, 0.25}, {L, 20, 20, 2}, {R, 20, 20, 30}}, 89);
    // G86 after G98: positioning at the initial level 30, down to R, feed, rapid out to 30.
    check_pieces(p, "N4", {20, 20, 30}, {{R, 30, 20, 30}, {R, 30, 20, 2}, {L, 30, 20, -5}, {R, 30, 20, 30}}, 86);
    const auto n4 = named(p, "N4");
    CHECK(n4[2]->spindle_rpm == 1000);
    CHECK(n4[3]->spindle_rpm == 0);                            // out with the spindle stopped
    CHECK(named(p, "N5").front()->spindle_rpm == 1000);         // and it turns again after the hole
}

TEST_CASE("dialects: canned cycles in G91 and in inch, their errors", "[dialects][cycles]") {
    // G91: X/Y incremental, R from the initial level, Z from R (FANUC).
    const NcProgram inc = parse("N1 G90 G00 X10. Y20. Z30.\nN2 G91 G98 G81 X10. R-28. Z-7. F100\n");
    check_pieces(inc, "N2", {10, 20, 30}, {{R, 20, 20, 30}, {R, 20, 20, 2}, {L, 20, 20, -5}, {R, 20, 20, 30}}, 81);
    NcReadOptions o = options();
    o.program_units = ProgramUnits::Inch;
    const NcProgram inch = parse("N1 G90 G00 X1. Y1. Z1.\nN2 G99 G83 Z-0.2 R0.1 Q0.1 F10.\n", o);
    const auto pieces = named(inch, "N2");
    // R 2.54, Q 2.54, bottom -5.08 mm: R, feed to 0, up, down to 0.5, feed to -2.54, up, down to
    // -2.04, feed to -5.08, back to R.
    REQUIRE(pieces.size() == 9);
    CHECK(pieces[1]->end_mm[2] == Approx(0).margin(1e-12));
    CHECK(pieces[3]->end_mm[2] == Approx(0.5));
    CHECK(pieces.back()->end_mm[2] == Approx(2.54));
    CHECK(pieces[1]->feed_mm_min == Approx(254));

    const std::string start = "N1 G90 G00 X10. Y20. Z30.\n";
    CHECK_THAT(error_of(start + "N2 G81 X1. Z-5. F100\n"), Catch::StartsWith("t.nc:2: word 'G81': the canned cycle has no R level"));
    CHECK_THAT(error_of(start + "N2 G83 X1. Z-5. R2. F100\n"), Catch::StartsWith("t.nc:2: word 'G83': a peck cycle needs the peck depth Q"));
    CHECK_THAT(error_of(start + "N2 G81 X1. Z5. R2. F100\n"), Catch::StartsWith("t.nc:2: word 'X1.': the hole bottom Z lies at or above the R level"));
    CHECK_THAT(error_of(start + "N2 G18 G81 X1. Z-5. R2. F100\n"), Catch::StartsWith("t.nc:2: word 'G81': canned cycles are supported in the G17 plane only"));
    CHECK_THAT(error_of(start + "N2 G81 X1. Z-5. R2. K3 F100\n"), Catch::StartsWith("t.nc:2: word 'K3': repeat counts (K)"));
    CHECK_THAT(error_of(start + "N2 G84 X1. Z-5. R2. F100\n"), Catch::StartsWith("t.nc:2: word 'G84': this canned cycle is not supported"));
    CHECK_THAT(error_of(start + "N2 G01 X1. Q2. F100\n"), Catch::StartsWith("t.nc:2: word 'Q2.': Q is supported only in canned cycles"));
}

TEST_CASE("dialects: F words of a canned cycle are rewritten once, on its line", "[dialects][cycles]") {
    const std::string text = "N1 G90 G00 X10. Y20. Z30.\nN2 G98 G83 Z-5. R2. Q2. F100\nN3 X20.\nN4 G80\n";
    const NcProgram p = parse(text);
    std::vector<double> feeds(p.blocks.size(), 0.0);
    for (std::size_t i = 0; i < p.blocks.size(); ++i)
        if (p.blocks[i].motion == L) feeds[i] = p.blocks[i].name == "N2" ? 150 : 80;
    const std::string out = rewrite_feeds(p, feeds);
    CHECK(out == "N1 G90 G00 X10. Y20. Z30.\nN2 G98 G83 Z-5. R2. Q2. F150\nN3 X20. F80\nN4 G80\n");
    const NcProgram back = parse(out);
    for (const NcBlock& b : back.blocks)
        if (b.motion == L) CHECK(b.feed_mm_min == (b.name == "N2" ? 150 : 80));
}

TEST_CASE("dialects: G53 moves at the rapid rate to machine positions and leaves G01 in force", "[dialects]") {
    NcReadOptions o = options();
    o.work_offsets_mm["G54"] = {100, 200, -300};
    const NcProgram p = parse("N1 G90 G01 X0 Y0 Z10. F500\nN2 G53 Z0.\nN3 X5.\nN4 G53 X-20. Y-30.\n", o);
    CHECK(named(p, "N2").front()->motion == R);
    CHECK(named(p, "N2").front()->end_mm == std::array<double, 3>{100, 200, 0});
    CHECK(named(p, "N3").front()->motion == L);   // G01 is still in force
    CHECK(named(p, "N3").front()->end_mm == std::array<double, 3>{105, 200, 0});
    CHECK(named(p, "N4").front()->end_mm == std::array<double, 3>{-20, -30, 0});
    CHECK_THAT(error_of("N1 G91 G53 Z0.\n", o), Catch::StartsWith("t.nc:1: word 'G53': G53 takes absolute machine positions"));
    CHECK_THAT(error_of("N1 G90 G00 X0 Y0 Z0\nN2 G02 G53 X5. I1.\n", o), Catch::StartsWith("t.nc:2: word 'I1.': arc words in a G53 block"));
}

TEST_CASE("dialects: tape marks, program numbers and block skip", "[dialects]") {
    // What follows the closing '%' is not read (here: something no control would run).
    const NcProgram p = parse("%\nO1234 (NAME)\n:1235\nN1 G00 X1. Y0 Z0\n%\nN2 G41 ###\n");
    REQUIRE(p.blocks.size() == 3);
    CHECK(p.blocks.back().name == "N1");
    // '/' (or '/1'.. '/9') at the head of a block, also after its N number: skipped only when
    // the block skip switch is on.
    const std::string skip = "N1 G00 X1. Y0 Z0\n/N2 X2.\nN3 /2 X3. Y1.\nN4 Y2.\n";
    const NcProgram off = parse(skip);
    CHECK(named(off, "N2").front()->end_mm[0] == 2);
    CHECK(named(off, "N3").front()->end_mm[0] == 3);
    NcReadOptions o = options();
    o.block_skip = true;
    const NcProgram on = parse(skip, o);
    CHECK(named(on, "N2").empty());
    CHECK(named(on, "N3").empty());
    CHECK(named(on, "N4").front()->end_mm == std::array<double, 3>{1, 2, 0});
    CHECK_THAT(error_of("N1 G00 X1. / Y2.\n"), Catch::StartsWith("t.nc:1: word '/': unexpected character"));
}

TEST_CASE("dialects: comments and bytes that are not UTF-8 never fail a program", "[dialects]") {
    // "(Fräsen)" and "(Größe °C)" in cp1252/Latin-1 and in UTF-8, a UTF-8 byte order mark, and
    // no-break spaces between words (A0 in Latin-1, C2 A0 in UTF-8).
    const std::string text =
        "\xEF\xBB\xBF%\nO0100 (Fr\xE4sen)\nN1 G00 X1. Y2. Z3. (Gr\xF6\xDF" "e \xB0" "C)\n"
        "N2 G01 X5.\xA0Y6. F100 ; Werkst\xFC" "ck\nN3 X7.\xC2\xA0Y8. (Gr\xC3\xB6\xC3\x9F" "e)\n%\n";
    const NcProgram p = parse(text);
    REQUIRE(p.blocks.size() == 4);
    CHECK(named(p, "N2").front()->end_mm == std::array<double, 3>{5, 6, 3});
    CHECK(named(p, "N3").front()->end_mm == std::array<double, 3>{7, 8, 3});
    // A stray byte outside a comment is an error whose message stays ASCII (valid in JSON).
    const std::string e = error_of("N1 G00 X1. \xE4 Y2.\n");
    CHECK(e == "t.nc:1: word '\\xE4': a byte outside a comment that is not part of an NC word");
    CHECK_THAT(error_of("N1 G00 X1. (Fr\xE4sen\n"), Catch::StartsWith("t.nc:1: word '(Fr\\xE4sen': comment without ')'"));
    // Written back with new feeds, the comment's bytes stay as they were.
    std::vector<double> feeds(p.blocks.size(), 0.0);
    feeds[2] = 200;
    const std::string out = rewrite_feeds(p, feeds);
    CHECK(out.find("(Fr\xE4sen)") != std::string::npos);
    CHECK(out.find("N2 G01 X5.\xA0Y6. F200 ; Werkst\xFC" "ck") != std::string::npos);
}

TEST_CASE("dialects: T with M06 selects the tool, blocks and the commanded motion carry it", "[dialects][tools]") {
    const std::string text =
        "N1 G90 G00 X0 Y0 Z50.\nN2 T5\nN3 M06\nN4 G01 X10. F600\nN5 T7 M6\nN6 X20.\nN7 T8\nN8 X30.\nN9 M30\n";
    const NcProgram p = parse(text);
    const std::vector<std::pair<std::string, int>> want{{"N1", -1}, {"N2", -1}, {"N3", 5}, {"N4", 5}, {"N5", 7},
                                                        {"N6", 7},  {"N7", 7},  {"N8", 7}, {"N9", 7}};
    for (const auto& [name, tool] : want) {
        INFO(name);
        CHECK(named(p, name).front()->tool == tool);
        CHECK(named(p, name).front()->tool_change == (name == "N3" || name == "N5"));
    }
    CHECK(program_tools(p) == std::vector<int>{5, 7});   // T8 was selected, never changed to
    // With a control that changes on T: T8 is a change, M06 has nothing left to do.
    NcReadOptions o = options();
    o.tool_change_on_t = true;
    const NcProgram on_t = parse(text, o);
    CHECK(named(on_t, "N2").front()->tool == 5);
    CHECK(named(on_t, "N3").front()->tool_change == false);
    CHECK(named(on_t, "N8").front()->tool == 8);
    CHECK_THAT(error_of("N1 G00 X0 Y0 Z0\nN2 M06\n"), Catch::StartsWith("t.nc:2: word 'M06': tool change without a tool selected"));
    CHECK_THAT(error_of("N1 T1.5 M06\n"), Catch::StartsWith("t.nc:1: word 'T1.5': a tool number is a whole number"));

    // The commanded motion: one tool number per sample, like the block index.
    CommandedOptions co;
    co.step_s = 0.01;
    const MotionModel m = commanded_motion(p, co);
    REQUIRE(m.tool.size() == m.size());
    std::size_t checked = 0;
    for (std::size_t i = 0; i < m.size(); ++i) {
        const std::string& block = m.block_names[static_cast<std::size_t>(m.block[i])];
        const int tool = block == "N4" ? 5 : block == "N6" || block == "N8" ? 7 : -2;
        if (tool == -2) continue;
        CHECK(m.tool[i] == tool);
        ++checked;
    }
    CHECK(checked > 200);   // 10 mm at 600 mm/min per block: 1 s, 100 samples each
}
