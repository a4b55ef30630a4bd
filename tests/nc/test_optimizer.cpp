// Feed recommendations: the re-prediction lands every cutting block at the target fraction of its
// binding limit without exceeding any limit, and the written program differs only in F words.
#include "corner_fixture.hpp"

#include "force_model/feed_optimizer.hpp"

#include <catch2/catch.hpp>

using namespace cutload;
using namespace cutload::nctest;

namespace {

// Token streams of two programs with F words removed, line by line.
std::vector<std::vector<std::string>> non_feed_tokens(const std::string& text) {
    std::vector<std::vector<std::string>> out;
    std::istringstream in(text);
    for (std::string line; std::getline(in, line);) {
        std::vector<std::string> t = motion_io::nc_tokens(line);
        t.erase(std::remove_if(t.begin(), t.end(), [](const std::string& w) { return w[0] == 'F' || w[0] == 'f'; }), t.end());
        out.push_back(t);
    }
    return out;
}

double load_ratio(const force_model::BlockSummary& b, const force_model::Limits& l) {
    double r = 0;
    if (l.force_N > 0) r = std::max(r, b.peak_force_N / l.force_N);
    if (l.torque_Nm > 0) r = std::max(r, b.peak_torque_Nm / l.torque_Nm);
    if (l.power_kW > 0) r = std::max(r, b.peak_power_kW / l.power_kW);
    if (l.chip_mm > 0) r = std::max(r, b.max_chip_mm / l.chip_mm);
    if (l.bending_MPa > 0) r = std::max(r, b.max_bending_MPa / l.bending_MPa);
    return r;
}

}  // namespace

TEST_CASE("optimizer: feeds meet the target without exceeding a limit, only F words change", "[optimizer]") {
    CornerCase c = corner_case();
    // Force limit: the straight finishing cut (N20) runs at 90 % of it, so N20 slows down a
    // little and the corner blocks, loaded more, slow down further. Chip and torque limits are
    // checked too.
    const force_model::Prediction base = force_model::predict(c.actual, c.spec, predict_options(c));
    const auto n20 = std::find_if(base.blocks.begin(), base.blocks.end(), [](const auto& b) { return b.block == "N20"; });
    REQUIRE(n20 != base.blocks.end());
    c.spec.limits.force_N = n20->peak_force_N / 0.9;
    c.spec.limits.chip_mm = 0.5;
    c.spec.limits.torque_Nm = 5;
    force_model::FeedOptimizerOptions o;
    o.target = 0.8;
    o.commanded.step_s = c.actual.step_s;
    o.commanded.rapid_mm_min = c.dry_run.machine.rapid_mm_min;
    o.max_feed_mm_min = 12000;
    const force_model::FeedOptimization r = force_model::optimize_feeds(c.program, c.actual, c.spec, predict_options(c), o);

    REQUIRE(!r.blocks.empty());
    for (const auto& b : r.blocks)
        WARN(fmt::format("{}: F{:.0f} -> F{:.0f}, binding {}, load {:.1f}% -> {:.1f}% of the limit{}", b.block,
                         b.programmed_feed_mm_min, b.recommended_feed_mm_min, b.binding, 100 * b.ratio_before,
                         100 * b.ratio_after, b.at_feed_limit ? " (at the feed range)" : ""));
    WARN(fmt::format("{} predictions; highest load after {:.2f}% of its limit", r.predictions, 100 * r.max_ratio_after));
    CHECK(r.target_met);
    CHECK(r.predictions <= o.max_predictions);
    for (const auto& b : r.blocks) {
        CHECK(b.ratio_after <= o.target + 1e-9);
        if (!b.at_feed_limit) CHECK(b.ratio_after >= o.target * (1 - o.tolerance));
    }
    // No limit exceeded anywhere in the re-prediction, and it is the prediction at the new feeds.
    for (const auto& b : r.after.blocks) CHECK(load_ratio(b, c.spec.limits) <= o.target + 1e-9);
    CHECK(r.after.stats.simulated_s != r.before.stats.simulated_s);
    const bool some_changed = std::any_of(r.blocks.begin(), r.blocks.end(),
                                          [](const auto& b) { return b.recommended_feed_mm_min != b.programmed_feed_mm_min; });
    CHECK(some_changed);

    // The written program: every non-F word byte-identical, and its F words are the recommendation.
    std::string original;
    for (const auto& l : c.program.lines) original += l + "\n";
    const std::string rewritten = motion_io::rewrite_feeds(c.program, r.feed_mm_min);
    CHECK(non_feed_tokens(rewritten) == non_feed_tokens(original));
    CHECK(rewritten != original);
    motion_io::NcReadOptions ro;
    ro.work_offsets_mm["G54"] = {100, 100, 100};
    ro.start_mm = std::array<double, 3>{c.dry_run.start_mm[0], c.dry_run.start_mm[1], c.dry_run.start_mm[2]};
    const motion_io::NcProgram again = motion_io::parse_nc_program(rewritten, "opt.nc", ro);
    REQUIRE(again.blocks.size() == c.program.blocks.size());
    for (std::size_t i = 0; i < again.blocks.size(); ++i)
        if (r.feed_mm_min[i] > 0) CHECK(again.blocks[i].feed_mm_min == r.feed_mm_min[i]);
}

TEST_CASE("optimizer: rewriting feeds inserts and restores modal F words, packed or spaced", "[optimizer]") {
    motion_io::NcReadOptions ro;
    ro.work_offsets_mm["G54"] = {0, 0, 0};
    ro.start_mm = std::array<double, 3>{0, 0, 0};
    const std::string text = "N1 G01 X10. F600 (FIRST)\nN2 Y10.\nN3 X0.\nN4G01X0Y0F900\r\nN5 G00 Z5.\nN6 G01 Z0";
    const motion_io::NcProgram p = motion_io::parse_nc_program(text, "m.nc", ro);
    std::vector<double> feeds(p.blocks.size(), 0.0);
    feeds[1] = 300;   // N2 slower; N3 keeps its programmed 600
    feeds[3] = 1200;  // N4's own F word changes
    const std::string out = motion_io::rewrite_feeds(p, feeds);
    CHECK(out == "N1 G01 X10. F600 (FIRST)\nN2 Y10. F300\nN3 X0. F600\nN4G01X0Y0F1200\r\nN5 G00 Z5.\nN6 G01 Z0 F900");
    const motion_io::NcProgram q = motion_io::parse_nc_program(out, "m2.nc", ro);
    CHECK(q.blocks[2].feed_mm_min == 600);
    CHECK(q.blocks[5].feed_mm_min == 900);   // N6 keeps the feed it inherited from N4
}

TEST_CASE("optimizer: with a tool table, a block is held to its tool's own limits", "[optimizer][tools]") {
    CornerCase c = corner_case();
    const force_model::Prediction base = force_model::predict(c.actual, c.spec, predict_options(c));
    const auto n20 = std::find_if(base.blocks.begin(), base.blocks.end(), [](const auto& b) { return b.block == "N20"; });
    REQUIRE(n20 != base.blocks.end());
    // The program runs T5 throughout (as after a T5 M06), the log names it; the run's own limits
    // check nothing, T5's force limit puts the straight cut at 90 % of it.
    for (auto& b : c.program.blocks) b.tool = 5;
    c.actual.tool.assign(c.actual.size(), 5);
    force_model::RunSpec spec = c.spec;
    spec.limits = force_model::Limits{};
    force_model::NumberedTool t5{5, c.spec.tool, {}};
    t5.limits.force_N = n20->peak_force_N / 0.9;
    spec.tools = {t5};
    force_model::FeedOptimizerOptions o;
    o.target = 0.8;
    o.commanded.step_s = c.actual.step_s;
    o.commanded.rapid_mm_min = c.dry_run.machine.rapid_mm_min;
    o.max_feed_mm_min = 12000;
    const force_model::FeedOptimization r = force_model::optimize_feeds(c.program, c.actual, spec, predict_options(c), o);
    REQUIRE(!r.blocks.empty());
    CHECK(r.target_met);
    const force_model::Limits t5_limits = force_model::limits_for(spec.limits, t5.limits);
    for (const auto& b : r.blocks) {
        INFO(b.block << ": " << b.ratio_before << " -> " << b.ratio_after << " of T5's limits");
        CHECK(b.binding == "force");
        CHECK(b.ratio_after <= o.target + 1e-9);
        if (!b.at_feed_limit) CHECK(b.ratio_after >= o.target * (1 - o.tolerance));
    }
    for (const auto& b : r.after.blocks) {
        CHECK(load_ratio(b, t5_limits) <= o.target + 1e-9);
        if (b.peak_force_N > 0) CHECK(b.tool == 5);
    }
    // The run's own limits (none) would have left nothing to optimise.
    CHECK_THROWS_AS(force_model::optimize_feeds(c.program, c.actual, [&] {
                        force_model::RunSpec none = spec;
                        none.tools[0].limits = {};
                        return none;
                    }(), predict_options(c), o),
                    force_model::SpecError);
}
