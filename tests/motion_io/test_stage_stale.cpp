// Stage "stale_repeats": a position read again before the CNC latched a new one.
#include "stage_rig.hpp"
#include "stages/stale.hpp"

#include <catch2/catch.hpp>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;

namespace {

struct StaleRig {
    StaleRig() { rig.feeder->begin(); }
    detail::Diagnostics diag{"log.csv"};
    StageRig rig{std::make_unique<detail::StaleRepeats>(diag), Flow::Sessions | Flow::Positions,
                 Flow::Sessions | Flow::Positions};
    // x values read every 6 ms, lines from 2.
    void read(const std::vector<double>& xs) {
        for (double x : xs) {
            rig.feeder->session_record(pos(0.006 * static_cast<double>(n_), x, 0, 0, 2 + n_));
            ++n_;
        }
    }
    std::vector<double> kept() const {
        std::vector<double> x;
        for (const Record& r : rig.out->positions()) x.push_back(r.v[0]);
        return x;
    }
    std::size_t n_ = 0;
};

}  // namespace

TEST_CASE("stale_repeats: a repeat while moving is dropped, the reading is held until the next decides",
          "[stale]") {
    StaleRig s;
    s.read({0.0, 0.4, 0.8, 0.8, 1.2});
    CHECK(s.kept() == std::vector<double>{0.0, 0.4, 0.8});   // the repeat gone, 1.2 still held
    s.rig.feeder->end();
    CHECK(s.kept() == std::vector<double>{0.0, 0.4, 0.8, 1.2});
    const IngestWarning w = warning_of(s.diag, "stale_repeat");
    CHECK(w.count == 1);
    CHECK_THAT(w.message, Catch::Contains("log.csv:5"));
    CHECK(dynamic_cast<detail::StaleRepeats*>(s.rig.under_test)->dropped() == 1);
}

TEST_CASE("stale_repeats: at standstill repeats are genuine and kept", "[stale]") {
    StaleRig s;
    s.read({1.0, 1.0, 1.0, 1.0, 1.0});
    s.rig.feeder->end();
    CHECK(s.kept().size() == 5);
    CHECK(s.diag.warnings().empty());
}

TEST_CASE("stale_repeats: a repeat at the start or end of a move counts as moving on one side", "[stale]") {
    StaleRig s;
    // Leaving standstill: 1.0 1.0 then moving; the second 1.0 repeats while the next differs.
    s.read({1.0, 1.0, 1.0, 1.5, 2.0, 2.0});
    s.rig.feeder->end();
    // The third 1.0 (next differs) and the last 2.0 (the pair before it moved) are stale.
    CHECK(s.kept() == std::vector<double>{1.0, 1.0, 1.5, 2.0});
    CHECK(warning_of(s.diag, "stale_repeat").count == 2);
}
