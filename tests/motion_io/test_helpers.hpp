// Shared helpers of the motion_io tests: temporary files and synthetic logs.
#pragma once

#include "motion_io/motion_io.hpp"
#include "motion_io/synth.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace cutload::motion_io::test {

// A file under the system temp folder, removed when the object goes out of scope.
class TempFile {
public:
    // Writes `content` unless create is false (a path that must not exist).
    explicit TempFile(const std::string& name, const std::string& content = {}, bool create = true)
        : path_(std::filesystem::temp_directory_path() / ("cutload_motion_test_" + name)) {
        std::error_code ec;
        std::filesystem::remove(path_, ec);
        if (create) std::ofstream(path_, std::ios::binary) << content;
    }
    ~TempFile() {
        std::error_code ec;
        std::filesystem::remove(path_, ec);
    }
    std::string path() const { return path_.string(); }

private:
    std::filesystem::path path_;
};

// One straight G01 move at a constant programmed feed, in the seed's sampling pattern.
inline DryRunSpec straight_line_spec(double feed_mm_min, double length_mm, std::uint64_t seed = 7) {
    DryRunSpec spec;
    spec.start_mm[0] = 238.555, spec.start_mm[1] = -279.308, spec.start_mm[2] = -321.958;
    ProgramBlock b;
    b.name = "N10";
    b.feed_mm_min = feed_mm_min;
    // Diagonal in XY so both axes beat against the grid.
    b.target_mm[0] = spec.start_mm[0] - length_mm * 0.6;
    b.target_mm[1] = spec.start_mm[1] - length_mm * 0.8;
    b.target_mm[2] = spec.start_mm[2];
    spec.program.push_back(b);
    spec.seed = seed;
    return spec;
}

inline std::string synth_csv(const DryRunSpec& spec) {
    std::ostringstream s;
    synthesize_dry_run(spec, s);
    return s.str();
}

inline double speed_mm_min(const MotionModel& m, std::size_t i) {
    return std::sqrt(m.vx_mm_s[i] * m.vx_mm_s[i] + m.vy_mm_s[i] * m.vy_mm_s[i] + m.vz_mm_s[i] * m.vz_mm_s[i]) * 60.0;
}

inline std::string source_path(const std::string& rel) { return std::string(CUTLOAD_SOURCE_DIR) + "/" + rel; }

// A CSV log with every time stamp (columns named "t_..." or "t [s]") moved by shift_us
// microseconds, in exact decimal arithmetic: what the same run logged by a client whose clock
// started elsewhere writes. The stamps must have at most 6 decimals (all generated and bundled logs).
inline std::string shift_time_columns(const std::string& csv, long long shift_us) {
    std::istringstream in(csv);
    std::string line, out;
    std::vector<bool> is_time;
    auto split = [](const std::string& l) {
        std::vector<std::string> cells(1);
        for (char c : l) {
            if (c == ',') cells.emplace_back();
            else cells.back().push_back(c);
        }
        return cells;
    };
    while (std::getline(in, line)) {
        std::vector<std::string> cells = split(line);
        if (is_time.empty()) {
            for (const std::string& h : cells) is_time.push_back(h.rfind("t_", 0) == 0 || h == "t [s]");
            out += line + '\n';
            continue;
        }
        for (std::size_t i = 0; i < cells.size() && i < is_time.size(); ++i) {
            if (!is_time[i] || cells[i].empty()) continue;
            const std::string& v = cells[i];
            const bool negative = v[0] == '-';
            const std::size_t dot = v.find('.');
            const std::string whole = v.substr(negative ? 1 : 0, dot == std::string::npos ? std::string::npos : dot - (negative ? 1 : 0));
            std::string frac = dot == std::string::npos ? "" : v.substr(dot + 1);
            if (frac.size() > 6) throw std::runtime_error("shift_time_columns: more than 6 decimals in " + v);
            frac.resize(6, '0');
            long long us = std::stoll(whole) * 1000000 + std::stoll(frac);
            us = (negative ? -us : us) + shift_us;
            const long long mag = us < 0 ? -us : us;
            std::string frac_out = std::to_string(mag % 1000000);
            frac_out.insert(0, 6 - frac_out.size(), '0');
            cells[i] = (us < 0 ? "-" : "") + std::to_string(mag / 1000000) + "." + frac_out;
        }
        for (std::size_t i = 0; i < cells.size(); ++i) out += (i ? "," : "") + cells[i];
        out += '\n';
    }
    return out;
}
inline std::string shared_path(const std::string& rel) { return std::string(CUTLOAD_SHARED_DIR) + "/" + rel; }

// How many times a warning code was reported (0 when it was not).
inline std::size_t warning_count(const IngestReport& r, const std::string& code) {
    for (const auto& w : r.warnings)
        if (w.code == code) return w.count;
    return 0;
}

}  // namespace cutload::motion_io::test
