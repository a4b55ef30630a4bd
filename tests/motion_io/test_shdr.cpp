// MTConnect SHDR: the real Okuma MULTUS log and small synthetic streams.
#include "test_helpers.hpp"

#include <catch2/catch.hpp>
#include <fmt/format.h>

#include <algorithm>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;

namespace {

const std::string kOkuma = "data/real/okuma_multus_shdr/okuma.txt";

}  // namespace

TEST_CASE("Okuma SHDR: four restart sessions split, feed unit quirk flagged without the option", "[shdr][shared]") {
    ReadOptions opt;
    opt.step_ms = 50;
    IngestReport report;
    const MotionModel m = ingest(shared_path(kOkuma), opt, &report);
    CHECK(report.format == "shdr");
    CHECK(report.sessions == 4);
    // The last recording (13:57:41-13:58:06) holds only the restart dump: no motion to resample.
    CHECK(warning_count(report, "session_too_short") == 1);
    REQUIRE(m.session_start.size() == 3);
    CHECK(warning_count(report, "session_backwards") == 2);   // 13:51 -> 13:37 and 14:30 -> 13:57
    CHECK(warning_count(report, "session_gap") == 1);         // 13:47 -> 14:21
    // p1Fact is sent in mm/min although MTConnect declares mm/s: loud, but no silent rescaling.
    CHECK(warning_count(report, "feed_unit_suspect") == 1);
    CHECK(warning_count(report, "out_of_range") > 0);
    CHECK(report.channels.at("pos").samples > 3000);
    CHECK(report.blocks > 100);
}

TEST_CASE("Okuma SHDR: --feed-units mm/min resolves the quirk explicitly", "[shdr][shared]") {
    ReadOptions opt;
    opt.step_ms = 50;
    opt.feed_unit = "mm/min";
    const IngestReport report = inspect(shared_path(kOkuma), opt);
    CHECK(report.sessions == 4);
    CHECK(warning_count(report, "feed_unit_suspect") == 0);
    CHECK(warning_count(report, "out_of_range") == 0);
}

TEST_CASE("SHDR: conditions, assets, agent commands and UNAVAILABLE are skipped and axes merge", "[shdr]") {
    const std::string log =
        "* adapterVersion: 2.0\n"
        "2024-01-01T00:00:00.000Z|X1actw|0|Y1actw|0|Z1actw|10|S1speed|1000|line|N1\n"
        "2024-01-01T00:00:00.000Z|system|NORMAL||||\n"
        "2024-01-01T00:00:00.500Z|@ASSET@|T1|CuttingTool|--multiline--AB\n"
        "<CuttingTool>|X1actw|999</CuttingTool>\n"
        "--multiline--AB\n"
        "2024-01-01T00:00:01.000Z|X1actw|10|S1speed|UNAVAILABLE\n"
        "2024-01-01T00:00:02.000Z|X1actw|20|line|N2\n"
        "2024-01-01T00:00:03.000Z|X1actw|30|Y1actw|5\n";
    TempFile f("small.shdr", log);
    ReadOptions opt;
    opt.step_ms = 100;
    IngestReport report;
    const MotionModel m = ingest(f.path(), opt, &report);
    CHECK(report.sessions == 1);
    CHECK(report.channels.at("pos").samples == 4);
    CHECK(warning_count(report, "unavailable") == 1);
    REQUIRE(m.size() == 31);
    CHECK(m.x_mm.back() == Approx(30));
    CHECK(m.y_mm.back() == Approx(5));
    CHECK(m.z_mm.back() == Approx(10));
    CHECK(m.spindle_rpm.back() == Approx(1000));
    CHECK(m.block_names[static_cast<std::size_t>(m.block.back())] == "N2");
}

TEST_CASE("SHDR: a JSON map file picks the keys and declares units", "[shdr]") {
    const std::string log =
        "2024-01-01T00:00:00Z|pos|0 0 0|rpm|100|feedrate|60\n"
        "2024-01-01T00:00:01Z|pos|1 0 0\n"
        "2024-01-01T00:00:02Z|pos|2 0 0\n"
        "2024-01-01T00:00:03Z|pos|3 0 0\n";
    TempFile f("mapped.shdr", log);
    TempFile map("map.json", R"({"position": ["pos"], "spindle": "rpm", "feed": ["feedrate"],
                                 "units": {"length": "in", "feed": "in/min"}})");
    ReadOptions opt;
    opt.map_file = map.path();
    opt.step_ms = 500;
    const MotionModel m = ingest(f.path(), opt);
    REQUIRE(m.size() == 7);
    CHECK(m.x_mm.back() == Approx(3 * 25.4));
    CHECK(m.spindle_rpm.front() == Approx(100));
}

TEST_CASE("SHDR: a linear axis that stops between sparse reports does not run past them", "[shdr][slope_limit]") {
    // An event-driven log: X stands at 0, is next reported at 10 mm (a rapid between the reports
    // 0.3 s apart) and stands there; Z moves on at 1 mm/s, read with X's reports.
    const std::string start = "2024-01-01T00:00:";
    std::string log = start + "00.000Z|X1actw|0|Y1actw|0|Z1actw|0|S1speed|1000\n";
    for (int k = 1; k <= 20; ++k)
        log += fmt::format("{}{:06.3f}Z|Z1actw|{:.3f}{}\n", start, 0.3 * k, 0.3 * k, k == 10 ? "|X1actw|10" : "");
    TempFile f("sparse_x.shdr", log);
    ReadOptions opt;
    opt.step_ms = 10;
    const MotionModel m = ingest(f.path(), opt);
    REQUIRE(m.size() > 500);
    const auto [lo, hi] = std::minmax_element(m.x_mm.begin(), m.x_mm.end());
    CHECK(*lo >= -0.005);
    CHECK(*hi <= 10.005);
    CHECK(m.x_mm.back() == Approx(10).margin(1e-9));
    for (std::size_t i = 0; i < m.size(); ++i) REQUIRE(m.vz_mm_s[i] == Approx(1).margin(1e-6));
}
