// Stage "sequence": time order within the reorder horizon, sessions, single axes merged.
#include "stage_rig.hpp"
#include "stages/sequence.hpp"

#include <catch2/catch.hpp>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;

namespace {

struct SequenceRig {
    detail::Diagnostics diag{"log.csv"};
    StageRig rig{std::make_unique<detail::Sequence>(diag), static_cast<Flows>(Flow::Checked),
                 Flow::Sessions | Flow::Positions | Flow::Feed | Flow::Spindle | Flow::Blocks};
    void push(const Record& r) { rig.chain.push(r); }
    std::vector<double> times() const {
        std::vector<double> t;
        for (const Record& r : rig.out->records) t.push_back(r.t_s);
        return t;
    }
};

}  // namespace

TEST_CASE("sequence: records up to 1 s late are put in time order and counted", "[sequence]") {
    SequenceRig s;
    for (double t : {0.0, 0.01, 0.03, 0.02, 0.04, 0.5, 0.05}) s.push(pos(t, t));
    s.push(value(Chan::Spindle, 0.045, 100));
    CHECK(s.rig.out->records.empty());   // nothing is final until 1 s has passed after it
    s.push(pos(1.045, 0));
    CHECK(s.times() == std::vector<double>{0.0, 0.01, 0.02, 0.03, 0.04});
    s.rig.chain.finish();
    CHECK(s.times() == std::vector<double>{0.0, 0.01, 0.02, 0.03, 0.04, 0.045, 0.05, 0.5, 1.045});
    CHECK(s.rig.out->records[5].ch == Chan::Spindle);
    CHECK(warning_of(s.diag, "time_backwards").count == 3);   // 0.02, 0.05 and the spindle at 0.045
    CHECK(s.rig.out->sessions_begun == 1);
    CHECK(s.rig.out->summaries.size() == 1);
}

TEST_CASE("sequence: a jump back beyond the horizon or a silence over 60 s starts a session", "[sequence]") {
    SequenceRig s;
    s.push(pos(100.0, 1));
    s.push(pos(100.5, 2));
    s.push(pos(98.0, 3));     // 2.5 s back: a restart dump
    s.push(pos(98.1, 4));
    s.push(pos(170.0, 5));    // 71.9 s later
    s.rig.chain.finish();
    CHECK(s.rig.out->sessions_begun == 3);
    CHECK(s.rig.out->summaries.size() == 3);
    CHECK(s.times() == std::vector<double>{100.0, 100.5, 98.0, 98.1, 170.0});
    CHECK(warning_of(s.diag, "session_backwards").count == 1);
    CHECK(warning_of(s.diag, "session_gap").count == 1);
}

TEST_CASE("sequence: single axes stamped alike make one position once all three are known", "[sequence]") {
    SequenceRig s;
    s.push(value(Chan::AxisX, 0.0, 1.0, 2));
    s.push(value(Chan::AxisY, 0.0, 2.0, 2));   // z still unknown: nothing yet
    s.push(value(Chan::AxisX, 0.1, 1.5, 3));
    s.push(value(Chan::AxisZ, 0.1, 3.0, 3));
    s.push(value(Chan::AxisY, 0.2, 2.5, 4));   // one axis changes: the others held
    s.rig.chain.finish();
    const auto p = s.rig.out->positions();
    REQUIRE(p.size() == 2);
    CHECK(p[0].t_s == 0.1);
    CHECK((p[0].v[0] == 1.5 && p[0].v[1] == 2.0 && p[0].v[2] == 3.0));
    CHECK((p[1].v[0] == 1.5 && p[1].v[1] == 2.5 && p[1].v[2] == 3.0));
    CHECK(warning_of(s.diag, "axis_incomplete").count == 1);
}

TEST_CASE("sequence: the end of the stream ends the session, records after it start another", "[sequence]") {
    SequenceRig s;
    s.push(pos(0.0, 0));
    s.push(pos(0.1, 1));
    s.rig.chain.finish();
    CHECK(s.rig.out->summaries.size() == 1);
    s.push(pos(0.2, 2));
    s.rig.chain.finish();
    CHECK(s.rig.out->sessions_begun == 2);
    CHECK(s.rig.out->positions().size() == 3);
}
