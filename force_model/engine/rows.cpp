#include "engine/rows.hpp"
#include "engine/derived.hpp"
#include "engine/motion_walk.hpp"

#include <array>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>

namespace cutload::force_model {

namespace {

// A float or double is NaN or infinite exactly when its exponent bits are all ones.
// check_finite_rows tests a row's first kTestedWords 32-bit words, from t_s to removed_mm3 (no
// padding among them): per word the exponent mask to test and the value meaning "all ones" (for a
// double, its high word; a word not tested wants a value its zero mask cannot give).
constexpr std::size_t kTestedWords = offsetof(ForceSample, removed_mm3) / sizeof(std::uint32_t) + 1;
static_assert(offsetof(ForceSample, t_s) == 0 && offsetof(ForceSample, removed_mm3) % sizeof(std::uint32_t) == 0);
static_assert(std::endian::native == std::endian::little, "a double's exponent is in its high (second) word");
// The words before fx_N are t_s, spindle_angle_deg, block and tool; the ten floats from fx_N to
// removed_mm3 lie side by side: nothing in between is padding.
static_assert(offsetof(ForceSample, spindle_angle_deg) == 8 && offsetof(ForceSample, block) == 16 &&
              offsetof(ForceSample, tool) == 20 && offsetof(ForceSample, fx_N) == 24);
static_assert(offsetof(ForceSample, removed_mm3) - offsetof(ForceSample, fx_N) == 9 * sizeof(float));
struct RowWordTest {
    std::array<std::uint32_t, kTestedWords> mask{}, all_ones{};
    constexpr RowWordTest() {
        for (std::size_t k = 0; k < kTestedWords; ++k) all_ones[k] = 1;
        const auto test_double = [&](std::size_t offset) {
            mask[offset / 4 + 1] = all_ones[offset / 4 + 1] = 0x7ff00000u;
        };
        const auto test_float = [&](std::size_t offset) { mask[offset / 4] = all_ones[offset / 4] = 0x7f800000u; };
        test_double(offsetof(ForceSample, t_s));
        test_double(offsetof(ForceSample, spindle_angle_deg));
        for (std::size_t o = offsetof(ForceSample, fx_N); o <= offsetof(ForceSample, removed_mm3); o += 4) test_float(o);
    }
};

}  // namespace

void check_finite_rows(std::span<const ForceSample> rows) {
    // Flags OR-ed per word, not values summed, and whole rows of words with a mask each: the
    // compiler tests several words at a time with no dependent chain through the rows (summing
    // `v - v` cost 4 % of bench_force's CPU time, testing field by field 3 %). The rows are searched
    // only when a flag is set, for the message.
    static constexpr RowWordTest test;
    std::array<std::uint32_t, kTestedWords> flags{};
    const auto* bytes = reinterpret_cast<const unsigned char*>(rows.data());
    for (std::size_t i = 0; i < rows.size(); ++i) {
        const unsigned char* row = bytes + i * sizeof(ForceSample);
        for (std::size_t k = 0; k < kTestedWords; ++k) {
            std::uint32_t word;
            std::memcpy(&word, row + k * sizeof word, sizeof word);
            flags[k] |= std::uint32_t((word & test.mask[k]) == test.all_ones[k]);
        }
    }
    std::uint32_t any_bad = 0;
    for (const std::uint32_t f : flags) any_bad |= f;
    if (any_bad == 0) return;
    for (const ForceSample& s : rows)
        for (const double v : {s.t_s, s.spindle_angle_deg, double(s.fx_N), double(s.fy_N), double(s.fz_N),
                               double(s.torque_Nm), double(s.power_kW), double(s.chip_mm), double(s.bending_MPa),
                               double(s.radial_engagement_mm), double(s.axial_engagement_mm), double(s.removed_mm3)})
            if (!std::isfinite(v))
                throw std::runtime_error("predict: the engine computed a non-finite value at t = " +
                                         std::to_string(s.t_s) + " s; nothing is written");
}

void RowTable::use_tool(std::int32_t slot, std::int32_t number, double shank_diameter_mm) {
    slot_ = slot;
    number_ = number;
    section_modulus_mm3_ = shank_section_modulus_mm3(shank_diameter_mm);
}

void RowTable::reserve(std::size_t rows) {
    samples.reserve(rows);
    extra.reserve(rows);
}

void RowTable::append_steps(const std::vector<StepMeta>& meta, const std::vector<kernels::StepResult>& results,
                            double removed_mm3) {
    // Each row is pushed as one whole prvalue, which the compiler builds in registers and stores
    // once. Rows built field by field on the stack and copied, or resized (zeroed) and then
    // filled, took two to three times as long: the rows are a large share of what a prediction
    // writes. The removed volume goes in with them rather than in a second pass over the rows.
    if (meta.empty()) {
        attribute_removed(removed_mm3);
        return;
    }
    const float removed_share_mm3 = float(removed_mm3 / double(meta.size()));
    for (std::size_t k = 0; k < meta.size(); ++k) {
        const kernels::StepResult& r = results[k];
        const StepMeta& step = meta[k];
        const float torque_Nm = r.torque_Nmm / 1000;
        samples.push_back(ForceSample{.t_s = step.t_s,
                                      .spindle_angle_deg = step.angle_deg,
                                      .block = step.block,
                                      .tool = number_,
                                      .fx_N = r.fx_N,
                                      .fy_N = r.fy_N,
                                      .fz_N = r.fz_N,
                                      .torque_Nm = torque_Nm,
                                      .power_kW = spindle_power_kW(torque_Nm, step.rpm),
                                      .chip_mm = r.chip_mm,
                                      .bending_MPa = bending_stress_MPa(r.mx_Nmm, r.my_Nmm, section_modulus_mm3_),
                                      .radial_engagement_mm = r.q_max_mm - r.q_min_mm,
                                      .axial_engagement_mm = r.z_max_mm - r.z_min_mm,
                                      .removed_mm3 = removed_share_mm3});
        extra.push_back(RowExtra{.slot = slot_,
                                 .feed_mm_min = float(step.feed_mm_min),
                                 .engaged = r.engaged,
                                 .spindle_rpm = float(step.rpm)});
    }
}

namespace {

void append_sample(RowTable& rows, const motion_io::MotionModel& m, std::size_t i, std::int32_t slot, std::int32_t number,
                   bool stopped_in_material) {
    ForceSample s;
    s.t_s = m.t_s[i];
    s.spindle_angle_deg = m.spindle_angle_deg[i];
    s.block = m.block[i];
    s.tool = number;
    rows.samples.push_back(s);
    RowExtra x;
    x.slot = slot;
    x.feed_mm_min = float(speed_mm_s(m, i) * 60);
    x.stopped_in_material = stopped_in_material;
    x.spindle_rpm = float(m.spindle_rpm[i]);
    rows.extra.push_back(x);
}

}  // namespace

void RowTable::append_motion_sample(const motion_io::MotionModel& m, std::size_t i, bool stopped_in_material) {
    append_sample(*this, m, i, slot_, number_, stopped_in_material);
}

void RowTable::append_unknown_tool(const motion_io::MotionModel& m, std::size_t i, std::int32_t number) {
    append_sample(*this, m, i, -1, number, false);
}

void RowTable::attribute_removed(double removed_mm3) {
    if (!samples.empty()) samples.back().removed_mm3 += float(removed_mm3);
}

}  // namespace cutload::force_model
