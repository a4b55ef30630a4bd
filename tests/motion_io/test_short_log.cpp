// A log too short for the CNC clock's phase drift (under four chunks of 64 reads): the period comes
// from the bounds the time stamps put on the ticks and the CNC's nominal period inside them.
#include "test_helpers.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

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

namespace {

// `sessions` copies of a log's rows, each 100 s after the one before (a new session each: more
// than a minute apart), as a shift log with restarts writes them. Time columns are the first,
// third and fifth (synthesize_dry_run's layout).
std::string repeated_sessions(const std::string& csv, int sessions) {
    std::istringstream in(csv);
    std::string header;
    std::getline(in, header);
    std::vector<std::string> rows;
    for (std::string line; std::getline(in, line);) rows.push_back(line);
    std::string out = header + "\n";
    char buf[32];
    for (int s = 0; s < sessions; ++s)
        for (const std::string& row : rows) {
            std::vector<std::string> f;
            std::size_t start = 0;
            for (std::size_t comma; (comma = row.find(',', start)) != std::string::npos; start = comma + 1)
                f.push_back(row.substr(start, comma - start));
            f.push_back(row.substr(start));
            for (const std::size_t c : {0u, 2u, 4u}) {
                std::snprintf(buf, sizeof buf, "%.6f", std::stod(f[c]) + 100.0 * s);
                f[c] = buf;
            }
            for (std::size_t i = 0; i < f.size(); ++i) out += (i ? "," : "") + f[i];
            out += '\n';
        }
    return out;
}

}  // namespace

TEST_CASE("short sessions of one log share the period the first one found: one scan, the same timing",
          "[repair][short]") {
    // A short log 12 times over: each session alone would be scanned at the fine phase resolution
    // (0.3 s each, a log of 1000 such sessions 3 minutes); the CNC keeps its period.
    const std::string one = synth_csv(straight_line_spec(6000, 20, 2));
    TempFile single("one_session.csv", one), many("sessions.csv", repeated_sessions(one, 12));
    IngestReport r1, r12;
    const MotionModel m1 = ingest(single.path(), ReadOptions{}, &r1);
    const MotionModel m12 = ingest(many.path(), ReadOptions{}, &r12);
    REQUIRE(r12.sessions == 12);
    CHECK(warning_count(r12, "period_short_log") == 1);      // the one scan
    CHECK(warning_count(r12, "period_not_estimated") == 0);
    CHECK(r12.channels.at("pos").update_period_s == Approx(0.004).epsilon(1e-9));
    // Every session is timed as the log alone is: the same velocities, sample for sample.
    REQUIRE(m12.session_start.size() == 12);
    for (std::size_t s = 0; s < 12; ++s) {
        const std::size_t at = m12.session_start[s];
        const std::size_t end = s + 1 < 12 ? m12.session_start[s + 1] : m12.size();
        REQUIRE(end - at == m1.size());
        double worst = 0;
        for (std::size_t i = 0; i < m1.size(); ++i)
            worst = std::max(worst, std::fabs(m12.vx_mm_s[at + i] - m1.vx_mm_s[i]) + std::fabs(m12.vy_mm_s[at + i] - m1.vy_mm_s[i]));
        CHECK(worst < 1e-3);
    }
}

TEST_CASE("a log of many short sessions with no period to find makes at most 8 scans, and says so", "[repair][short]") {
    // Readings every 6 ms with jitter and no CNC grid behind them: no period explains them better
    // than their own stamps, so every session would be scanned in vain.
    std::string log = "t,x,y,z\n";
    std::uint64_t state = 12345;
    auto uniform = [&] {   // a small documented LCG (Knuth MMIX), seeded: the same log every run
        state = state * 6364136223846793005ULL + 1442695040888963407ULL;
        return static_cast<double>(state >> 11) / 9007199254740992.0;
    };
    char buf[96];
    const int sessions = 20, rows = 40;
    for (int s = 0; s < sessions; ++s)
        for (int k = 0; k < rows; ++k) {
            const double t = 100.0 * s + 0.006 * k + 0.0004 * (uniform() - 0.5);
            std::snprintf(buf, sizeof buf, "%.6f,%.3f,%.3f,-2.000\n", t, 10 + 0.1 * k + 0.02 * uniform(), 0.05 * k);
            log += buf;
        }
    TempFile f("no_period_sessions.csv", log);
    IngestReport report;
    const MotionModel m = ingest(f.path(), ReadOptions{}, &report);
    CHECK(report.sessions == std::size_t(sessions));
    CHECK(report.channels.at("pos").update_period_s == 0);
    CHECK(warning_count(report, "period_not_estimated") == std::size_t(sessions - 8));
    CHECK(m.session_start.size() == std::size_t(sessions));
}
