// CSV reading: column order and case, units, per-channel time stamps.
#include "test_helpers.hpp"

#include <catch2/catch.hpp>
#include <fmt/format.h>

#include <algorithm>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;

namespace {

// A straight move at 600 mm/min along X, sampled every 10 ms, written with the given columns.
std::string line_log(const std::string& header, double t_scale, double len_scale, int rows = 101) {
    std::string s = header + "\n";
    for (int i = 0; i < rows; ++i) {
        const double t = i * 0.01, x = 10.0 + 10.0 * t;   // 10 mm/s
        s += std::to_string(t * t_scale) + "," + std::to_string(x * len_scale) + "," + std::to_string(2 * len_scale) + "," +
             std::to_string(-5 * len_scale) + "\n";
    }
    return s;
}

}  // namespace

TEST_CASE("CSV: columns in any order and any case, defaults s and mm", "[csv]") {
    // Reordered: z, t, y, x.
    std::string s = "Z,T,Y,x\n";
    for (int i = 0; i < 51; ++i) s += "-5," + std::to_string(i * 0.01) + ",2," + std::to_string(10 + 0.1 * i) + "\n";
    TempFile f("order.csv", s);
    ReadOptions opt;
    opt.step_ms = 5;
    const MotionModel m = ingest(f.path(), opt);
    REQUIRE(m.size() == 101);
    CHECK(m.x_mm.back() == Approx(15.0));
    CHECK(m.y_mm.back() == Approx(2.0));
    CHECK(m.z_mm.back() == Approx(-5.0));
    CHECK(m.vx_mm_s[50] == Approx(10.0));
}

TEST_CASE("CSV: units in brackets (ms, in, in/min) are converted", "[csv]") {
    std::string s = "t [ms],x [in],y [in],z [in],feed [in/min],spindle [rev/s]\n";
    for (int i = 0; i < 51; ++i)
        s += std::to_string(i * 10.0) + "," + std::to_string(1.0 + 0.01 * i) + ",0,0,60,100\n";   // 1 in/s
    TempFile f("units.csv", s);
    ReadOptions opt;
    opt.step_ms = 10;
    IngestReport report;
    const MotionModel m = ingest(f.path(), opt, &report);
    REQUIRE(m.size() == 51);
    CHECK(m.t_s.back() - m.t_s.front() == Approx(0.5));
    CHECK(m.x_mm.front() == Approx(25.4));
    CHECK(m.vx_mm_s[25] == Approx(25.4));
    CHECK(m.spindle_rpm[10] == Approx(6000));
    // 60 in/min = 25.4 mm/s matches the positions: no unit warning.
    for (const auto& w : report.warnings) CHECK(w.code != "feed_unit_suspect");
}

TEST_CASE("CSV: a three-axis feed column in the wrong unit is flagged, naming the unit to give", "[csv][feed]") {
    // X at 10 mm/s = 600 mm/min = 23.62 in/min for 2 s.
    auto log = [](const std::string& feed_header, double feed) {
        std::string s = "t,x,y,z," + feed_header + "\n";
        for (int i = 0; i <= 200; ++i) s += fmt::format("{:.3f},{:.3f},2.000,-5.000,{:.2f}\n", 0.01 * i, 10.0 + 0.1 * i, feed);
        return s;
    };
    struct Case {
        std::string header;
        double feed;
        const char* hint;
    };
    for (const Case& c : {Case{"feed [mm/min]", 600 / 25.4, "--feed-units in/min"},   // in/min read as mm/min
                          Case{"feed [in/min]", 600, "--feed-units mm/min"},          // mm/min read as in/min
                          Case{"feed [mm/s]", 600, "--feed-units mm/min"}}) {         // mm/min read as mm/s
        INFO(c.header << " holding " << c.feed);
        TempFile f("feed_unit.csv", log(c.header, c.feed));
        const IngestReport report = inspect(f.path(), ReadOptions{});
        REQUIRE(warning_count(report, "feed_unit_suspect") == 1);
        const auto w = std::find_if(report.warnings.begin(), report.warnings.end(),
                                    [](const IngestWarning& x) { return x.code == "feed_unit_suspect"; });
        CHECK_THAT(w->message, Catch::Contains(c.hint));
    }
    TempFile right("feed_unit_right.csv", log("feed [mm/min]", 600));
    CHECK(warning_count(inspect(right.path(), ReadOptions{}), "feed_unit_suspect") == 0);
}

TEST_CASE("CSV: --units fills in an undeclared length unit and conflicts with a declared one", "[csv]") {
    TempFile plain("units_plain.csv", line_log("t,x,y,z", 1, 1 / 25.4));
    ReadOptions opt;
    opt.step_ms = 10;
    opt.length_unit = "in";
    const MotionModel m = ingest(plain.path(), opt);
    CHECK(m.x_mm.front() == Approx(10.0));

    TempFile declared("units_declared.csv", line_log("t,x [mm],y [mm],z [mm]", 1, 1));
    CHECK_THROWS_WITH(ingest(declared.path(), opt), Catch::Contains("x [mm]") && Catch::Contains("--units in"));
}

TEST_CASE("CSV: per-channel time stamps replace t for their channel", "[csv]") {
    // Spindle ramps 0 -> 1000 rpm; its own stamps lag t_pos by 4 ms.
    std::string s = "t_spindle,spindle,t_pos,x,y,z,block\n";
    for (int i = 0; i < 101; ++i) {
        const double tp = 0.01 * i;
        s += std::to_string(tp - 0.004) + "," + std::to_string(1000.0 * tp) + "," + std::to_string(tp) + "," +
             std::to_string(10 * tp) + ",0,0," + (i < 50 ? "N10" : "N20") + "\n";
    }
    TempFile f("perchannel.csv", s);
    ReadOptions opt;
    opt.step_ms = 10;
    IngestReport report;
    const MotionModel m = ingest(f.path(), opt, &report);
    REQUIRE(m.size() > 90);
    // At t_pos = 0.5 s the spindle, stamped at its own time, reads 1000 * (0.5 + 0.004).
    std::size_t i = 50;
    REQUIRE(m.t_s[i] == Approx(0.5));
    CHECK(m.spindle_rpm[i] == Approx(504.0).margin(0.5));
    CHECK(m.block_names[static_cast<std::size_t>(m.block[i])] == "N20");
    CHECK(m.block_names[static_cast<std::size_t>(m.block[10])] == "N10");
    CHECK(report.blocks == 2);
    CHECK(report.channels.at("spindle").samples == 101);
    CHECK(report.channels.at("pos").interval.median_s == Approx(0.01).epsilon(0.01));
}

TEST_CASE("CSV: a backward time jump beyond 1 s starts a new session, small ones are reordered", "[csv]") {
    std::string s = "t,x,y,z\n";
    for (int i = 0; i < 50; ++i) s += std::to_string(10 + 0.01 * i) + "," + std::to_string(0.1 * i) + ",0,0\n";
    // Two rows swapped (a 10 ms backward step), then a restart at t = 0.
    s += "10.51,5.1,0,0\n10.50,5.0,0,0\n";
    for (int i = 0; i < 50; ++i) s += std::to_string(0.01 * i) + "," + std::to_string(50 + 0.1 * i) + ",0,0\n";
    TempFile f("sessions.csv", s);
    ReadOptions opt;
    opt.step_ms = 10;
    IngestReport report;
    const MotionModel m = ingest(f.path(), opt, &report);
    CHECK(report.sessions == 2);
    REQUIRE(m.session_start.size() == 2);
    CHECK(m.t_s[m.session_start[1]] == Approx(0.0));
    auto count = [&](const std::string& code) {
        for (const auto& w : report.warnings)
            if (w.code == code) return w.count;
        return std::size_t{0};
    };
    CHECK(count("time_backwards") == 1);
    CHECK(count("session_backwards") == 1);
    // The swapped pair was put back in order: constant 10 mm/s throughout the first session.
    for (std::size_t i = 1; i + 1 < m.session_start[1]; ++i) REQUIRE(m.vx_mm_s[i] == Approx(10.0).epsilon(1e-6));
}

TEST_CASE("CSV: a tool column gives each sample the tool in the spindle", "[csv]") {
    // 1 s at 10 mm/s; the tool cell is empty until 0.2 s (not read), T7 until 0.5 s, then T12.
    std::string s = "t,x,y,z,tool\n";
    for (int i = 0; i <= 100; ++i) {
        const double t = i * 0.01;
        s += std::to_string(t) + "," + std::to_string(10 * t) + ",0,0," + (t < 0.195 ? "" : t < 0.495 ? "7" : "12") + "\n";
    }
    TempFile f("tool.csv", s);
    ReadOptions opt;
    opt.step_ms = 10;
    IngestReport report;
    const MotionModel m = ingest(f.path(), opt, &report);
    REQUIRE(m.tool.size() == m.size());
    CHECK(report.channels.count("tool") == 1);
    for (const auto& w : report.warnings) CHECK(w.code != "unknown_column");   // a known channel now
    for (std::size_t i = 0; i < m.size(); ++i) {
        INFO("t = " << m.t_s[i]);
        // Before the first reading the first tool read was already in the spindle (as for blocks).
        CHECK(m.tool[i] == (m.t_s[i] < 0.495 ? 7 : 12));
    }
    // Without a tool column the model has none (not a column of -1).
    TempFile plain("notool.csv", line_log("t,x,y,z", 1, 1));
    CHECK(ingest(plain.path(), opt).tool.empty());
    // A tool number is a whole number from 0.
    TempFile bad("badtool.csv", "t,x,y,z,tool\n0,0,0,0,1\n0.01,0.1,0,0,T2\n");
    CHECK_THROWS_WITH(ingest(bad.path(), opt), Catch::Contains(":3") && Catch::Contains("column 'tool': 'T2' is not a number"));
    TempFile frac("fractool.csv", "t,x,y,z,tool\n0,0,0,0,1\n0.01,0.1,0,0,2.5\n");
    CHECK_THROWS_WITH(ingest(frac.path(), opt), Catch::Contains("column 'tool': '2.5' is not a tool number"));
}
