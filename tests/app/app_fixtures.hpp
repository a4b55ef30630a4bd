// Fixtures of the app suite: the bundled demo as a use case's input, the straight slot the CLI's
// program tests use, and a recorder of what a use case reports through its Control.
#pragma once

#include "app/control.hpp"
#include "app/predict_run.hpp"

#include <catch2/catch.hpp>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <unistd.h>

namespace cutload::apptest {

inline std::string source_path(const std::string& rel) { return std::string(CUTLOAD_SOURCE_DIR) + "/" + rel; }

inline std::string read_text(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

inline void write_text(const std::filesystem::path& p, const std::string& text) {
    std::ofstream out(p, std::ios::binary);
    out << text;
    REQUIRE(out);
}

// A fresh, empty scratch folder, removed with everything in it at scope end. The process id keeps
// suites run at once (from several build folders) apart.
class Scratch {
public:
    explicit Scratch(const std::string& name)
        : dir_(std::filesystem::temp_directory_path() / ("cutload_app_test_" + name + "_" + std::to_string(::getpid()))) {
        std::filesystem::remove_all(dir_);
        std::filesystem::create_directories(dir_);
    }
    ~Scratch() {
        std::error_code ec;
        std::filesystem::remove_all(dir_, ec);
    }
    Scratch(const Scratch&) = delete;
    Scratch& operator=(const Scratch&) = delete;
    operator const std::filesystem::path&() const { return dir_; }
    std::filesystem::path operator/(const std::string& name) const { return dir_ / name; }

private:
    std::filesystem::path dir_;
};

// data/demo_dryrun.csv with data/demo_run.json, as `cutload predict --device cpu` reads them.
inline app::RunInput demo_input(bool with_program) {
    app::RunInput in;
    in.log_path = source_path("data/demo_dryrun.csv");
    in.read = app::read_options(app::LogFormat{});
    in.spec = force_model::load_run_spec(source_path("data/demo_run.json"));
    if (with_program) {
        in.program.emplace();
        in.program->path = source_path("data/demo_program.nc");
    }
    in.device = force_model::Device::Cpu;
    return in;
}

// The straight slot of the CLI's program tests (tests/cli/test_program_cli.cpp): along +X at
// 1200 mm/min and 10000 rpm, logged every 2 ms, its two-block program, and a spec with a 400 N
// force limit. Writes slot.csv, slot.nc and slot.json into `dir`.
inline void write_slot(const std::filesystem::path& dir) {
    std::ostringstream log;
    log << "t,x,y,z,feed,spindle\n";
    for (int i = 0; i < 500; ++i) {
        const double t = i * 0.002;
        log << t << ',' << -6.0 + 20.0 * t << ",5,-2,1200,10000\n";
    }
    write_text(dir / "slot.csv", log.str());
    write_text(dir / "slot.nc", "%\nO0007 (SLOT)\nN10 G90 G21 G17 G01 X4. Y5. Z-2. F1200 S10000 M03\nN20 X14.\nM30\n%\n");
    write_text(dir / "slot.json", R"({"tool": {"shape": "flat", "diameter_mm": 8, "flutes": 2, "helix_deg": 30,
        "flute_length_mm": 20, "stickout_mm": 30},
      "material": {"name": "A7050", "Ktc_N_mm2": 800, "Krc_N_mm2": 300, "Kac_N_mm2": 100, "Kte_N_mm": 20,
        "Kre_N_mm": 20, "Kae_N_mm": 5},
      "stock": {"box_mm": {"min": [0, 0, -10], "max": [100, 10, 0]}},
      "limits": {"force_N": 400}})");
}

// The same row of forces: time, block, the three components and the volume removed.
inline bool same_sample(const force_model::ForceSample& a, const force_model::ForceSample& b) {
    return a.t_s == b.t_s && a.block == b.block && a.fx_N == b.fx_N && a.fy_N == b.fy_N && a.fz_N == b.fz_N &&
           a.removed_mm3 == b.removed_mm3;
}

// Everything a use case reports, and a cancel that can be set when a given phase starts.
class Recorder {
public:
    std::vector<std::pair<app::Phase, double>> calls;
    std::atomic<bool> cancel{false};
    std::optional<app::Phase> cancel_at;   // set `cancel` when this phase is first reported

    app::Control control() {
        app::Control c;
        c.cancel = &cancel;
        c.progress = [this](app::Phase p, double f) {
            calls.emplace_back(p, f);
            if (cancel_at && p == *cancel_at) cancel = true;
        };
        return c;
    }

    // The phases in the order they were first reported.
    std::vector<app::Phase> phases() const {
        std::vector<app::Phase> out;
        for (const auto& [p, f] : calls)
            if (out.empty() || out.back() != p) out.push_back(p);
        return out;
    }

    // Fractions never decrease and stay in 0..1; phases never go back.
    void require_monotonic() const {
        for (std::size_t i = 0; i < calls.size(); ++i) {
            INFO("call " << i << ": " << app::phase_name(calls[i].first) << " " << calls[i].second);
            REQUIRE(calls[i].second >= 0);
            REQUIRE(calls[i].second <= 1);
            if (i == 0) continue;
            REQUIRE(calls[i].second >= calls[i - 1].second);
            REQUIRE(static_cast<int>(calls[i].first) >= static_cast<int>(calls[i - 1].first));
        }
    }

    // The largest fraction reported while `phase` ran (nullopt: never reported).
    std::optional<double> reached(app::Phase phase) const {
        std::optional<double> f;
        for (const auto& [p, x] : calls)
            if (p == phase) f = x;
        return f;
    }
    std::optional<double> started(app::Phase phase) const {
        for (const auto& [p, x] : calls)
            if (p == phase) return x;
        return std::nullopt;
    }
};

}  // namespace cutload::apptest
