// Stage "validate": nothing non-finite and nothing beyond what a machine can report passes.
#include "stage_rig.hpp"
#include "stages/validate.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <limits>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;

namespace {

struct ValidateRig {
    detail::Diagnostics diag{"log.csv"};
    StageRig rig{std::make_unique<detail::Validate>(diag), static_cast<Flows>(Flow::Readings),
                 static_cast<Flows>(Flow::Checked)};
    void push(const Record& r) { rig.chain.push(r); }
};

}  // namespace

TEST_CASE("validate: readings inside the physical ranges pass unchanged, in order", "[validate]") {
    ValidateRig v;
    v.push(pos(0.0, 9999999, -9999999, 0, 2));              // 10 km less a mm: far, but a wrong unit explains it
    v.push(value(Chan::Spindle, 0.0, -5999999, 2));         // rpm read as rev/s on a fast spindle
    v.push(value(Chan::Feed, 0.0, 1.19e7, 2));              // mm/min read as mm/s on a fast rapid
    v.push(value(Chan::AxisX, 0.1, 500, 3));
    v.push(block(0.1, 7, 3));
    REQUIRE(v.rig.out->records.size() == 5);
    CHECK(v.rig.out->records[0].v[1] == -9999999);
    CHECK(v.rig.out->records[4].block == 7);
    CHECK(v.diag.warnings().empty());
}

TEST_CASE("validate: a value beyond its physical range is dropped, naming line, channel and value", "[validate]") {
    ValidateRig v;
    v.push(value(Chan::Spindle, 0.0, 10000, 2));
    v.push(value(Chan::Spindle, 0.006, 1e10, 3));
    v.push(value(Chan::Spindle, 0.012, 1e9, 4));
    v.push(pos(0.012, 1, 2, 1e308, 4));
    v.push(value(Chan::Feed, 0.018, -2e7, 5));
    v.push(value(Chan::AxisY, 0.018, 2e7, 5));
    v.push(value(Chan::Spindle, 0.018, 10000, 5));
    REQUIRE(v.rig.out->records.size() == 2);
    CHECK(v.rig.out->records[1].line == 5);
    const IngestWarning w = warning_of(v.diag, "glitch_dropped");
    CHECK(w.count == 5);
    CHECK_THAT(w.message, Catch::Contains("log.csv:3") && Catch::Contains("spindle 1e+10 rpm") &&
                              Catch::Contains("glitch, dropped"));
    CHECK(dynamic_cast<detail::Validate*>(v.rig.under_test)->dropped() == 5);
}

TEST_CASE("validate: NaN and infinity never pass, in a value or a time stamp", "[validate]") {
    ValidateRig v;
    const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
    v.push(pos(0.0, nan, 0, 0, 2));
    v.push(pos(0.0, 0, -inf, 0, 3));
    v.push(value(Chan::Spindle, inf, 100, 4));
    v.push(value(Chan::Feed, 0.0, nan, 5));
    v.push(block(nan, 1, 6));
    v.push(pos(0.006, 1, 1, 1, 7));
    REQUIRE(v.rig.out->records.size() == 1);
    CHECK(v.rig.out->records[0].line == 7);
    const IngestWarning w = warning_of(v.diag, "glitch_dropped");
    CHECK(w.count == 5);
    CHECK_THAT(w.message, Catch::Contains("log.csv:2") && Catch::Contains("position (nan, 0, 0)"));
}

TEST_CASE("validate: the limits are tunable", "[validate]") {
    detail::Diagnostics diag{"log.csv"};
    detail::PhysicalLimits limits;
    limits.max_abs_spindle_rpm = 50000;
    StageRig rig{std::make_unique<detail::Validate>(diag, limits), static_cast<Flows>(Flow::Readings),
                 static_cast<Flows>(Flow::Checked)};
    rig.chain.push(value(Chan::Spindle, 0, 49999, 2));
    rig.chain.push(value(Chan::Spindle, 0, 50001, 3));
    CHECK(rig.out->records.size() == 1);
    CHECK_THAT(warning_of(diag, "glitch_dropped").message, Catch::Contains("beyond +-50000 rpm"));
}

TEST_CASE("validate: a spindle spike beyond the plausible speed is dropped, a ramp or a held level is kept", "[validate]") {
    SECTION("a jump from cutting speed to 5e6 rpm and back: a glitch (issue 19)") {
        ValidateRig v;
        v.push(value(Chan::Spindle, 0.000, 10000, 2));
        v.push(value(Chan::Spindle, 0.006, 5e6, 3));
        v.push(value(Chan::Spindle, 0.012, -5e6, 4));
        v.push(value(Chan::Spindle, 0.018, 10002, 5));
        REQUIRE(v.rig.out->records.size() == 2);
        CHECK(v.rig.out->records[1].line == 5);
        const IngestWarning w = warning_of(v.diag, "glitch_dropped");
        CHECK(w.count == 2);
        CHECK_THAT(w.message, Catch::Contains("log.csv:3") && Catch::Contains("spindle 5e+06 rpm, a jump from 10000 rpm"));
        // The tooth period the sampling check judges by comes from what passed.
        CHECK(v.diag.facts().spindle_max_abs_rpm == 10002);
    }
    SECTION("a ramp past the plausible speed (a unit mix-up) moves in steps a spindle can take: kept") {
        ValidateRig v;
        for (const double rpm : {0.0, 30000.0, 60000.0, 95000.0, 140000.0, 600000.0})
            v.push(value(Chan::Spindle, rpm / 1e7, rpm, 2));
        CHECK(v.rig.out->records.size() == 6);
        CHECK(v.diag.warnings().empty());
        CHECK(v.diag.facts().spindle_max_abs_rpm == 600000);
    }
    SECTION("a level held longer than a spike is the channel's own, after max_spike_readings readings") {
        ValidateRig v;
        v.push(value(Chan::Spindle, 0, 0, 2));
        const std::size_t held = detail::PhysicalLimits{}.max_spike_readings + 8;
        for (std::size_t i = 0; i < held; ++i) v.push(value(Chan::Spindle, 0.006 * double(i + 1), 600000, 3 + i));
        CHECK(v.rig.out->records.size() == 1 + 8);
        CHECK(warning_of(v.diag, "glitch_dropped").count == detail::PhysicalLimits{}.max_spike_readings);
    }
    SECTION("a spike never touches another channel") {
        ValidateRig v;
        v.push(value(Chan::Spindle, 0, 8000, 2));
        v.push(value(Chan::Feed, 0, 5e5, 2));   // beyond the plausible feed, within the physical one
        v.push(pos(0, 2e5, 0, 0, 2));
        CHECK(v.rig.out->records.size() == 3);
    }
}
