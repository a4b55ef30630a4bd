// Small fixtures for the engine tests: run specs and motion models built directly (uniform samples,
// constant feed along straight 3D segments), so the tests do not depend on log ingest.
#pragma once

#include "force_model/engine.hpp"
#include "kernels/opencl_runtime.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

namespace cutload::enginetest {

using P3 = std::array<double, 3>;

struct Leg {
    P3 end;
    double feed_mm_min;
    std::string block;
    double rpm = 10000;
    std::int32_t tool = -1;   // T number in the spindle; the motion names tools when any leg does
};

// Uniform 1 ms samples along straight legs from `start`; spindle angle by the trapezoid rule.
inline motion_io::MotionModel legs_motion(P3 start, const std::vector<Leg>& legs, double step_s = 0.001) {
    motion_io::MotionModel m;
    m.step_s = step_s;
    double t = 0, angle = 0, prev_rpm = legs.empty() ? 0 : legs.front().rpm;
    P3 p = start;
    const bool tools = std::any_of(legs.begin(), legs.end(), [](const Leg& l) { return l.tool >= 0; });
    auto push = [&](const P3& pos, const P3& vel, double rpm, int block) {
        if (tools) m.tool.push_back(block >= 0 ? legs[std::size_t(block)].tool : -1);
        if (!m.t_s.empty()) angle += 6.0 * 0.5 * (prev_rpm + rpm) * step_s;
        prev_rpm = rpm;
        m.t_s.push_back(t);
        m.x_mm.push_back(pos[0]);
        m.y_mm.push_back(pos[1]);
        m.z_mm.push_back(pos[2]);
        m.vx_mm_s.push_back(vel[0]);
        m.vy_mm_s.push_back(vel[1]);
        m.vz_mm_s.push_back(vel[2]);
        m.spindle_rpm.push_back(rpm);
        m.spindle_angle_deg.push_back(angle);
        m.block.push_back(block);
        t += step_s;
    };
    for (std::size_t l = 0; l < legs.size(); ++l) {
        const Leg& leg = legs[l];
        m.block_names.push_back(leg.block);
        const P3 d{leg.end[0] - p[0], leg.end[1] - p[1], leg.end[2] - p[2]};
        const double len = std::hypot(d[0], d[1], d[2]);
        const double speed = leg.feed_mm_min / 60.0;
        const auto n = std::max<long>(1, std::lround(len / (speed * step_s)));
        const P3 v = len > 0 ? P3{d[0] / len * speed, d[1] / len * speed, d[2] / len * speed} : P3{0, 0, 0};
        for (long k = 0; k < n; ++k) {
            const double u = double(k) / double(n);
            push({p[0] + u * d[0], p[1] + u * d[1], p[2] + u * d[2]}, v, leg.rpm, int(l));
        }
        p = leg.end;
    }
    push(p, {0, 0, 0}, legs.empty() ? 0 : legs.back().rpm, int(legs.size()) - 1);
    m.session_start = {0};
    return m;
}

inline force_model::RunSpec base_spec(double box_x = 40, double box_y = 20, double box_z = 10) {
    force_model::RunSpec s;
    s.tool.shape = force_model::ToolShape::Flat;
    s.tool.diameter_mm = 8;
    s.tool.flutes = 2;
    s.tool.helix_deg = 30;
    s.tool.flute_length_mm = 20;
    s.tool.stickout_mm = 30;
    s.tool.holder = {32, 40};
    s.material = {"Al7075-T6", 767.0, 168.8, 222.0, 27.7, 26.6, 0.7};
    s.stock.min_mm[0] = s.stock.min_mm[1] = s.stock.min_mm[2] = 0;
    s.stock.max_mm[0] = box_x;
    s.stock.max_mm[1] = box_y;
    s.stock.max_mm[2] = box_z;
    s.resolution = {2, 0.1, 0.1};
    return s;
}

// Every field of two rows equal, bit for bit (ForceSample has padding: memcmp is not a test).
inline bool same_row(const force_model::ForceSample& a, const force_model::ForceSample& b) {
    return a.t_s == b.t_s && a.spindle_angle_deg == b.spindle_angle_deg && a.block == b.block && a.tool == b.tool &&
           a.fx_N == b.fx_N && a.fy_N == b.fy_N && a.fz_N == b.fz_N && a.torque_Nm == b.torque_Nm &&
           a.power_kW == b.power_kW && a.chip_mm == b.chip_mm && a.bending_MPa == b.bending_MPa &&
           a.radial_engagement_mm == b.radial_engagement_mm && a.axial_engagement_mm == b.axial_engagement_mm &&
           a.removed_mm3 == b.removed_mm3 && a.holder_contact == b.holder_contact && a.fx_machine_N == b.fx_machine_N &&
           a.fy_machine_N == b.fy_machine_N && a.fz_machine_N == b.fz_machine_N && a.tool_axis_x == b.tool_axis_x &&
           a.tool_axis_y == b.tool_axis_y && a.tool_axis_z == b.tool_axis_z;
}

inline bool opencl_available() {
    try {
        kernels::OpenClRuntime::instance();
        return true;
    } catch (const kernels::OpenClError&) {
        return false;
    }
}

inline force_model::Prediction run_on(const motion_io::MotionModel& m, const force_model::RunSpec& s, force_model::Device d,
                                      const force_model::Stock* base = nullptr) {
    force_model::PredictOptions o;
    o.device = d;
    o.base_stock = base;
    return force_model::predict(m, s, o);
}

// A stock checkpoint as a service keeps it: through the stock format and back.
struct TakenCheckpoint {
    force_model::StockCheckpoint at;
    force_model::StockPtr stock;
};

// The whole run, with its stock checkpoints at least every_s apart.
inline force_model::Prediction run_with_checkpoints(const motion_io::MotionModel& m, const force_model::RunSpec& s,
                                                    force_model::Device d, double every_s,
                                                    std::vector<TakenCheckpoint>& taken) {
    force_model::PredictOptions o;
    o.device = d;
    o.checkpoint_every_s = every_s;
    o.checkpoint = [&](const force_model::StockCheckpoint& at, const force_model::Stock& stock) {
        std::stringstream bytes;
        force_model::save_stock(stock, bytes);
        taken.push_back({at, force_model::load_stock(bytes, "checkpoint")});
    };
    return force_model::predict(m, s, o);
}

// The window [from_s, to_s) resumed at checkpoint c.
inline force_model::Prediction resumed_window(const motion_io::MotionModel& m, const force_model::RunSpec& s,
                                              force_model::Device d, const TakenCheckpoint& c, double from_s, double to_s) {
    force_model::PredictOptions o;
    o.device = d;
    o.window = force_model::TimeWindow{from_s, to_s};
    o.base_stock = c.stock.get();
    o.resume = c.at;
    return force_model::predict(m, s, o);
}

struct Load {
    double mean_N = 0, peak_N = 0;
};

// Mean and peak resultant over the rows in [t0_s, t1_s]; at least 100 rows are required.
inline Load load_between(const force_model::Prediction& p, double t0_s, double t1_s) {
    Load l;
    std::size_t n = 0;
    for (const auto& s : p.samples) {
        if (s.t_s < t0_s || s.t_s > t1_s) continue;
        const double f = std::sqrt(double(s.fx_N) * s.fx_N + double(s.fy_N) * s.fy_N + double(s.fz_N) * s.fz_N);
        l.mean_N += f;
        l.peak_N = std::max(l.peak_N, f);
        ++n;
    }
    REQUIRE(n > 100);
    l.mean_N /= double(n);
    return l;
}

}  // namespace cutload::enginetest
