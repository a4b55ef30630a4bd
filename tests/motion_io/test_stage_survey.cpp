// Stage "survey": what the log holds before any repair.
#include "stage_rig.hpp"
#include "stages/survey.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;

namespace {

constexpr Flows kIn = Flow::Sessions | Flow::Positions | Flow::Feed | Flow::Spindle | Flow::Blocks;
constexpr Flows kOut = Flow::Sessions | Flow::Positions | Flow::Spindle | Flow::Blocks;

struct SurveyRig {
    explicit SurveyRig(bool event_driven = false)
        : rig{std::make_unique<detail::Survey>(diag, event_driven), kIn, kOut} {}
    detail::Diagnostics diag{"log.csv"};
    StageRig rig;
    const detail::Survey& survey() const { return *dynamic_cast<detail::Survey*>(rig.under_test); }
    void push(const Record& r) { rig.feeder->session_record(r); }
};

}  // namespace

TEST_CASE("survey: counts, intervals and the feed of plain differencing, the feed channel stops here", "[survey]") {
    SurveyRig s;
    s.rig.feeder->begin();
    // 3-4-5 steps of 5 mm every 10 ms: 500 mm/s = 30000 mm/min; then one step in 20 ms.
    for (int i = 0; i < 4; ++i) {
        s.push(pos(0.01 * i, 3.0 * i, 4.0 * i, 0, 2 + i));
        s.push(value(Chan::Feed, 0.01 * i, 30000, 2 + i));
        s.push(value(Chan::Spindle, 0.01 * i, 8000, 2 + i));
    }
    s.push(pos(0.05, 12, 16, 0, 6));
    s.push(block(0.05, 3, 6));
    detail::SessionSummary summary;
    s.rig.feeder->end(summary);
    IngestReport r;
    s.survey().report(r);
    CHECK(r.channels.at("pos").samples == 5);
    CHECK(r.channels.at("pos").interval.min_s == Approx(0.01));
    CHECK(r.channels.at("pos").interval.max_s == Approx(0.02));
    CHECK(r.channels.at("feed").samples == 4);
    CHECK(r.channels.at("spindle").samples == 4);
    CHECK(r.channels.at("block").samples == 1);
    CHECK(r.feed_raw_max_mm_min == Approx(30000));
    CHECK(r.feed_raw_min_mm_min == Approx(15000));
    // Everything but the feed goes on.
    CHECK(s.rig.out->positions().size() == 5);
    CHECK(s.rig.out->of(Chan::Spindle).size() == 4);
    CHECK(s.rig.out->of(Chan::Block).size() == 1);
    CHECK(s.rig.out->of(Chan::Feed).empty());
    CHECK(summary.position_reads == 5);
    CHECK(summary.first_line == 2);
    CHECK(summary.first_t_s == 0.0);
    CHECK(summary.last_t_s == 0.05);
}

TEST_CASE("survey: the feed channel's integral against the path length tells a 60x unit mix-up", "[survey]") {
    SurveyRig s;
    s.rig.feeder->begin();
    // 10 mm/s along x for 1 s; the feed channel says 600 "mm/min" read as mm/s: 36000 mm/min.
    for (int i = 0; i <= 100; ++i) {
        s.push(pos(0.01 * i, 0.1 * i));
        s.push(value(Chan::Feed, 0.01 * i, 36000));
    }
    s.rig.feeder->end();
    CHECK(s.survey().feed_to_path_ratio() == Approx(60).epsilon(1e-9));
    CHECK(s.survey().position_reads() == 101);
}

TEST_CASE("survey: the feed check leaves out the intervals in which a rotary axis turns", "[survey][rotary]") {
    SurveyRig s;
    s.rig.feeder->begin();
    // 10 mm/s along x with C standing (feed 600 mm/min) for 1 s, then C turning 60 deg/s with x
    // standing for 1 s, the feed counting its degrees as mm (3600): only the first second counts.
    // C standing to 0.001 deg (jitter) still counts as standing.
    for (int i = 0; i <= 200; ++i) {
        const double t = 0.01 * i;
        Record p = pos(t, 0.1 * std::min(i, 100));
        p.rot_deg[2] = i <= 100 ? 0.001 * (i % 2) : 0.6 * (i - 100);
        s.push(p);
        s.push(value(Chan::Feed, t, i < 100 ? 600 : 3600));
    }
    s.rig.feeder->end();
    CHECK(s.survey().feed_to_path_ratio() == Approx(1).epsilon(1e-9));
}

TEST_CASE("survey: a gap in a polled log is warned, an event-driven log's silences are not gaps", "[survey]") {
    for (bool event_driven : {false, true}) {
        SurveyRig s(event_driven);
        s.rig.feeder->begin();
        for (int i = 0; i < 20; ++i) s.push(pos(0.006 * i, 0.6 * i, 0, 0, 2 + i));
        s.push(pos(0.5, 13, 0, 0, 22));   // 386 ms without a reading
        s.rig.feeder->end();
        INFO("event-driven " << event_driven);
        const IngestWarning w = warning_of(s.diag, "gap");
        CHECK(w.count == (event_driven ? 0u : 1u));
        if (!event_driven) CHECK_THAT(w.message, Catch::Contains("log.csv:22") && Catch::Contains("0.386 s"));
    }
}

TEST_CASE("survey: a session whose time never advances is an error naming its first line", "[survey]") {
    SurveyRig s;
    s.rig.feeder->begin();
    s.push(pos(5.0, 1, 0, 0, 7));
    s.push(pos(5.0, 2, 0, 0, 8));
    CHECK_THROWS_WITH(s.rig.feeder->end(), Catch::Contains("log.csv:7") && Catch::Contains("time never advances"));
}
