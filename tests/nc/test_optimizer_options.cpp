// Feed optimizer options a shop asks for: change only the flagged blocks, never raise a feed,
// round changed feeds to a step, and say which flags each change clears. Checked against a
// prediction made apart from the optimizer (the flags at the programmed feeds) and against the
// optimizer's own re-prediction at the feeds it recommends.
#include "corner_fixture.hpp"

#include "force_model/feed_optimizer.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <map>
#include <set>

using namespace cutload;
using namespace cutload::nctest;

namespace {

std::vector<std::string> flag_set(const force_model::BlockSummary& b) {
    std::set<std::string> s;
    for (const auto& f : b.flags) s.insert(f.flag);
    return {s.begin(), s.end()};
}

std::map<std::string, const force_model::BlockSummary*> by_name(const force_model::Prediction& p) {
    std::map<std::string, const force_model::BlockSummary*> m;
    for (const auto& b : p.blocks) m.try_emplace(b.block, &b);
    return m;
}

force_model::FeedOptimizerOptions options_for(const CornerCase& c) {
    force_model::FeedOptimizerOptions o;
    o.target = 0.8;
    o.commanded.step_s = c.actual.step_s;
    o.commanded.rapid_mm_min = c.dry_run.machine.rapid_mm_min;
    o.max_feed_mm_min = 12000;
    return o;
}

}  // namespace

TEST_CASE("optimizer options: only flagged blocks slow down, to a 50 mm/min step, clearing their flags", "[optimizer]") {
    CornerCase c = corner_case();
    const force_model::Prediction base = force_model::predict(c.actual, c.spec, predict_options(c));
    const auto blocks = by_name(base);
    REQUIRE(blocks.count("N20") == 1);
    // N20 (the straight cut) at 90 % of the force limit: over the target, but not flagged; the
    // corner blocks load the tool more and go over the limit.
    c.spec.limits.force_N = blocks.at("N20")->peak_force_N / 0.9;
    const force_model::Prediction flagged = force_model::predict(c.actual, c.spec, predict_options(c));
    const auto flagged_blocks = by_name(flagged);
    REQUIRE(flag_set(*flagged_blocks.at("N20")).empty());
    REQUIRE(flag_set(*flagged_blocks.at("N30")) == std::vector<std::string>{"force_limit"});

    force_model::FeedOptimizerOptions o = options_for(c);
    o.only_flagged = true;
    o.never_raise = true;
    o.feed_step_mm_min = 50;
    const force_model::FeedOptimization r = force_model::optimize_feeds(c.program, c.actual, c.spec, predict_options(c), o);
    const auto after = by_name(r.after);

    REQUIRE(r.blocks.size() == 3);
    int changed = 0;
    for (const auto& b : r.blocks) {
        INFO(b.block << ": F" << b.programmed_feed_mm_min << " -> F" << b.recommended_feed_mm_min << ", load "
                     << b.ratio_before << " -> " << b.ratio_after);
        // The flags reported are the engine's at the programmed and at the recommended feeds.
        REQUIRE(b.flags_before == flag_set(*flagged_blocks.at(b.block)));
        REQUIRE(b.flags_after == flag_set(*after.at(b.block)));
        REQUIRE(b.recommended_feed_mm_min <= b.programmed_feed_mm_min);
        if (b.flags_before.empty()) {
            REQUIRE(b.recommended_feed_mm_min == b.programmed_feed_mm_min);
            continue;
        }
        ++changed;
        REQUIRE(b.recommended_feed_mm_min < b.programmed_feed_mm_min);
        REQUIRE(std::fmod(b.recommended_feed_mm_min, 50.0) == 0.0);
        REQUIRE(b.ratio_after <= o.target + 1e-9);
        // Brought under the target, so under the limit: the force flag is gone.
        REQUIRE(b.flags_after.empty());
    }
    REQUIRE(changed >= 1);
    // N20 keeps its feed, so its load stays about where it was (its neighbours' feeds move a
    // little of what it meets): over the target, and the result says so.
    CHECK(after.at("N20")->peak_force_N / c.spec.limits.force_N == Approx(0.9).epsilon(0.05));
    CHECK_FALSE(r.target_met);
}

TEST_CASE("optimizer options: never raising leaves a program under its target as it is", "[optimizer]") {
    CornerCase c = corner_case();
    const force_model::Prediction base = force_model::predict(c.actual, c.spec, predict_options(c));
    double peak = 0;
    for (const auto& b : base.blocks) peak = std::max(peak, b.peak_force_N);
    c.spec.limits.force_N = 3 * peak;   // every block at a third of its limit
    force_model::FeedOptimizerOptions o = options_for(c);
    o.never_raise = true;
    const force_model::FeedOptimization r = force_model::optimize_feeds(c.program, c.actual, c.spec, predict_options(c), o);
    REQUIRE(r.blocks.size() == 3);
    for (const auto& b : r.blocks) {
        INFO(b.block);
        REQUIRE(b.recommended_feed_mm_min == b.programmed_feed_mm_min);
        REQUIRE(b.ratio_after == Approx(b.ratio_before).epsilon(1e-6));
    }
    CHECK(r.target_met);
    // Without the option the same program is sped up towards the target.
    o.never_raise = false;
    const force_model::FeedOptimization raised = force_model::optimize_feeds(c.program, c.actual, c.spec, predict_options(c), o);
    CHECK(std::any_of(raised.blocks.begin(), raised.blocks.end(),
                      [](const auto& b) { return b.recommended_feed_mm_min > b.programmed_feed_mm_min; }));
}

TEST_CASE("optimizer options: a block that no feed clears stops at the minimum raised to the step", "[optimizer]") {
    CornerCase c = corner_case();
    const force_model::Prediction base = force_model::predict(c.actual, c.spec, predict_options(c));
    double peak = 0;
    for (const auto& b : base.blocks) peak = std::max(peak, b.peak_force_N);
    // Far below what any feed gives (the edge forces alone exceed it): every cutting block falls to
    // the lowest feed the options allow.
    c.spec.limits.force_N = 0.02 * peak;
    force_model::FeedOptimizerOptions o = options_for(c);
    o.min_feed_mm_min = 10;
    o.feed_step_mm_min = 50;
    const force_model::FeedOptimization r = force_model::optimize_feeds(c.program, c.actual, c.spec, predict_options(c), o);
    REQUIRE_FALSE(r.blocks.empty());
    int at_limit = 0;
    for (const auto& b : r.blocks) {
        INFO(b.block << ": F" << b.programmed_feed_mm_min << " -> F" << b.recommended_feed_mm_min);
        if (b.recommended_feed_mm_min == b.programmed_feed_mm_min) continue;
        // 10 mm/min is not on a 50 mm/min step: the floor is 50.
        REQUIRE(b.recommended_feed_mm_min >= 50);
        REQUIRE(std::fmod(b.recommended_feed_mm_min, 50.0) == 0.0);
        if (b.at_feed_limit) {
            ++at_limit;
            REQUIRE(b.recommended_feed_mm_min == 50);
        }
    }
    REQUIRE(at_limit >= 1);
    CHECK_FALSE(r.target_met);
}
