// The five-axis demo (data/demo3_*): a ring groove on the AC table-table machine cut by turning the
// C table under a standing tool. The bundled program and log are the generator's (regenerate with
//   CUTLOAD_UPDATE_DEMO3=1 build/tests/test_app "[demo3]"), and the log's axes through the machine
// give the tool's motion against the part that the program asks for: the tip on the R35 and R38
// circles about the C line, at the G93 block's 3000 mm/min and the G94 combined block's
// 3600 deg/min x R38 = 2387.6 mm/min.
#include "app/predict_run.hpp"
#include "app/workpiece_motion.hpp"
#include "motion_io/synth.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>

using namespace cutload;

namespace {

std::string source(const std::string& rel) { return std::string(CUTLOAD_SOURCE_DIR) + "/" + rel; }

std::string read_text(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

// The C line of data/machines/ac_table_table.json, and the stock top (G54) on it.
constexpr double kCx = -350, kCy = -275, kTopZ = -460;

}  // namespace

TEST_CASE("demo3: the bundled program and log are the generator's", "[demo3]") {
    const std::string program = motion_io::demo3_program_text();
    std::ostringstream csv;
    const std::size_t rows = motion_io::synthesize_nc_dry_run(motion_io::demo3_dry_run_spec(), csv);
    if (const char* u = std::getenv("CUTLOAD_UPDATE_DEMO3"); u && std::string(u) == "1") {
        std::ofstream(source("data/demo3_program.nc"), std::ios::binary) << program;
        std::ofstream(source("data/demo3_dryrun.csv"), std::ios::binary) << csv.str();
    }
    CHECK(read_text(source("data/demo3_program.nc")) == program);
    CHECK(read_text(source("data/demo3_dryrun.csv")) == csv.str());
    CHECK(rows > 1000);
}

TEST_CASE("demo3: the log through the AC machine turns the tool along the programmed arcs at the programmed feeds",
          "[demo3][five_axis]") {
    motion_io::IngestReport report;
    const motion_io::MotionModel axes = motion_io::ingest(source("data/demo3_dryrun.csv"), motion_io::ReadOptions{}, &report);
    CHECK(report.rotary_axes == "ac");
    const auto machine = app::load_machine_definition(source("data/machines/ac_table_table.json"));
    const motion_io::MotionModel w = app::workpiece_motion(axes, *machine, 0);

    // Per block: the tip's radius from the C line and its speed against the part, over the
    // block's middle half (away from the acceleration at its ends).
    struct Seen {
        double r_min = 1e9, r_max = 0, feed_min = 1e9, feed_max = 0;
        double t_first = -1, t_last = -1;
    };
    auto block_stats = [&](const std::string& name) {
        Seen s;
        std::int32_t id = -1;
        for (std::size_t k = 0; k < w.block_names.size(); ++k)
            if (w.block_names[k] == name) id = std::int32_t(k);
        REQUIRE(id >= 0);
        for (std::size_t i = 0; i < w.size(); ++i)
            if (w.block[i] == id) {
                if (s.t_first < 0) s.t_first = w.t_s[i];
                s.t_last = w.t_s[i];
            }
        const double span = s.t_last - s.t_first;
        for (std::size_t i = 0; i < w.size(); ++i) {
            if (w.block[i] != id || w.t_s[i] < s.t_first + 0.25 * span || w.t_s[i] > s.t_last - 0.25 * span) continue;
            const double r = std::hypot(w.x_mm[i] - kCx, w.y_mm[i] - kCy);
            const double feed = std::hypot(w.vx_mm_s[i], w.vy_mm_s[i], w.vz_mm_s[i]) * 60;
            s.r_min = std::min(s.r_min, r), s.r_max = std::max(s.r_max, r);
            s.feed_min = std::min(s.feed_min, feed), s.feed_max = std::max(s.feed_max, feed);
            CHECK(w.z_mm[i] == Approx(kTopZ - 2).margin(0.002));   // 2 mm deep throughout
        }
        return s;
    };
    // N50 G93 C360. F13.642: one turn in 60/13.642 s, 2 pi 35 mm at 3000.03 mm/min.
    const Seen n50 = block_stats("N50");
    CHECK(n50.r_min > 35 - 0.01);
    CHECK(n50.r_max < 35 + 0.01);
    const double n50_mm_min = 2 * std::numbers::pi * 35 * 13.642;
    CHECK(n50.feed_min > 0.99 * n50_mm_min);
    CHECK(n50.feed_max < 1.01 * n50_mm_min);
    CHECK(n50.t_last - n50.t_first == Approx(60 / 13.642).epsilon(0.02));
    // N70 G94 C0. F3600 (combined: 3600 deg/min), at R38: 2387.6 mm/min.
    const Seen n70 = block_stats("N70");
    CHECK(n70.r_min > 38 - 0.01);
    CHECK(n70.r_max < 38 + 0.01);
    const double n70_mm_min = 3600 * std::numbers::pi / 180 * 38;
    CHECK(n70.feed_min > 0.99 * n70_mm_min);
    CHECK(n70.feed_max < 1.01 * n70_mm_min);
}

TEST_CASE("demo3: the program through the AC machine is the tip's path against the part, timed as the machine runs it",
          "[demo3][five_axis]") {
    const auto machine = app::load_machine_definition(source("data/machines/ac_table_table.json"));
    CHECK(app::machine_rotary_axes(*machine) == "AC");
    const motion_io::NcProgram axes = motion_io::parse_nc_program(motion_io::demo3_program_text(), "demo3.nc", motion_io::demo3_read_options());
    const motion_io::NcProgram w = app::workpiece_program(axes, *machine, 0, 30000);
    CHECK(w.rotary_axes.empty());
    std::size_t n50_pieces = 0;
    double n50_s = 0, n70_s = 0, worst_sagitta_mm = 0;
    for (const motion_io::NcBlock& b : w.blocks) {
        CHECK(b.start_deg == std::array<double, 3>{});
        if (b.name != "N50" && b.name != "N70") continue;
        const double r = b.name == "N50" ? 35 : 38;
        const double speed = b.name == "N50" ? 2 * std::numbers::pi * 35 * 13.642 : 3600 * std::numbers::pi / 180 * 38;
        // Piece ends on the circle about the C line, 2 mm deep; the chord's middle within 1 um of it.
        CHECK(std::hypot(b.end_mm[0] - kCx, b.end_mm[1] - kCy) == Approx(r).margin(1e-6));
        CHECK(b.end_mm[2] == Approx(kTopZ - 2).margin(1e-9));
        const double mid_r = std::hypot(0.5 * (b.start_mm[0] + b.end_mm[0]) - kCx, 0.5 * (b.start_mm[1] + b.end_mm[1]) - kCy);
        worst_sagitta_mm = std::max(worst_sagitta_mm, r - mid_r);
        CHECK(b.feed_mm_min == Approx(speed).epsilon(1e-4));
        (b.name == "N50" ? n50_s : n70_s) += motion_io::block_time_s(b, 30000);
        n50_pieces += b.name == "N50";
    }
    CHECK(worst_sagitta_mm <= app::kProgramChordTolMm);
    CHECK(worst_sagitta_mm > 0.25 * app::kProgramChordTolMm);   // not needlessly fine
    CHECK(n50_pieces > 100);
    CHECK(n50_s == Approx(60 / 13.642).epsilon(1e-12));
    CHECK(n70_s == Approx(6.0).epsilon(1e-12));

    // A program that tilts the tool is refused naming its block.
    motion_io::NcReadOptions ro = motion_io::demo3_read_options();
    const motion_io::NcProgram tilted = motion_io::parse_nc_program("N10 G00 X35. Y0 Z5. A0 C0\nN20 G01 A-20. F1000\n", "tilt.nc", ro);
    try {
        app::workpiece_program(tilted, *machine, 0, 30000);
        FAIL("a tilted tool was not refused");
    } catch (const motion_io::NcProgramError& e) {
        CHECK_THAT(std::string(e.what()), Catch::StartsWith("tilt.nc:2: block N20: the tool axis leans"));
    }
}

TEST_CASE("demo3: a rotary move that needs more pieces than allowed is refused as the pieces are made, naming line and "
          "block",
          "[demo3][five_axis]") {
    const auto machine = app::load_machine_definition(source("data/machines/ac_table_table.json"));
    const motion_io::NcReadOptions ro = motion_io::demo3_read_options();
    auto refusal = [&](const std::string& text, const app::PieceLimits& limits) -> std::string {
        const motion_io::NcProgram p = motion_io::parse_nc_program(text, "many.nc", ro);
        try {
            app::workpiece_program(p, *machine, 0, 30000, limits);
        } catch (const motion_io::NcProgramError& e) {
            return e.what();
        }
        return "(not refused)";
    };
    // 2000 turns of the C table at R35 (the reader's own bound is 1e6 deg): 512 pieces of 1 um a
    // turn, about a million in all. The limit of 65536 is passed 128 turns in, 6.4 % into the
    // block, and the refusal comes there rather than after every piece has been made.
    const std::string m = refusal("N1 G00 X35. Y0 Z5. A0 C0\nN2 G93 G01 C720000. F0.5\n", {});
    INFO(m);
    REQUIRE_THAT(m, Catch::StartsWith("many.nc:2: block N2: its tip path needs more than 65536 pieces of 1 um, passed "));
    const double percent = std::stod(m.substr(m.find("passed ") + 7));
    CHECK(percent > 5);
    CHECK(percent < 8);

    // A block whose quarter turns alone pass the limit is refused before any pose is computed.
    app::PieceLimits small;
    small.per_block = 1000;
    CHECK_THAT(refusal("N1 G00 X35. Y0 Z5. A0 C0\nN2 G93 G01 C360000. F1.\n", small),
               Catch::Equals("many.nc:2: block N2: its tip path needs more than 1000 pieces of 1 um (turn the rotary axes "
                             "less in one block)"));

    // The program's total: three turns of 512 pieces after the rapid's one pass 1500 in the third
    // (N4), with its 476th piece: 476 / 512 = 93 % into it.
    app::PieceLimits total;
    total.total = 1500;
    const std::string t = refusal("N1 G00 X35. Y0 Z5. A0 C0\nN2 G93 G01 C360. F10.\nN3 C720. F10.\nN4 C1080. F10.\n", total);
    INFO(t);
    CHECK_THAT(t, Catch::Equals("many.nc:4: block N4: the program's tip path needs more than 1500 pieces of 1 um in all, "
                                    "passed 93 % into the block (split the program)"));
    total.total = 1537;   // exactly enough
    CHECK(refusal("N1 G00 X35. Y0 Z5. A0 C0\nN2 G93 G01 C360. F10.\nN3 C720. F10.\nN4 C1080. F10.\n", total) ==
          "(not refused)");
}
