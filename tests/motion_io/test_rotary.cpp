// Rotary axes (A, B, C) of a CSV log carried through the ingest into the motion model
// (docs/five_axis.md, section 2.2): the unwrap stage alone, then whole logs shaped like a dry run
// of a table that turns: readings every 6 ms with jitter, positions latched on a 2 ms CNC grid and
// written to 3 decimals, the C display counting 0 to 360.
#include "stage_rig.hpp"
#include "stages/stale.hpp"
#include "stages/unwrap.hpp"
#include "test_helpers.hpp"

#include <catch2/catch.hpp>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <random>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;

namespace {

Record rotary_pos(double t_s, double c_deg, std::size_t line) {
    Record r = pos(t_s, 100, 0, 50, line);
    r.rot_deg[2] = c_deg;
    return r;
}

struct TableTurn {
    double c0_deg = 350;            // the display passes 360 -> 0 after 1/3 s
    double c_rate_deg_s = 30;
    double x_rate_mm_s = 0;         // X moving too, or standing still
    double duration_s = 3;
    std::uint64_t seed = 11;
};

// t, x, y, z, c, s: a reading every 6 ms +-0.8 ms of what the CNC latched on its 2 ms grid.
std::string table_turn_csv(const TableTurn& spec) {
    std::mt19937_64 rng(spec.seed);
    std::uniform_real_distribution<double> jitter(-0.0008, 0.0008);
    std::string csv = "t,x,y,z,c,s\n";
    for (int k = 0;; ++k) {
        const double t = 0.006 * k + (k > 0 ? jitter(rng) : 0.0);
        if (t > spec.duration_s) break;
        const double latched = std::floor(t / 0.002) * 0.002;
        const double c = std::fmod(spec.c0_deg + spec.c_rate_deg_s * latched, 360.0);
        csv += fmt::format("{:.6f},{:.3f},{:.3f},{:.3f},{:.3f},10000\n", t, 100 + spec.x_rate_mm_s * latched, 0.0, 50.0, c);
    }
    return csv;
}

}  // namespace

TEST_CASE("unwrap: each angle takes the equivalent nearest the one before", "[rotary][unwrap]") {
    CHECK(detail::nearest_equivalent_deg(1.0, 359.0) == 361.0);
    CHECK(detail::nearest_equivalent_deg(359.0, 1.0) == -1.0);
    CHECK(detail::nearest_equivalent_deg(-179.0, 179.0) == 181.0);
    CHECK(detail::nearest_equivalent_deg(10.5, 10.0) == 10.5);
    CHECK(detail::nearest_equivalent_deg(0.25, 1080.0) == 1080.25);
    // Exactly half a turn: a head that swung 0 -> 180 deg between readings reads 180, not -180.
    CHECK(detail::nearest_equivalent_deg(180.0, 0.0) == 180.0);
    CHECK(detail::nearest_equivalent_deg(-180.0, 0.0) == -180.0);
    CHECK(detail::nearest_equivalent_deg(540.0, 0.0) == 180.0);   // 180 and -180 tie: nearer 540
    CHECK(detail::nearest_equivalent_deg(180.001, 0.0) == Approx(-179.999));

    detail::Diagnostics diag("log.csv");
    diag.facts().rotary = {false, false, true};
    StageRig rig(std::make_unique<detail::UnwrapRotary>(diag.facts()), Flow::Sessions | Flow::Positions,
                 Flow::Sessions | Flow::Positions);
    rig.feeder->begin();
    const double shown[] = {350, 355, 359.5, 4.5, 9.5, 1.0};
    for (std::size_t k = 0; k < 6; ++k) rig.feeder->session_record(rotary_pos(0.006 * double(k), shown[k], k + 2));
    rig.feeder->end();
    std::vector<double> c;
    for (const Record& r : rig.out->positions()) c.push_back(r.rot_deg[2]);
    CHECK(c == std::vector<double>{350, 355, 359.5, 364.5, 369.5, 361.0});
    // A new session starts from its first reading as shown.
    rig.feeder->begin();
    rig.feeder->session_record(rotary_pos(9.0, 4.5, 20));
    rig.feeder->end();
    CHECK(rig.out->positions().back().rot_deg[2] == 4.5);
}

TEST_CASE("stale_repeats: a turning table with X, Y, Z standing is no repeat", "[rotary][stale]") {
    detail::Diagnostics diag("log.csv");
    StageRig rig(std::make_unique<detail::StaleRepeats>(diag), Flow::Sessions | Flow::Positions,
                 Flow::Sessions | Flow::Positions);
    rig.feeder->begin();
    const double c[] = {0.0, 0.18, 0.36, 0.36, 0.54};   // one real repeat, of C
    for (std::size_t k = 0; k < 5; ++k) rig.feeder->session_record(rotary_pos(0.006 * double(k), c[k], k + 2));
    rig.feeder->end();
    std::vector<double> kept;
    for (const Record& r : rig.out->positions()) kept.push_back(r.rot_deg[2]);
    CHECK(kept == std::vector<double>{0.0, 0.18, 0.36, 0.54});
}

TEST_CASE("ingest: a C table turning through 360 deg is unwrapped, resampled and its rate recovered",
          "[rotary][ingest]") {
    for (const double x_rate : {0.0, 25.0}) {
        INFO("X at " << x_rate << " mm/s");
        TableTurn spec;
        spec.x_rate_mm_s = x_rate;
        const TempFile log("rotary_c_" + std::to_string(int(x_rate)) + ".csv", table_turn_csv(spec));
        IngestReport report;
        const MotionModel m = ingest(log.path(), ReadOptions{}, &report);
        CHECK(report.rotary_axes == "c");
        REQUIRE(m.size() > 2500);
        CHECK_FALSE(m.has_rotary(0));
        CHECK_FALSE(m.has_rotary(1));
        REQUIRE(m.has_rotary(2));
        REQUIRE(m.rot_deg[2].size() == m.size());
        REQUIRE(m.rot_vel_deg_s[2].size() == m.size());
        CHECK(warning_count(report, "stale_repeat") == 0);
        // Away from the ends (one-sided velocity windows), position and rate follow the turn: the
        // angle keeps counting past 360 and the rate is 30 deg/s to well within the ingest's 1 %.
        std::size_t checked = 0;
        for (std::size_t i = 0; i < m.size(); ++i) {
            const double t = m.t_s[i];
            if (t < 0.05 || t > spec.duration_s - 0.05) continue;
            INFO("t = " << t);
            CHECK(m.rot_deg[2][i] == Approx(spec.c0_deg + spec.c_rate_deg_s * t).margin(0.02));
            CHECK(m.rot_vel_deg_s[2][i] == Approx(spec.c_rate_deg_s).epsilon(0.01));
            CHECK(m.vx_mm_s[i] == Approx(x_rate).margin(0.01 * std::max(1.0, x_rate)));
            ++checked;
        }
        CHECK(checked > 2500);
        CHECK(m.rot_deg[2].back() > 360.0 + 30.0);   // past a whole turn, not back at the display's 0..360
        // Between samples the angle is the Hermite of the stored angles and rates.
        const std::size_t i = m.size() / 2;
        const MotionState s = sample_between(m, i, 0.5 * (m.t_s[i] + m.t_s[i + 1]));
        CHECK(s.rot_deg[2] == Approx(0.5 * (m.rot_deg[2][i] + m.rot_deg[2][i + 1])).margin(1e-6));
        CHECK(s.rot_vel_deg_s[2] == Approx(spec.c_rate_deg_s).epsilon(0.01));
    }
}

TEST_CASE("ingest: a three-axis log carries no rotary channels", "[rotary][ingest]") {
    const TempFile log("rotary_none.csv", synth_csv(straight_line_spec(3000, 40)));
    IngestReport report;
    const MotionModel m = ingest(log.path(), ReadOptions{}, &report);
    REQUIRE(m.size() > 100);
    CHECK(report.rotary_axes.empty());
    for (int k = 0; k < 3; ++k) {
        CHECK_FALSE(m.has_rotary(k));
        CHECK(m.rot_vel_deg_s[std::size_t(k)].empty());
    }
}

TEST_CASE("ingest: a rotary cell that is empty, not a number or beyond 1e9 deg is refused at its line",
          "[rotary][ingest][errors]") {
    auto message = [](const std::string& name, const std::string& csv) {
        const TempFile log(name, csv);
        try {
            ingest(log.path(), ReadOptions{});
        } catch (const IngestError& e) {
            return std::string(e.what());
        }
        return std::string("(accepted)");
    };
    const std::string head = "t,x,y,z,a,c\n0.000,1,2,3,0,10\n";
    CHECK_THAT(message("rot_empty.csv", head + "0.006,1,2,3,,10\n"),
               Catch::Contains(":3") && Catch::Contains("column 'a': empty while the linear axes are present"));
    CHECK_THAT(message("rot_huge.csv", head + "0.006,1,2,3,0,2e9\n"),
               Catch::Contains(":3") && Catch::Contains("column 'c'") && Catch::Contains("beyond"));
    CHECK_THAT(message("rot_alone.csv", head + "0.006,,,,0,10\n"),
               Catch::Contains(":3") && Catch::Contains("without the linear axes"));
    CHECK_THAT(message("rot_text.csv", head + "0.006,1,2,3,0,ten\n"), Catch::Contains(":3"));
}

namespace {

// A five-axis log whose feed column counts degrees as mm (FANUC: the feed of a block that turns a
// rotary axis is its travel over linear and rotary axes together, degrees as mm; an inverse-time
// (G93) block's actual feed is shown the same way): readings every 6 ms of
//   0 to 1 s: X at 10 mm/s, A and C standing              feed 600 mm/min
//   1 to 2 s: X at 10 mm/s while C turns 60 deg/s         feed sqrt(10^2 + 60^2) x 60 = 3649
//   2 to 3 s: X standing, C turning 90 deg/s              feed 5400 (deg/min as mm/min)
// The x, y, z path is 20 mm, the feed integrates to 10 + 60.8 + 90 = 160.8 mm: 8 x. `feed_scale`
// writes the feed column in another unit (1 / 25.4: in/min under a mm/min header).
std::string combined_feed_csv(double feed_scale = 1) {
    std::string csv = "t,x,y,z,a,c,feed [mm/min],s\n";
    for (int k = 0; 0.006 * k <= 3.0; ++k) {
        const double t = 0.006 * k;
        const double x = 100 + 10 * std::min(t, 2.0);
        const double c = 60 * std::clamp(t - 1, 0.0, 1.0) + 90 * std::max(t - 2, 0.0);
        const double feed = t < 1 ? 600 : t < 2 ? std::hypot(10.0, 60.0) * 60 : 5400;
        csv += fmt::format("{:.6f},{:.3f},0.000,50.000,0.000,{:.3f},{:.1f},8000\n", t, x, c, feed * feed_scale);
    }
    return csv;
}

}  // namespace

TEST_CASE("ingest: a feed combined over linear and rotary travel is no feed-unit mistake", "[rotary][ingest][feed]") {
    const TempFile log("combined_feed.csv", combined_feed_csv());
    IngestReport report;
    const MotionModel m = ingest(log.path(), ReadOptions{}, &report);
    CHECK(report.rotary_axes == "ac");
    REQUIRE(m.has_rotary(2));
    CHECK(warning_count(report, "feed_unit_suspect") == 0);
}

TEST_CASE("ingest: a five-axis log's feed in the wrong unit is still found where the rotary axes stand",
          "[rotary][ingest][feed]") {
    // in/min written under a mm/min header: 1/25.4 of the path on the first second.
    const TempFile log("combined_feed_inch.csv", combined_feed_csv(1 / 25.4));
    IngestReport report;
    (void)ingest(log.path(), ReadOptions{}, &report);
    REQUIRE(warning_count(report, "feed_unit_suspect") == 1);
    const auto w = std::find_if(report.warnings.begin(), report.warnings.end(),
                                [](const IngestWarning& x) { return x.code == "feed_unit_suspect"; });
    CHECK_THAT(w->message, Catch::Contains("--feed-units in/min"));
}
