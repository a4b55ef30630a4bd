// app::optimize_feeds on the straight slot `cutload optimize` and the service's optimization jobs
// were tested on (tests/cli/test_program_cli.cpp, tests/server/test_program.cpp): the same
// expectations, progress to 1 and a cancel honoured while the search predicts.
#include "app_fixtures.hpp"

#include "app/optimize.hpp"

#include <algorithm>
#include <iterator>

using namespace cutload;
using namespace cutload::apptest;

namespace {

app::OptimizeInput slot_input(const std::filesystem::path& dir) {
    write_slot(dir);
    app::OptimizeInput in;
    in.log_path = (dir / "slot.csv").string();
    in.spec = force_model::load_run_spec((dir / "slot.json").string());
    in.program.path = (dir / "slot.nc").string();
    in.search.target = 0.8;
    in.search.max_feed_mm_min = 20000;
    return in;
}

}  // namespace

TEST_CASE("optimize_feeds: the slot's feeds load the tool to the target, only F words change", "[app][optimize]") {
    const Scratch dir("optimize");
    const app::OptimizeInput in = slot_input(dir);
    Recorder rec;
    const app::OptimizeResult r = app::optimize_feeds(in, rec.control());
    rec.require_monotonic();
    CHECK(rec.phases() == std::vector<app::Phase>{app::Phase::Ingest, app::Phase::Program, app::Phase::Mapping,
                                                  app::Phase::Optimize, app::Phase::Done});
    CHECK(rec.calls.back().second == 1.0);

    // The slot's log has no block column: its samples take the program's blocks by mapping.
    CHECK(r.program.mapped);
    CHECK(std::count(r.motion.block_names.begin(), r.motion.block_names.end(), "N20") == 1);
    CHECK(r.feeds.target_met);
    CHECK(r.feeds.max_ratio_after <= 0.8 + 1e-9);
    REQUIRE(r.feeds.blocks.size() == 2);
    for (const auto& b : r.feeds.blocks) {
        INFO(b.block);
        CHECK(b.binding == "force");
        CHECK(b.ratio_before < 0.6);
        CHECK(b.recommended_feed_mm_min > 1200);
        CHECK(b.ratio_after <= 0.8 + 1e-9);
        CHECK(b.ratio_after >= 0.8 * 0.95);
    }
    CHECK(r.changed_blocks == 2);

    // Token by token, every word but F is the program's.
    std::istringstream before(read_text(in.program.path)), after(r.program_text);
    std::string a, b;
    std::size_t f_changed = 0;
    while (std::getline(before, a)) {
        REQUIRE(std::getline(after, b));
        auto not_f = [](const std::string& t) { return t[0] != 'F'; };
        const auto ta = motion_io::nc_tokens(a), tb = motion_io::nc_tokens(b);
        std::vector<std::string> ka, kb;
        std::copy_if(ta.begin(), ta.end(), std::back_inserter(ka), not_f);
        std::copy_if(tb.begin(), tb.end(), std::back_inserter(kb), not_f);
        CHECK(ka == kb);
        if (ta != tb) ++f_changed;
    }
    CHECK_FALSE(std::getline(after, b));
    CHECK(f_changed >= 1);
}

TEST_CASE("optimize_feeds: a cancel while the search predicts stops it", "[app][optimize][cancel]") {
    const Scratch dir("optimize_cancel");
    Recorder rec;
    rec.cancel_at = app::Phase::Optimize;
    CHECK_THROWS_AS(app::optimize_feeds(slot_input(dir), rec.control()), force_model::Cancelled);
    CHECK(rec.phases().back() == app::Phase::Optimize);
    CHECK(*rec.reached(app::Phase::Optimize) == *rec.started(app::Phase::Optimize));
}

TEST_CASE("optimize_feeds: a spec without limits and a program the log does not run are refused", "[app][optimize]") {
    const Scratch dir("optimize_refused");
    app::OptimizeInput in = slot_input(dir);
    in.spec.limits = force_model::Limits{};
    CHECK_THROWS_AS(app::optimize_feeds(in), force_model::SpecError);

    in = slot_input(dir);
    write_text(dir / "far.nc", "%\nN10 G90 G00 Y300.\nN20 G01 X504. F1200 S10000 M03\n%\n");
    in.program.path = (dir / "far.nc").string();
    CHECK_THROWS_WITH(app::optimize_feeds(in), Catch::Contains("far.nc: only") && Catch::Contains("not this log's program"));
}
