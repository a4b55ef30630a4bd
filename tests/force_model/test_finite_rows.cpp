// check_finite_rows tests a row's fields through a mask per 32-bit word (engine/rows.cpp): every
// field it promises to test, in every position of a span, refuses NaN and both infinities; the
// fields it leaves alone, the largest and smallest finite values and zeros of either sign pass.
#include "engine/rows.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

using cutload::force_model::check_finite_rows;
using cutload::force_model::ForceSample;

namespace {

struct Field {
    std::string name;
    std::function<void(ForceSample&, double)> set;
};

std::vector<Field> tested_fields() {
    return {
        {"t_s", [](ForceSample& s, double v) { s.t_s = v; }},
        {"spindle_angle_deg", [](ForceSample& s, double v) { s.spindle_angle_deg = v; }},
        {"fx_N", [](ForceSample& s, double v) { s.fx_N = float(v); }},
        {"fy_N", [](ForceSample& s, double v) { s.fy_N = float(v); }},
        {"fz_N", [](ForceSample& s, double v) { s.fz_N = float(v); }},
        {"torque_Nm", [](ForceSample& s, double v) { s.torque_Nm = float(v); }},
        {"power_kW", [](ForceSample& s, double v) { s.power_kW = float(v); }},
        {"chip_mm", [](ForceSample& s, double v) { s.chip_mm = float(v); }},
        {"bending_MPa", [](ForceSample& s, double v) { s.bending_MPa = float(v); }},
        {"radial_engagement_mm", [](ForceSample& s, double v) { s.radial_engagement_mm = float(v); }},
        {"axial_engagement_mm", [](ForceSample& s, double v) { s.axial_engagement_mm = float(v); }},
        {"removed_mm3", [](ForceSample& s, double v) { s.removed_mm3 = float(v); }},
    };
}

// Rows with ordinary values, each different.
std::vector<ForceSample> rows(std::size_t n) {
    std::vector<ForceSample> r(n);
    for (std::size_t i = 0; i < n; ++i) {
        ForceSample& s = r[i];
        s.t_s = 0.001 * double(i);
        s.spindle_angle_deg = 2.0 * double(i);
        s.block = std::int32_t(i % 7);
        s.tool = 3;
        s.fx_N = float(i) - 120.5f;
        s.fy_N = -float(i) * 0.25f;
        s.fz_N = 17.0f;
        s.torque_Nm = 1.5f;
        s.power_kW = 0.9f;
        s.chip_mm = 0.05f;
        s.bending_MPa = 40.0f;
        s.radial_engagement_mm = 1.0f;
        s.axial_engagement_mm = 3.0f;
        s.removed_mm3 = 0.01f;
    }
    return r;
}

}  // namespace

TEST_CASE("check_finite_rows: NaN and infinities in any tested field, at any row, are refused",
          "[engine][rows]") {
    const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
    const std::size_t n = 13;   // odd: the vectorised loop's tail is covered
    REQUIRE_NOTHROW(check_finite_rows(rows(n)));
    for (const Field& f : tested_fields())
        for (const double bad : {nan, inf, -inf})
            for (const std::size_t at : {std::size_t(0), std::size_t(6), n - 1}) {
                INFO(f.name << " = " << bad << " at row " << at);
                auto r = rows(n);
                f.set(r[at], bad);
                CHECK_THROWS_AS(check_finite_rows(r), std::runtime_error);
            }
}

TEST_CASE("check_finite_rows: finite extremes, zeros and the fields it does not test pass", "[engine][rows]") {
    for (const Field& f : tested_fields()) {
        const bool is_double = f.name == "t_s" || f.name == "spindle_angle_deg";
        const double big = is_double ? std::numeric_limits<double>::max() : double(std::numeric_limits<float>::max());
        const double tiny = is_double ? std::numeric_limits<double>::denorm_min()
                                      : double(std::numeric_limits<float>::denorm_min());
        for (const double ok : {big, -big, tiny, -tiny, 0.0, -0.0}) {
            INFO(f.name << " = " << ok);
            auto r = rows(5);
            f.set(r[2], ok);
            CHECK_NOTHROW(check_finite_rows(r));
        }
    }
    // Machine-axis forces and the tool axis are filled by the application after the engine's check.
    auto r = rows(5);
    r[1].fx_machine_N = std::numeric_limits<float>::quiet_NaN();
    r[1].tool_axis_z = std::numeric_limits<float>::infinity();
    r[3].block = -1;
    r[3].tool = std::int32_t(0x7ff00000);   // integer bits that would read as an exponent of all ones
    r[3].holder_contact = true;
    CHECK_NOTHROW(check_finite_rows(r));
    CHECK_NOTHROW(check_finite_rows({}));
}
