// Stage "hold": for event-driven logs, a value unchanged through a silence is made explicit.
#include "stage_rig.hpp"
#include "stages/hold.hpp"

#include <catch2/catch.hpp>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;

namespace {

struct HoldRig {
    HoldRig() { rig.feeder->begin(); }
    StageRig rig{std::make_unique<detail::HoldValues>(), Flow::Sessions | Flow::Positions | Flow::Spindle,
                 Flow::Sessions | Flow::Positions | Flow::Spindle};
    void push(const Record& r) { rig.feeder->session_record(r); }
};

}  // namespace

TEST_CASE("hold: after a silence over twice the usual interval, the held value is repeated one interval before "
          "the change", "[hold]") {
    HoldRig h;
    for (int i = 0; i < 5; ++i) h.push(pos(0.1 * i, i, 0, 0, 2 + i));   // every 0.1 s
    h.push(pos(2.0, 10, 0, 0, 7));                                       // 1.6 s of silence
    const auto p = h.rig.out->positions();
    REQUIRE(p.size() == 7);
    // The copy: the position held since 0.4 s, stamped 0.1 s (the median interval) before 2.0 s.
    CHECK(p[5].t_s == Approx(1.9));
    CHECK(p[5].v[0] == 4);
    CHECK(p[5].line == 7);
    CHECK(p[6].v[0] == 10);
}

TEST_CASE("hold: nothing is inserted before three intervals are known, nor after an ordinary one", "[hold]") {
    HoldRig h;
    h.push(pos(0.0, 0));
    h.push(pos(0.1, 1));
    h.push(pos(0.2, 2));
    h.push(pos(5.0, 3));   // only two intervals known
    h.push(pos(5.1, 4));
    h.push(pos(5.25, 5));  // 1.5 x the usual: not a silence
    CHECK(h.rig.out->positions().size() == 6);
}

TEST_CASE("hold: spindle readings are held on their own clock, and each session starts afresh", "[hold]") {
    HoldRig h;
    for (int i = 0; i < 4; ++i) h.push(value(Chan::Spindle, 0.5 * i, 1000));
    h.push(value(Chan::Spindle, 3.5, 2000));   // 2 s silence against 0.5 s usual
    const auto s = h.rig.out->of(Chan::Spindle);
    REQUIRE(s.size() == 6);
    CHECK(s[4].t_s == Approx(3.0));
    CHECK(s[4].v[0] == 1000);
    h.rig.feeder->end();
    h.rig.feeder->begin();
    for (int i = 0; i < 3; ++i) h.push(value(Chan::Spindle, 0.5 * i, 1000));
    h.push(value(Chan::Spindle, 10.0, 3000));   // the new session knows only two intervals
    CHECK(h.rig.out->of(Chan::Spindle).size() == 10);
}
