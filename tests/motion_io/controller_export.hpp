// A seeded generator of controller trace exports shaped like the University of Michigan SMART lab
// "CNC Mill Tool Wear" data (the real file is experiment_05.csv in the shared data folder; see its
// SOURCE.md): per-axis X1_/Y1_/Z1_ ActualPosition, ActualVelocity, ActualAcceleration and
// CommandPosition columns, a spindle velocity, the program number, the G-code line as
// M1_sequence_number, the feed, a text column Machining_Process; one row every 100 ms and no time
// column; every number printed with 3 significant digits in E-notation (printf "%.2E", 1.98E+02),
// so positions between 100 and 999 mm are written in 1 mm steps.
//
// The commanded path is piecewise linear at a constant feed per segment (20 mm/s cutting, 50 mm/s
// positioning, as in experiment 5) around the real export's working area (X 140-198, Y 100-160,
// Z 101-119 mm); the actual path follows it with a 30 ms servo lag plus seeded Gaussian noise of
// 5 um. The true positions at each row are returned for reference.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

namespace cutload::motion_io::test {

struct ControllerExport {
    std::string csv;
    std::vector<std::array<double, 3>> actual_mm, command_mm;   // true positions at each row
    std::vector<int> line;                                       // G-code line of each row
    double period_s = 0.1;
};

inline ControllerExport umich_like_export(std::uint64_t seed) {
    struct Segment {
        std::array<double, 3> to;
        double speed_mm_s;
        int line;
        const char* process;
    };
    const std::array<double, 3> home{198, 158, 119};
    const std::vector<Segment> program{
        {{198, 158, 119}, 0, 0, "Prep"},                 // 2 s idle at home
        {{150, 120, 119}, 50, 2, "Prep"},
        {{150, 120, 105}, 20, 7, "Layer 1 Up"},
        {{185, 120, 105}, 20, 14, "Layer 1 Up"},
        {{185, 135, 105}, 20, 16, "Layer 1 Up"},
        {{150, 135, 105}, 20, 18, "Layer 1 Up"},
        {{150, 150, 105}, 20, 20, "Layer 1 Up"},
        {{185, 150, 105}, 20, 23, "Layer 1 Up"},
        {{185, 150, 119}, 20, 25, "Layer 1 Up"},
        {{198, 158, 119}, 50, 29, "End"},
        {{198, 158, 119}, 0, 0, "End"},                  // 2 s idle at home
    };
    // Segment start times along the commanded path (idle segments last 2 s).
    std::vector<double> t_start;
    std::vector<std::array<double, 3>> from;
    double t = 0;
    std::array<double, 3> p = home;
    for (const Segment& s : program) {
        t_start.push_back(t);
        from.push_back(p);
        const double len = std::hypot(s.to[0] - p[0], s.to[1] - p[1], s.to[2] - p[2]);
        t += s.speed_mm_s > 0 ? len / s.speed_mm_s : 2.0;
        p = s.to;
    }
    const double t_end = t;
    auto segment_at = [&](double tt) {
        std::size_t k = 0;
        while (k + 1 < program.size() && t_start[k + 1] <= tt) ++k;
        return k;
    };
    auto command_at = [&](double tt) {
        tt = std::clamp(tt, 0.0, t_end);
        const std::size_t k = segment_at(tt);
        const double seg_t = (k + 1 < t_start.size() ? t_start[k + 1] : t_end) - t_start[k];
        const double u = seg_t > 0 ? std::clamp((tt - t_start[k]) / seg_t, 0.0, 1.0) : 1.0;
        std::array<double, 3> c;
        for (int a = 0; a < 3; ++a) c[a] = from[k][a] + u * (program[k].to[a] - from[k][a]);
        return c;
    };

    constexpr double kLag_s = 0.03, kNoise_mm = 0.005;
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> noise(0.0, kNoise_mm);
    ControllerExport out;
    auto e3 = [](double v) {
        char buf[32];
        std::snprintf(buf, sizeof buf, "%.2E", v);
        return std::string(buf);
    };
    std::string& csv = out.csv;
    for (const char* axis : {"X1", "Y1", "Z1"})
        for (const char* item : {"ActualPosition", "ActualVelocity", "ActualAcceleration", "CommandPosition"})
            csv += std::string(axis) + "_" + item + ",";
    csv += "S1_ActualVelocity,M1_CURRENT_PROGRAM_NUMBER,M1_sequence_number,M1_CURRENT_FEEDRATE,Machining_Process\n";
    const auto rows = static_cast<std::size_t>(std::floor(t_end / out.period_s)) + 1;
    for (std::size_t i = 0; i < rows; ++i) {
        const double tt = static_cast<double>(i) * out.period_s;
        const std::array<double, 3> cmd = command_at(tt), lagged = command_at(tt - kLag_s);
        const std::array<double, 3> before = command_at(tt - kLag_s - 0.01);
        std::array<double, 3> act;
        for (int a = 0; a < 3; ++a) act[a] = lagged[a] + noise(rng);
        const std::size_t k = segment_at(tt);
        for (int a = 0; a < 3; ++a) {
            const double v = (lagged[a] - before[a]) / 0.01;
            csv += e3(act[a]) + "," + e3(v) + "," + e3(0.0) + "," + e3(cmd[a]) + ",";
        }
        csv += e3(program[k].speed_mm_s > 0 ? 53.3 : 0.0) + "," + e3(1) + "," + e3(program[k].line) + "," +
               e3(program[k].speed_mm_s > 0 ? program[k].speed_mm_s : 6.0) + "," + program[k].process + "\n";
        out.actual_mm.push_back(act);
        out.command_mm.push_back(cmd);
        out.line.push_back(program[k].line);
    }
    return out;
}

}  // namespace cutload::motion_io::test
