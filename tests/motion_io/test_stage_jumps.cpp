// Stage "drop_jumps": position readings no machine could have reached are glitches.
#include "stage_rig.hpp"
#include "stages/jumps.hpp"

#include <catch2/catch.hpp>

#include <cmath>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;

namespace {

struct JumpRig {
    explicit JumpRig(detail::JumpLimits limits = {})
        : rig{std::make_unique<detail::DropJumps>(diag, limits), Flow::Sessions | Flow::Positions,
              Flow::Sessions | Flow::Positions} {
        rig.feeder->begin();
    }
    detail::Diagnostics diag{"log.csv"};
    StageRig rig;
    // Readings every 6 ms along x at 6000 mm/min (0.6 mm per reading), line = 2 + index.
    void move(int from, int to) {
        for (int i = from; i < to; ++i) push(i, 0.6 * i);
    }
    void push(int i, double x) { rig.feeder->session_record(pos(0.006 * i, x, 5, -2, static_cast<std::size_t>(2 + i))); }
    void end() { rig.feeder->end(); }
    std::vector<std::size_t> lines() const {
        std::vector<std::size_t> l;
        for (const Record& r : rig.out->positions()) l.push_back(r.line);
        return l;
    }
    std::size_t dropped() const { return dynamic_cast<detail::DropJumps*>(rig.under_test)->dropped(); }
};

std::vector<std::size_t> lines_except(int n, std::vector<std::size_t> gone) {
    std::vector<std::size_t> l;
    for (int i = 0; i < n; ++i)
        if (std::find(gone.begin(), gone.end(), static_cast<std::size_t>(2 + i)) == gone.end())
            l.push_back(static_cast<std::size_t>(2 + i));
    return l;
}

}  // namespace

TEST_CASE("drop_jumps: motion up to the rapid traverse passes untouched and undelayed", "[jumps]") {
    JumpRig j;
    // 190 m/min: 19 mm per 6 ms.
    for (int i = 0; i < 20; ++i) j.push(i, 19.0 * i);
    CHECK(j.rig.out->positions().size() == 20);   // the first waited for the second; then each passes at once
    j.end();
    CHECK(j.lines() == lines_except(20, {}));
    CHECK(j.diag.warnings().empty());
}

TEST_CASE("drop_jumps: a reading that jumps away and back is dropped, naming it", "[jumps]") {
    JumpRig j;
    j.move(0, 10);
    j.push(10, 300.0);   // 294 mm in 6 ms
    j.move(11, 20);
    j.end();
    CHECK(j.lines() == lines_except(20, {12}));
    const IngestWarning w = warning_of(j.diag, "glitch_dropped");
    CHECK(w.count == 1);
    CHECK_THAT(w.message, Catch::Contains("log.csv:12") && Catch::Contains("position (300, 5, -2)") &&
                              Catch::Contains("294.600 mm") && Catch::Contains("comes back"));
}

TEST_CASE("drop_jumps: six readings off together, and six scattered, are all dropped", "[jumps]") {
    JumpRig j;
    j.move(0, 10);
    for (int i = 10; i < 16; ++i) j.push(i, 1e6);   // stuck at a far value for 36 ms
    j.move(16, 30);
    int next = 30;
    for (int i : {32, 40, 47, 51, 60, 66}) {
        j.move(next, i);
        j.push(i, i % 2 ? -400.0 : 800.0);
        next = i + 1;
    }
    j.move(next, 70);
    j.end();
    CHECK(j.lines() == lines_except(70, {12, 13, 14, 15, 16, 17, 34, 42, 49, 53, 62, 68}));
    CHECK(j.dropped() == 12);
    CHECK(warning_of(j.diag, "glitch_dropped").count == 12);
}

TEST_CASE("drop_jumps: a glitch in the first or the last reading of a session is dropped", "[jumps]") {
    JumpRig j;
    j.push(0, 5000);
    j.move(1, 10);
    j.push(10, -5000);
    j.end();
    CHECK(j.lines() == lines_except(11, {2, 12}));
    CHECK(warning_of(j.diag, "glitch_dropped").count == 2);
}

TEST_CASE("drop_jumps: a jump the log stays at is real and kept, with a warning", "[jumps]") {
    JumpRig j;
    j.move(0, 10);
    for (int i = 10; i < 60; ++i) j.push(i, 500.0 + 0.6 * i);   // lost readings: the machine is elsewhere now
    j.end();
    CHECK(j.lines() == lines_except(60, {}));
    const IngestWarning w = warning_of(j.diag, "position_jump");
    CHECK(w.count == 1);
    CHECK_THAT(w.message, Catch::Contains("log.csv:12") && Catch::Contains("kept"));
    CHECK(j.diag.warnings().size() == 1);
}

TEST_CASE("drop_jumps: sparse readings of an event-driven log move far between them and pass", "[jumps]") {
    JumpRig j;
    // 400 mm in 10 s of silence (2.4 m/min), then a reading every 0.3 s.
    j.rig.feeder->session_record(pos(0.0, 0, 0, 0, 2));
    j.rig.feeder->session_record(pos(0.3, 0, 0, 0, 3));
    j.rig.feeder->session_record(pos(10.3, 400, 0, 0, 4));
    j.rig.feeder->session_record(pos(10.6, 410, 0, 0, 5));
    j.end();
    CHECK(j.lines() == std::vector<std::size_t>{2, 3, 4, 5});
    CHECK(j.diag.warnings().empty());
}

TEST_CASE("drop_jumps: each session starts afresh", "[jumps]") {
    JumpRig j;
    j.move(0, 5);
    j.end();
    j.rig.feeder->begin();
    // A new recording elsewhere: no jump from the last session's position.
    for (int i = 0; i < 5; ++i) j.rig.feeder->session_record(pos(0.006 * i, 900 + 0.6 * i, 0, 0, 100 + i));
    j.end();
    CHECK(j.rig.out->positions().size() == 10);
    CHECK(j.diag.warnings().empty());
    CHECK(j.rig.out->sessions_begun == 2);
}
