// The log targets' run: inspect the input (the whole chain of stages, bounded memory), then, when
// the motion it holds is short enough to keep, ingest it and check the motion model.
#pragma once

#include "fuzz_support.hpp"

#include "motion_io/motion_io.hpp"

#include <cmath>
#include <string>
#include <vector>

namespace cutload::fuzz {

// A 10 ms grid (the CLI's default is 1 ms) keeps an input of a few rows that spans minutes from
// costing seconds per run; every stage runs all the same.
inline constexpr double kGridStepMs = 10;
// Motion models up to this long are built and checked (100000 samples at 10 ms).
inline constexpr double kMaxModelSeconds = 1000;

inline void check_model(const motion_io::MotionModel& m) {
    const std::size_t n = m.size();
    for (const std::vector<double>* v : {&m.x_mm, &m.y_mm, &m.z_mm, &m.vx_mm_s, &m.vy_mm_s, &m.vz_mm_s, &m.spindle_rpm,
                                         &m.spindle_angle_deg})
        if (v->size() != n) broken("motion model channels differ in length");
    if (m.block.size() != n) broken("motion model block channel differs in length");
    for (std::size_t i = 0; i < n; ++i) {
        for (const double v : {m.t_s[i], m.x_mm[i], m.y_mm[i], m.z_mm[i], m.vx_mm_s[i], m.vy_mm_s[i], m.vz_mm_s[i],
                               m.spindle_rpm[i], m.spindle_angle_deg[i]})
            if (!std::isfinite(v)) broken("non-finite value in the motion model at sample " + std::to_string(i));
        if (m.block[i] >= static_cast<std::int32_t>(m.block_names.size())) broken("block index out of range");
    }
    std::size_t s = 0;
    for (std::size_t i = 1; i < n; ++i) {
        while (s + 1 < m.session_start.size() && m.session_start[s + 1] <= i) ++s;
        if (m.session_start[s] != i && !(m.t_s[i] > m.t_s[i - 1])) broken("time does not advance within a session");
    }
}

inline int run_log(const std::uint8_t* data, std::size_t size, motion_io::Format format) {
    static InputFile file;
    const std::string& path = file.write(data, size);
    motion_io::ReadOptions opt;
    opt.format = format;
    opt.step_ms = kGridStepMs;
    try {
        const motion_io::IngestReport report = motion_io::inspect(path, opt);
        check_output(motion_io::report_to_json(report));
        check_output(motion_io::to_json(motion_io::check_sampling(report, 2)));
        if (!(report.duration_s >= 0)) broken("negative or NaN duration");
        if (report.duration_s <= kMaxModelSeconds) check_model(motion_io::ingest(path, opt));
    } catch (const motion_io::IngestError& e) {
        check_output(nlohmann::json(e.what()));
    }
    return 0;
}

}  // namespace cutload::fuzz
