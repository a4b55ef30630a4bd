// Issue 19: one NC typo must not run away. Each reproducer below is one edit of the demo program
// (data/demo_program.nc). On main before this change each was read without complaint, and the
// commanded motion it implied was 2e12 samples at 1 ms (X99999999999.), 2.5e11 (F0.0001) and
// 1e11 (the 1e8 s dwell), so each of these tests failed there; now the value is refused while
// reading, naming file, line and word. A program whose values are each physical but whose
// work is not (a path of thousands of km) is refused at the block that passes the bound.
#include "nc_fixtures.hpp"

#include "motion_io/commanded.hpp"

#include <catch2/catch.hpp>

using namespace cutload;
using namespace cutload::nctest;

namespace {

motion_io::NcReadOptions demo_options() {
    const motion_io::DryRunSpec spec = motion_io::demo_dry_run_spec();
    return read_options_for(spec, {200, -300, -350});
}

// The demo program with line `line_no` (1-based) replaced.
std::string demo_with_line(std::size_t line_no, const std::string& replacement) {
    std::istringstream in(read_text(source_path("data/demo_program.nc")));
    std::string out, line;
    for (std::size_t n = 1; std::getline(in, line); ++n) out += (n == line_no ? replacement : line) + "\n";
    return out;
}

std::string error_of(const std::string& text, const motion_io::NcReadOptions& o) {
    try {
        motion_io::parse_nc_program(text, "demo_program.nc", o);
    } catch (const motion_io::NcProgramError& e) {
        return e.what();
    }
    return "(no error)";
}

}  // namespace

TEST_CASE("bounds: the demo with N40 X99999999999. is refused on its line and word", "[bounds]") {
    REQUIRE(demo_with_line(7, "N40 X64.5 F6000") == read_text(source_path("data/demo_program.nc")));   // line 7 is N40
    CHECK_THAT(error_of(demo_with_line(7, "N40 X99999999999. F6000"), demo_options()),
               Catch::StartsWith("demo_program.nc:7: word 'X99999999999.': 1e+11 mm is outside the physical range +-100000 mm"));
}

TEST_CASE("bounds: the demo with F0.0001 is refused on its line and word", "[bounds]") {
    CHECK_THAT(error_of(demo_with_line(7, "N40 X64.5 F0.0001"), demo_options()),
               Catch::StartsWith("demo_program.nc:7: word 'F0.0001': feed 0.0001 mm/min is outside the physical range 0.1..200000 mm/min"));
}

TEST_CASE("bounds: the demo with G04 X100000000. is refused on its line and word", "[bounds]") {
    CHECK_THAT(error_of(demo_with_line(7, "G04 X100000000."), demo_options()),
               Catch::StartsWith("demo_program.nc:7: word 'X100000000.': dwell 1e+08 s is above the longest, 99999.999 s"));
}

TEST_CASE("bounds: a rapid feed of 1e-9 mm/min is refused before anything is read", "[bounds]") {
    motion_io::NcReadOptions o = demo_options();
    o.rapid_mm_min = 1e-9;
    CHECK_THAT(error_of(read_text(source_path("data/demo_program.nc")), o),
               Catch::StartsWith("demo_program.nc: rapid feed: 1e-09 mm/min is outside the physical range 100..200000 mm/min"));
}

TEST_CASE("bounds: the work a program implies is bounded while reading and before sampling", "[bounds]") {
    // Every value is physical, but 2000 strokes of 99.999 m make 200 km of path: refused at the
    // block that passes 10 km (the 101st stroke), without reading on.
    std::string text = "N1 G90 G00 X0 Y0 Z0\nG01 F200000\n";
    for (int k = 0; k < 2000; ++k) text += k % 2 ? "X0\n" : "X99999.\n";
    motion_io::NcReadOptions o;
    o.work_offsets_mm["G54"] = {0, 0, 0};
    o.start_mm = std::array<double, 3>{0, 0, 0};
    CHECK_THAT(error_of(text, o), Catch::StartsWith("demo_program.nc:103: word 'X99999.': the programmed path reaches 1.01e+07 mm here, above the limit of 1e+07 mm"));
    // A slow feed over a short path: 100 mm at 0.1 mm/min is 60000 s, 6e7 samples at 1 ms.
    CHECK_THAT(error_of("N1 G90 G00 X0 Y0 Z0\nN2 G01 X100. F0.1\n", o),
               Catch::StartsWith("demo_program.nc:2: word 'X100.': the commanded motion up to here takes 6e+07 samples at 1 ms, above the limit of 1e+07"));
    // The limits are options.
    o.limits.max_samples = 1e8;
    CHECK_THAT(error_of("N1 G90 G00 X0 Y0 Z0\nN2 G01 X100. F0.1\nN3 X200.\n", o),
               Catch::StartsWith("demo_program.nc:3: word 'X200.': the program runs 1.2e+05 s up to here at its feeds, above the limit of 8.64e+04 s"));

    // The commanded motion estimates its size before building anything: a program read with
    // generous limits still cannot make it build more than it is allowed to.
    o.limits.max_duration_s = 1e6;
    const motion_io::NcProgram slow = motion_io::parse_nc_program("N1 G90 G00 X0 Y0 Z0\nN2 G01 X100. F0.1\n", "slow.nc", o);
    motion_io::CommandedOptions co;
    co.step_s = 0.001;
    CHECK(motion_io::commanded_sample_count(slow, co) == Approx(6e7).epsilon(1e-6));
    CHECK_THROWS_WITH(motion_io::commanded_motion(slow, co),
                      Catch::StartsWith("slow.nc: the commanded motion would take 6e+07 samples at 1 ms, above the limit of 1e+07"));
}

TEST_CASE("bounds: a log step far finer than the reader assumed is caught before the commanded motion is built", "[bounds]") {
    // 90 mm at 100 mm/min is 54 s: 54000 samples at 1 ms, 5.4 million at 0.01 ms. With a limit
    // of 1 million the reader (at its 1 ms) lets it pass; the program run, at the log's step, does not.
    motion_io::DryRunSpec spec;
    spec.start_mm[2] = 0;
    motion_io::ProgramBlock b;
    b.name = "N1";
    b.target_mm[0] = 10;
    b.feed_mm_min = 6000;
    spec.program.push_back(b);
    motion_io::MotionModel log = dry_run_motion(spec, "bounds_fine", 0.01);
    app::ProgramSettings settings;
    settings.work_offsets_mm["G54"] = {0, 0, 0};
    settings.limits.max_samples = 1e6;
    force_model::RunSpec run;
    motion_io::NcReadOptions ro = app::program_read_options(settings, run, app::log_start_mm(log));
    motion_io::NcProgram program = motion_io::parse_nc_program("N1 G90 G01 X10. Y0 Z0 F6000\nN2 X100. F100\n", "fine.nc", ro);
    CHECK_THROWS_WITH(app::prepare_program_run(std::move(program), settings, log),
                      Catch::StartsWith("fine.nc: the commanded motion would take 5.41e+06 samples at the log's 0.01 ms step, above the limit of 1e+06"));
}
