#include "engine/rows.hpp"
#include "engine/derived.hpp"
#include "engine/motion_walk.hpp"

namespace cutload::force_model {

void RowTable::use_tool(std::int32_t slot, std::int32_t number, double shank_diameter_mm) {
    slot_ = slot;
    number_ = number;
    section_modulus_mm3_ = shank_section_modulus_mm3(shank_diameter_mm);
}

void RowTable::reserve(std::size_t rows) {
    samples.reserve(rows);
    extra.reserve(rows);
}

void RowTable::append_steps(const std::vector<StepMeta>& meta, const std::vector<kernels::StepResult>& results) {
    // Each row is pushed as one whole prvalue, which the compiler builds in registers and stores
    // once. Rows built field by field on the stack and copied, or resized (zeroed) and then
    // filled, took two to three times as long: the rows are a large share of what a prediction
    // writes.
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
                                      .axial_engagement_mm = r.z_max_mm - r.z_min_mm});
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

void RowTable::attribute_removed(std::size_t first_row, std::size_t batch_rows, double removed_mm3) {
    if (batch_rows > 0) {
        const auto share = float(removed_mm3 / double(batch_rows));
        for (std::size_t k = first_row; k < samples.size(); ++k) samples[k].removed_mm3 = share;
    } else if (!samples.empty()) {
        samples.back().removed_mm3 += float(removed_mm3);
    }
}

}  // namespace cutload::force_model
