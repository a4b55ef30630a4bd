// A log too short for the CNC clock's phase drift (under four chunks of 64 reads): the period comes
// from the bounds the time stamps put on the ticks and the CNC's nominal period inside them.
#include "test_helpers.hpp"

#include <catch2/catch.hpp>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;

TEST_CASE("a short log (about 80 reads) is timed on the 4 ms grid: steady feed within 1 %, with a warning",
          "[repair][short]") {
    const double feed = 6000;
    // 20 mm: the move is short enough to leave no chunk for the phase drift, long enough for a
    // steady stretch between the acceleration ramps.
    for (std::uint64_t seed : {1u, 2u, 3u}) {
        const auto spec = straight_line_spec(feed, 20, seed);
        TempFile f("short_log.csv", synth_csv(spec));
        ReadOptions opt;
        opt.step_ms = 1.0;
        IngestReport report;
        const MotionModel m = ingest(f.path(), opt, &report);
        INFO("seed " << seed);
        REQUIRE(report.channels.at("pos").samples < 4 * 64);
        REQUIRE(m.size() > 100);
        CHECK(report.channels.at("pos").update_period_s == Approx(0.004).epsilon(1e-9));
        CHECK(warning_count(report, "period_short_log") == 1);
        // Plain differencing beats by more than 10 %; the repaired feed peaks at the programmed one.
        CHECK(report.feed_raw_max_mm_min > 1.1 * feed);
        CHECK(report.feed_repaired_max_mm_min < 1.01 * feed);
        CHECK(report.feed_repaired_max_mm_min > 0.99 * feed);
    }
}

TEST_CASE("a log long enough for the phase drift gives no short-log warning", "[repair][short]") {
    const auto spec = straight_line_spec(6000, 400);
    TempFile f("long_log.csv", synth_csv(spec));
    ReadOptions opt;
    IngestReport report;
    ingest(f.path(), opt, &report);
    CHECK(warning_count(report, "period_short_log") == 0);
    CHECK(report.channels.at("pos").update_period_s == Approx(0.004).epsilon(1e-3));
}
