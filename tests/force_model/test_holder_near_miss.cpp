// Holder near misses (document 004's clearance shell, limits.holder_clearance_mm) for a vertical
// tool: a holder whose face passes 1 mm over the stock's flat top has a clearance of exactly that
// (docs/five_axis.md, test H1), the flag carries the block's smallest clearance, and the check
// changes nothing else: the forces are the same with it off, and on every device.
#include "engine_fixtures.hpp"

#include <nlohmann/json.hpp>

using namespace cutload;
using namespace cutload::enginetest;

namespace {

// A full-depth slot along X through the 40 x 20 x 10 stock: tip at z 5, flutes 5 mm long (the top
// at z 10 is level with their top: no shank contact), holder face at z 5 + stickout.
force_model::Prediction slot_under_holder(double stickout_mm, double clearance_mm, force_model::Device d,
                                          double tip_z_mm = 5) {
    auto spec = base_spec();
    spec.tool.flute_length_mm = 5;
    spec.tool.stickout_mm = stickout_mm;
    spec.tool.holder = {20, 40};
    spec.limits.holder_clearance_mm = clearance_mm;
    const auto m = legs_motion({-10, 10, tip_z_mm}, {{{50, 10, tip_z_mm}, 3000, "N10"}});
    return run_on(m, spec, d);
}

const force_model::FlagHit* flag(const force_model::Prediction& p, const std::string& name) {
    for (const auto& b : p.blocks)
        for (const auto& f : b.flags)
            if (f.flag == name) return &f;
    return nullptr;
}

}  // namespace

TEST_CASE("a holder passing 1 mm over a flat top is a near miss of exactly 1 mm", "[engine][holder]") {
    std::vector<force_model::Device> devices{force_model::Device::Cpu};
    if (opencl_available()) devices.push_back(force_model::Device::OpenCL);
    for (const auto d : devices) {
        INFO((d == force_model::Device::Cpu ? "cpu" : "opencl"));
        const auto p = slot_under_holder(6, 2, d);   // face at z 11, the top at z 10
        const force_model::FlagHit* near = flag(p, "holder_near_miss");
        REQUIRE(near != nullptr);
        CHECK(near->value == Approx(1.0).margin(1e-6));
        CHECK(near->t_s > 0);
        CHECK(flag(p, "holder_contact") == nullptr);

        // A shell thinner than the gap, or none: no flag, and the same forces row for row.
        const auto thin = slot_under_holder(6, 0.5, d);
        const auto off = slot_under_holder(6, 0, d);
        CHECK(flag(thin, "holder_near_miss") == nullptr);
        CHECK(flag(off, "holder_near_miss") == nullptr);
        REQUIRE(off.samples.size() == p.samples.size());
        std::size_t differ = 0;
        for (std::size_t i = 0; i < p.samples.size(); ++i)
            differ += p.samples[i].fx_N != off.samples[i].fx_N || p.samples[i].fy_N != off.samples[i].fy_N ||
                      p.samples[i].holder_contact != off.samples[i].holder_contact;
        CHECK(differ == 0);
    }
}

TEST_CASE("a holder far above the stock never flags, a holder in it is contact, not a near miss", "[engine][holder]") {
    const auto far = slot_under_holder(30, 2, force_model::Device::Cpu);   // face 25 mm over the top
    CHECK(flag(far, "holder_near_miss") == nullptr);
    CHECK(flag(far, "holder_contact") == nullptr);
    const auto in = slot_under_holder(5.2, 2, force_model::Device::Cpu, 4.5);   // face at 9.7, under the top
    CHECK(flag(in, "holder_contact") != nullptr);
    CHECK(flag(in, "holder_near_miss") == nullptr);
}

TEST_CASE("the clearance shell is read, bounded and written back by the run spec", "[engine][holder][spec]") {
    auto j = force_model::to_json(base_spec());
    CHECK_FALSE(j["limits"].contains("holder_clearance_mm"));   // 0, the default, is not written
    j["limits"]["holder_clearance_mm"] = 2.5;
    const auto s = force_model::parse_run_spec(j);
    CHECK(s.limits.holder_clearance_mm == 2.5);
    CHECK(force_model::to_json(s)["limits"]["holder_clearance_mm"] == 2.5);
    j["limits"]["holder_clearance_mm"] = -1;
    CHECK_THROWS_WITH(force_model::parse_run_spec(j), Catch::Contains("limits.holder_clearance_mm"));
    j["limits"]["holder_clearance_mm"] = 80;
    CHECK_THROWS_WITH(force_model::parse_run_spec(j), Catch::Contains("must be <= 50 mm"));
}
