// SHDR rotary items (A, B, C in degrees; docs/five_axis.md section 2.1, docs/formats.md "Key map"):
// which item feeds which axis, how they join the position readings, what is refused, and the real
// Okuma MULTUS log's B and C axes.
#include "test_helpers.hpp"

#include <catch2/catch.hpp>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;

namespace {

const std::string kStart = "2024-01-01T00:00:";

// SHDR time stamp t seconds after 2024-01-01T00:00:00 (t < 60).
std::string stamp(double t_s) { return fmt::format("{}{:010.7f}Z", kStart, t_s); }

// An adapter's stream while the C table turns at 30 deg/s from 350 deg with X, Y, Z standing:
// the linear items once (an adapter sends only what changes), then C every 6 ms, displayed 0 to
// 360. C1actm is the machine coordinate; C1actw is shown 10 deg off (a work offset) and must not
// be read. B is only there as a work-coordinate item, standing at 15 deg.
std::string turning_c_shdr(double duration_s = 1.5) {
    std::string log = stamp(0) + "|X1actw|100|Y1actw|0|Z1actw|50|S1speed|10000|B1actw|15\n";
    for (int k = 0; 0.006 * k <= duration_s; ++k) {
        const double t = 0.006 * k;
        const double c = std::fmod(350 + 30 * t, 360.0);
        log += fmt::format("{}|C1actm|{:.4f}|C1actw|{:.4f}\n", stamp(t), c, std::fmod(c + 10, 360.0));
    }
    return log;
}

}  // namespace

TEST_CASE("SHDR rotary: C turning alone makes positions, machine items win, the display is unwrapped",
          "[shdr][rotary]") {
    TempFile f("turning_c.shdr", turning_c_shdr());
    ReadOptions opt;
    opt.step_ms = 1;
    IngestReport report;
    const MotionModel m = ingest(f.path(), opt, &report);
    CHECK(report.rotary_axes == "bc");
    REQUIRE(m.has_rotary(2));
    REQUIRE(m.has_rotary(1));
    CHECK_FALSE(m.has_rotary(0));
    REQUIRE(m.size() > 1000);
    // Every C reading with X, Y, Z standing is a position: C drives the motion model's time.
    CHECK(m.t_s.back() == Approx(1.5).margin(0.01));
    for (std::size_t i = 0; i < m.size(); ++i) {
        INFO("t = " << m.t_s[i]);
        // C1actm, not C1actw (10 deg off): 350 + 30 t, counting on past 360.
        REQUIRE(m.rot_deg[2][i] == Approx(350 + 30 * m.t_s[i]).margin(1e-3));
        REQUIRE(m.rot_deg[1][i] == Approx(15).margin(1e-9));
        REQUIRE(m.x_mm[i] == Approx(100).margin(1e-9));
        REQUIRE(m.z_mm[i] == Approx(50).margin(1e-9));
    }
    CHECK(m.rot_deg[2].back() > 390);   // past the display's 360 -> 0
    CHECK(m.rot_vel_deg_s[2][m.size() / 2] == Approx(30).epsilon(1e-6));
}

TEST_CASE("SHDR rotary: the latched angles leave the linear motion as the log without them gives it",
          "[shdr][rotary]") {
    // X moves along; C stands at 90 and is sent once (with the dump), as a standing axis is.
    std::string plain, with_c;
    for (int k = 0; k <= 200; ++k) {
        const double t = 0.004 * k;
        const std::string line = fmt::format("{}|X1actw|{:.3f}|Y1actw|0|Z1actw|-5|S1speed|8000", stamp(t), 10 + 50 * t);
        plain += line + "\n";
        with_c += line + (k == 0 ? "|C3actm|90\n" : "\n");
    }
    TempFile a("plain.shdr", plain), b("with_c.shdr", with_c);
    ReadOptions opt;
    opt.step_ms = 1;
    IngestReport ra, rb;
    const MotionModel ma = ingest(a.path(), opt, &ra), mb = ingest(b.path(), opt, &rb);
    CHECK(ra.rotary_axes.empty());
    CHECK(rb.rotary_axes == "c");
    REQUIRE(ma.size() == mb.size());
    CHECK(ma.x_mm == mb.x_mm);
    CHECK(ma.vx_mm_s == mb.vx_mm_s);
    CHECK(ma.t_s == mb.t_s);
    CHECK(std::all_of(mb.rot_deg[2].begin(), mb.rot_deg[2].end(), [](double c) { return std::abs(c - 90) < 1e-9; }));
    CHECK(ra.channels.at("pos").samples == rb.channels.at("pos").samples);
}

TEST_CASE("SHDR rotary: with a 3-D path position every line's angles join its position", "[shdr][rotary]") {
    std::string log = stamp(0) + "|p1LPathPos|0 0 0|S1speed|5000|B1actm|0|C3actm|0\n";
    for (int k = 1; k <= 100; ++k) {
        const double t = 0.01 * k;
        // The path moves for the first half; then only B turns, sent on its own.
        if (k <= 50)
            log += fmt::format("{}|p1LPathPos|{:.3f} 0 0\n", stamp(t), 100 * t);
        else
            log += fmt::format("{}|B1actm|{:.3f}\n", stamp(t), 20 * (t - 0.5));
    }
    TempFile f("path_b.shdr", log);
    ReadOptions opt;
    opt.step_ms = 10;
    IngestReport report;
    const MotionModel m = ingest(f.path(), opt, &report);
    CHECK(report.rotary_axes == "bc");
    // One position per line: the B lines make positions too.
    CHECK(report.channels.at("pos").samples == 101);
    REQUIRE(m.has_rotary(1));
    CHECK(m.rot_deg[1].back() == Approx(10).margin(1e-9));
    CHECK(m.x_mm.back() == Approx(50).margin(1e-9));
    CHECK(m.t_s.back() == Approx(1.0).margin(1e-9));
}

TEST_CASE("SHDR rotary: UNAVAILABLE is held, an item that never has a value gives no axis", "[shdr][rotary]") {
    // C1actm (first choice) is only ever UNAVAILABLE: C3actm, which has values, serves. A1actm
    // likewise never has a value: no A axis.
    std::string log = stamp(0) + "|X1actw|0|Y1actw|0|Z1actw|0|C1actm|UNAVAILABLE|A1actm|UNAVAILABLE|C3actm|10\n";
    log += stamp(0.1) + "|X1actw|1|C3actm|UNAVAILABLE\n";
    log += stamp(0.2) + "|X1actw|2|C3actm|30\n";
    log += stamp(0.3) + "|X1actw|3\n";
    TempFile f("unavailable.shdr", log);
    ReadOptions opt;
    opt.step_ms = 100;
    IngestReport report;
    const MotionModel m = ingest(f.path(), opt, &report);
    CHECK(report.rotary_axes == "c");
    CHECK(warning_count(report, "unavailable") == 1);   // C3actm's; C1actm and A1actm are not read
    REQUIRE(m.size() == 4);
    CHECK(m.rot_deg[2][1] == Approx(10));   // held through UNAVAILABLE
    CHECK(m.rot_deg[2][3] == Approx(30));
}

TEST_CASE("SHDR rotary: positions before every axis is known are skipped, naming the axis", "[shdr][rotary]") {
    std::string log = stamp(0) + "|X1actw|0|Y1actw|0|Z1actw|0\n";
    log += stamp(0.1) + "|X1actw|1\n";
    log += stamp(0.2) + "|X1actw|2|C1actm|45\n";
    log += stamp(0.3) + "|X1actw|3\n";
    log += stamp(0.4) + "|X1actw|4\n";
    TempFile f("late_c.shdr", log);
    ReadOptions opt;
    opt.step_ms = 100;
    IngestReport report;
    const MotionModel m = ingest(f.path(), opt, &report);
    CHECK(warning_count(report, "axis_incomplete") == 2);
    const auto w = std::find_if(report.warnings.begin(), report.warnings.end(),
                                [](const IngestWarning& x) { return x.code == "axis_incomplete"; });
    REQUIRE(w != report.warnings.end());
    CHECK_THAT(w->message, Catch::Contains("rotary axis C") && Catch::Contains("first at") && Catch::Contains("late_c.shdr:1)"));
    REQUIRE(m.size() == 3);
    CHECK(m.x_mm.front() == Approx(2));
    CHECK(m.rot_deg[2].front() == Approx(45));
}

TEST_CASE("SHDR rotary: a non-finite or huge angle is refused at its line and column", "[shdr][rotary][errors]") {
    const std::string head = stamp(0) + "|X1actw|0|Y1actw|0|Z1actw|0|C1actm|0\n";
    {
        TempFile f("nan_c.shdr", head + stamp(0.1) + "|X1actw|1|C1actm|NaN\n");
        CHECK_THROWS_WITH(ingest(f.path(), ReadOptions{}),
                          Catch::Contains("nan_c.shdr:2:") && Catch::Contains("key 'C1actm'") &&
                              Catch::Contains("'NaN' is not a finite number"));
    }
    {
        TempFile f("huge_c.shdr", head + stamp(0.1) + "|X1actw|1|C1actm|2.5e12\n");
        CHECK_THROWS_WITH(ingest(f.path(), ReadOptions{}),
                          Catch::Contains("huge_c.shdr:2:46:") && Catch::Contains("key 'C1actm'") &&
                              Catch::Contains("2.5e+12 deg beyond +-1e+09 deg") && Catch::Contains("no axis position"));
    }
    {
        TempFile f("text_c.shdr", head + stamp(0.1) + "|X1actw|1|C1actm|12 deg\n");
        CHECK_THROWS_WITH(ingest(f.path(), ReadOptions{}),
                          Catch::Contains("text_c.shdr:2:") && Catch::Contains("'12 deg' is not a number"));
    }
}

TEST_CASE("SHDR rotary: a map names the items and their unit, and may not give one item two axes", "[shdr][rotary][map]") {
    std::string log;
    for (int k = 0; k <= 10; ++k)
        log += fmt::format("{}|X1actw|{}|Y1actw|0|Z1actw|0|tableC|{:.6f}\n", stamp(0.1 * k), k, 0.1 * k);
    TempFile f("mapped_c.shdr", log);
    TempFile map("rot_map.json", R"({"c": "tableC", "units": {"angle": "rad"}})");
    ReadOptions opt;
    opt.map_file = map.path();
    opt.step_ms = 100;
    IngestReport report;
    const MotionModel m = ingest(f.path(), opt, &report);
    CHECK(report.rotary_axes == "c");
    REQUIRE(m.has_rotary(2));
    CHECK(m.rot_deg[2].back() == Approx(180 / 3.14159265358979323846).epsilon(1e-12));

    TempFile twice("twice_map.json", R"({"b": "tableC", "c": "tableC"})");
    opt.map_file = twice.path();
    CHECK_THROWS_WITH(ingest(f.path(), opt), Catch::Contains("key 'tableC'") && Catch::Contains("another channel"));
}

TEST_CASE("SHDR rotary: an index reported by two sparse readings stays between them, its rate with it",
          "[shdr][rotary]") {
    // X moves on at 10 mm/s, read every 0.3 s; B stands at 0, is next reported at 180 (the head
    // indexed between the readings at 2.7 and 3.0 s), and stands there. The machine turned from 0 to
    // 180 and stopped: the resampled B must not swing past either end (it went to -15 and 195).
    std::string log = stamp(0) + "|X1actw|0|Y1actw|0|Z1actw|0|S1speed|1000|B1actw|0\n";
    for (int k = 1; k <= 20; ++k)
        log += fmt::format("{}|X1actw|{:.3f}{}\n", stamp(0.3 * k), 3.0 * k, k == 10 ? "|B1actw|180" : "");
    TempFile f("index_b.shdr", log);
    ReadOptions opt;
    opt.step_ms = 10;
    IngestReport report;
    const MotionModel m = ingest(f.path(), opt, &report);
    REQUIRE(m.has_rotary(1));
    REQUIRE(m.size() > 500);
    const auto [lo, hi] = std::minmax_element(m.rot_deg[1].begin(), m.rot_deg[1].end());
    CHECK(*lo >= -0.005);   // the limit's tolerance: 0.005 mm at 100 mm from the axis, 0.0029 deg
    CHECK(*hi <= 180.005);
    CHECK(m.rot_deg[1].front() == Approx(0).margin(1e-9));
    CHECK(m.rot_deg[1].back() == Approx(180).margin(1e-9));
    CHECK(*std::max_element(m.rot_vel_deg_s[1].begin(), m.rot_vel_deg_s[1].end()) > 300);   // it did turn
    // The rate is the positions' derivative: across each grid step the trapezoid of the rates gives
    // the change of angle (to the cubic's third derivative, under 0.01 deg at 10 ms here).
    double worst = 0;
    for (std::size_t i = 1; i < m.size(); ++i) {
        const double dt = m.t_s[i] - m.t_s[i - 1];
        worst = std::max(worst, std::abs(m.rot_deg[1][i] - m.rot_deg[1][i - 1] -
                                         0.5 * dt * (m.rot_vel_deg_s[1][i] + m.rot_vel_deg_s[1][i - 1])));
    }
    CHECK(worst < 0.01);
    // X, at constant feed, is untouched by the limit.
    for (std::size_t i = 0; i < m.size(); ++i) REQUIRE(m.vx_mm_s[i] == Approx(10).margin(1e-6));
}

TEST_CASE("Okuma SHDR: B stays within its readings across the 0 -> 180 deg index", "[shdr][rotary][shared]") {
    // B1actw reads 0 (14:28:49.8), 180 (14:29:01.56), 180.0091, then 166.2915, 137.3912, 135 as
    // the head comes back: the log's extremes are 0 and 180.0091 deg. The resampled B went from
    // -14.8 to 192.2 deg around the index before its slopes were limited.
    ReadOptions opt;
    opt.step_ms = 50;
    const MotionModel m = ingest(shared_path("data/real/okuma_multus_shdr/okuma.txt"), opt);
    REQUIRE(m.has_rotary(1));
    const auto [lo, hi] = std::minmax_element(m.rot_deg[1].begin(), m.rot_deg[1].end());
    CHECK(*lo >= -0.01);
    CHECK(*hi <= 180.0091 + 0.01);
    CHECK(*hi >= 180);
}

TEST_CASE("Okuma SHDR: B (work item only) and C (machine item) are read, in range, continuous once unwrapped",
          "[shdr][rotary][shared]") {
    // The MULTUS log has B1actw (no B1actm) and C3actm beside C3actw; C is displayed 0 to 360 and
    // jumps from 315.0503 to 56.3 deg between two readings (N1202 to N1203: +101.25 deg across 360).
    ReadOptions opt;
    opt.step_ms = 50;
    IngestReport report;
    const MotionModel m = ingest(shared_path("data/real/okuma_multus_shdr/okuma.txt"), opt, &report);
    CHECK(report.rotary_axes == "bc");
    REQUIRE(m.has_rotary(1));
    REQUIRE(m.has_rotary(2));
    CHECK_FALSE(m.has_rotary(0));
    CHECK(warning_count(report, "axis_incomplete") == 0);   // every restart dump sends B and C
    // B is read between 0 and 180.0091 deg (the log's extremes); the head indexes by 180 deg
    // (0 -> 180) between two of the adapter's sparse reports. Half a turn is a tie for the unwrap
    // stage, which keeps the reading as shown, so B stays at the log's range: 0 to 180 (before this
    // was fixed it reached -180). The resampled B stays within it too (the next test).
    const auto [b_lo, b_hi] = std::minmax_element(m.rot_deg[1].begin(), m.rot_deg[1].end());
    CHECK(*b_hi - *b_lo > 170);
    CHECK(*b_lo > -20);
    CHECK(*b_hi > 170);
    CHECK(*b_hi < 200);
    // C: continuous within each session, and counting past 360 where the display wrapped.
    double largest_step_deg = 0, c_max = -1e9;
    for (std::size_t s = 0; s < m.session_start.size(); ++s) {
        const std::size_t a = m.session_start[s], e = s + 1 < m.session_start.size() ? m.session_start[s + 1] : m.size();
        for (std::size_t i = a; i + 1 < e; ++i)
            largest_step_deg = std::max(largest_step_deg, std::abs(m.rot_deg[2][i + 1] - m.rot_deg[2][i]));
        for (std::size_t i = a; i < e; ++i) c_max = std::max(c_max, m.rot_deg[2][i]);
    }
    CHECK(largest_step_deg < 60);   // 50 ms steps: no 360 deg jump from the display
    CHECK(c_max > 360);             // 315.05 -> 56.3 read as 416.3
}
