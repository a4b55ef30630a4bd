// Fixtures for the NC program tests: a DryRunSpec's program written as G-code (so a synthetic
// dry-run log and its program come from one definition), logs ingested from memory, and the
// demo data's paths.
#pragma once

#include "force_model/force_model.hpp"
#include "app/program_run.hpp"
#include "motion_io/block_mapping.hpp"
#include "motion_io/nc_program.hpp"
#include "motion_io/synth.hpp"

#include <fmt/format.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <unistd.h>

namespace cutload::nctest {

inline std::string source_path(const std::string& rel) { return std::string(CUTLOAD_SOURCE_DIR) + "/" + rel; }

// FANUC style: always a decimal point, no trailing zeros ("45.", "40.5", "-3.").
inline std::string nc_number(double v) {
    if (std::abs(v) < 5e-7) v = 0;
    std::string s = fmt::format("{:.3f}", v);
    while (s.back() == '0') s.pop_back();
    return s;
}

struct NcStyle {
    std::string header_comment = "CUTLOAD TEST PROGRAM";
    int program_number = 1000;
};

// The spec's program in work coordinates (machine minus work_zero_mm), modal words written only
// when they change, S/M03 with the first block, M05 and M30 unnumbered at the end.
inline std::string program_text(const motion_io::DryRunSpec& spec, const std::array<double, 3>& work_zero_mm,
                                const NcStyle& style = {}) {
    std::string out = fmt::format("%\nO{} ({})\n", style.program_number, style.header_comment);
    out += "G21 G17 G40 G49 G80 G90 G94\n";
    std::array<double, 3> pos{spec.start_mm[0] - work_zero_mm[0], spec.start_mm[1] - work_zero_mm[1],
                              spec.start_mm[2] - work_zero_mm[2]};
    int mode = -1;
    double feed = 0;
    bool first = true;
    for (const motion_io::ProgramBlock& b : spec.program) {
        std::string line = b.name;
        const int m = b.rapid ? 0 : 1;
        if (m != mode) line += m == 0 ? " G00" : " G01";
        if (first) line += " G54";
        mode = m;
        for (int a = 0; a < 3; ++a) {
            const double v = b.target_mm[a] - work_zero_mm[a];
            if (first || std::abs(v - pos[a]) > 1e-9) line += fmt::format(" {}{}", "XYZ"[a], nc_number(v));
            pos[a] = v;
        }
        if (!b.rapid && std::abs(b.feed_mm_min - feed) > 1e-9) {
            line += fmt::format(" F{:.0f}", b.feed_mm_min);
            feed = b.feed_mm_min;
        }
        if (first) line += fmt::format(" S{:.0f} M03", spec.machine.spindle_rpm);
        first = false;
        out += line + "\n";
    }
    out += "M05\nM30\n%\n";
    return out;
}

inline std::string read_text(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

// A scratch file under the system temp dir, removed at scope end.
class TempFile {
public:
    explicit TempFile(const std::string& name, const std::string& content = {})
        : path_((std::filesystem::temp_directory_path() / ("cutload_nc_" + std::to_string(::getpid()) + "_" + name)).string()) {
        if (!content.empty()) {
            std::ofstream out(path_, std::ios::binary);
            out << content;
        }
    }
    ~TempFile() {
        std::error_code ec;
        std::filesystem::remove(path_, ec);
    }
    TempFile(const TempFile&) = delete;
    TempFile& operator=(const TempFile&) = delete;
    const std::string& path() const { return path_; }

private:
    std::string path_;
};

}  // namespace cutload::nctest

namespace cutload::nctest {

// A synthetic dry run of `spec` (the demo's machine and client models), ingested at step_ms.
inline motion_io::MotionModel dry_run_motion(const motion_io::DryRunSpec& spec, const std::string& tag, double step_ms = 1.0,
                                             bool keep_blocks = true) {
    std::ostringstream csv;
    motion_io::synthesize_dry_run(spec, csv);
    std::string text = csv.str();
    if (!keep_blocks) {
        // Drop the last column (block): a log from a client that does not read the block number.
        std::string stripped;
        std::istringstream in(text);
        for (std::string line; std::getline(in, line);) stripped += line.substr(0, line.rfind(',')) + "\n";
        text = stripped;
    }
    TempFile f(tag + ".csv", text);
    motion_io::ReadOptions ro;
    ro.step_ms = step_ms;
    return motion_io::ingest(f.path(), ro);
}

inline motion_io::NcReadOptions read_options_for(const motion_io::DryRunSpec& spec, const std::array<double, 3>& work_zero_mm) {
    motion_io::NcReadOptions o;
    o.work_offsets_mm["G54"] = work_zero_mm;
    o.start_mm = std::array<double, 3>{spec.start_mm[0], spec.start_mm[1], spec.start_mm[2]};
    return o;
}

// A small zig-zag with corners at two feeds and rapids on the demo's machine: calibrates the
// machine's block lead for mapping logs without blocks.
inline motion_io::DryRunSpec calibration_spec() {
    motion_io::DryRunSpec spec;
    spec.start_mm[0] = 0, spec.start_mm[1] = 0, spec.start_mm[2] = 50;
    auto add = [&](const char* name, bool rapid, double x, double y, double z, double f) {
        motion_io::ProgramBlock b;
        b.name = name;
        b.rapid = rapid;
        b.target_mm[0] = x, b.target_mm[1] = y, b.target_mm[2] = z;
        b.feed_mm_min = f;
        spec.program.push_back(b);
    };
    add("N1", true, 10, 0, 50, 0);
    add("N2", true, 10, 0, 5, 0);
    add("N3", false, 40, 0, 5, 6000);
    add("N4", false, 40, 20, 5, 6000);
    add("N5", false, 10, 20, 5, 3000);
    add("N6", false, 10, 40, 5, 3000);
    add("N7", true, 10, 40, 50, 0);
    spec.machine.spindle_ramp_s = 0;
    spec.seed = 99;
    return spec;
}

// The block lead of the demo machine, calibrated on calibration_spec()'s log with blocks.
inline double calibrated_lead_s() {
    const motion_io::DryRunSpec cal = calibration_spec();
    const motion_io::MotionModel cal_log = dry_run_motion(cal, "cal");
    const motion_io::NcProgram cal_prog = motion_io::parse_nc_program(program_text(cal, {0, 0, 0}), "cal.nc", read_options_for(cal, {0, 0, 0}));
    return motion_io::estimate_block_lead_s(cal_log, cal_prog, motion_io::BlockMappingOptions{});
}

}  // namespace cutload::nctest
