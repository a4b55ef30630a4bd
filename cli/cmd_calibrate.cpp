// cutload calibrate --tool TOOL.json --test FILE:SPINDLE_RPM:FEED_MM_MIN:AXIAL_MM:RADIAL_MM:MODE[:FROM_S-TO_S[:ZERO]] ...
//                   [--axes MATRIX] --out MATERIAL.json
// Identifies Ktc, Krc, Kac, Kte, Kre, Kae from the steady mean forces of straight dynamometer tests
// and saves them as the run spec's `material` object (docs/compare_calibrate.md).
#include "commands.hpp"
#include "app/calibrate.hpp"
#include "app/inputs.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <optional>
#include <utility>

namespace cutload::cli {
namespace {

struct CalibrateArgs {
    std::string tool, axes, out, name = "calibrated", model = "engine", measured_on = "workpiece", device = "cpu";
    std::vector<std::string> tests;
    double feed_deg = 0;
};

constexpr const char* kTestFields =
    "FILE:SPINDLE_RPM:FEED_MM_MIN:AXIAL_MM:RADIAL_MM:MODE[:FROM_S-TO_S[:ZERO_FX,ZERO_FY,ZERO_FZ]]";

double number_field(const std::string& text, const char* field, const std::string& value) {
    try {
        std::size_t used = 0;
        const double v = std::stod(value, &used);
        if (used != value.size() || !std::isfinite(v)) throw std::invalid_argument("trailing");
        return v;
    } catch (const std::exception&) {
        throw UsageError(fmt::format("--test `{}`: {} `{}` is not a number", text, field, value));
    }
}

// FROM_S-TO_S: two times (either may be negative) joined by a hyphen.
std::pair<double, double> parse_window(const std::string& text, const std::string& field) {
    std::size_t used = 0;
    double from = 0, to = 0;
    try {
        from = std::stod(field, &used);
        if (used >= field.size() || field[used] != '-') throw std::invalid_argument("no hyphen");
        std::size_t rest = 0;
        to = std::stod(field.substr(used + 1), &rest);
        if (used + 1 + rest != field.size() || !std::isfinite(from) || !std::isfinite(to))
            throw std::invalid_argument("trailing");
    } catch (const std::exception&) {
        throw UsageError(fmt::format("--test `{}`: steady window `{}` is not FROM_S-TO_S (e.g. 0.25-0.75, seconds "
                                     "of the record's time)",
                                     text, field));
    }
    if (!(to > from))
        throw UsageError(fmt::format("--test `{}`: steady window `{}` ends before it starts", text, field));
    return {from, to};
}

// Fields are split at colons; MODE is the last of the last three fields that names a mode, so the
// file name may hold colons and the window and zero may follow.
app::CalibrationTest parse_test(const std::string& text, double feed_deg) {
    std::vector<std::string> parts;
    for (std::size_t start = 0;;) {
        const auto colon = text.find(':', start);
        parts.push_back(text.substr(start, colon == std::string::npos ? std::string::npos : colon - start));
        if (colon == std::string::npos) break;
        start = colon + 1;
    }
    if (parts.size() < 6) throw UsageError(fmt::format("--test `{}`: expected {}", text, kTestFields));
    std::size_t mode = parts.size() - 1;   // no mode word: the sixth field from the right is read as one
    for (std::size_t back = 1; back <= 3 && back + 5 <= parts.size(); ++back) {
        const std::string& p = parts[parts.size() - back];
        if (p == "slot" || p == "up" || p == "down") {
            mode = parts.size() - back;
            break;
        }
    }
    app::CalibrationTest t;
    for (std::size_t i = 0; i + 4 < mode; ++i) t.file += (i ? ":" : "") + parts[i];
    static const char* fields[4] = {"SPINDLE_RPM", "FEED_MM_MIN", "AXIAL_MM", "RADIAL_MM"};
    double v[4];
    for (std::size_t i = 0; i < 4; ++i) v[i] = number_field(text, fields[i], parts[mode - 4 + i]);
    t.test.spindle_rpm = v[0];
    t.test.feed_mm_min = v[1];
    t.test.axial_mm = v[2];
    t.test.radial_mm = v[3];
    try {
        t.test.mode = force_model::parse_immersion(parts[mode]);
    } catch (const force_model::SpecError& e) {
        throw UsageError(fmt::format("--test `{}`: {} (fields: {})", text, e.what(), kTestFields));
    }
    t.test.feed_direction_deg = feed_deg;
    if (mode + 1 < parts.size() && !parts[mode + 1].empty()) {
        const auto [from, to] = parse_window(text, parts[mode + 1]);
        t.from_s = from;
        t.to_s = to;
    }
    if (mode + 2 < parts.size()) {
        try {
            t.zero_dyn_N = force_model::parse_force_vector(parts[mode + 2]);
        } catch (const force_model::MeasurementError& e) {
            throw UsageError(fmt::format("--test `{}`: zero offset: {}", text, e.what()));
        }
    }
    return t;
}

const char* zero_phrase(force_model::ZeroSource s) {
    switch (s) {
        case force_model::ZeroSource::LeadIn: return "from the idle lead-in";
        case force_model::ZeroSource::IdleTail: return "from the idle tail";
        case force_model::ZeroSource::Given: return "given";
        case force_model::ZeroSource::Estimated: return "estimated from the air between tooth passes";
        case force_model::ZeroSource::None: break;
    }
    return "none";
}

const char* drift_phrase(force_model::DriftSource s) {
    switch (s) {
        case force_model::DriftSource::Idle: return "from the lead-in to the tail";
        case force_model::DriftSource::Cut: return "trend of the steady revolutions";
        case force_model::DriftSource::None: break;
    }
    return "none found";
}

void warn_out_of_spec(const force_model::Material& m) {
    const auto k = force_model::coefficients_of(m);
    const bool bad[6] = {!(k[0] > 0), k[1] < 0, false, k[3] < 0, k[4] < 0, false};
    for (std::size_t i = 0; i < 6; ++i)
        if (bad[i])
            std::fprintf(stderr, "cutload: warning: %s = %.4g is outside the run spec's range; predict will reject "
                                 "this material until the tests are checked\n",
                         force_model::kCoefficientKeys[i], k[i]);
}

void run_calibrate(const CalibrateArgs& a) {
    app::CalibrationInput in;
    in.tool = app::load_tool(a.tool);   // TOOL.json: the run spec's tool object, or a whole RUN.json
    try {
        if (!a.axes.empty()) in.axes = force_model::parse_axis_matrix(a.axes);
    } catch (const force_model::MeasurementError& e) {
        throw UsageError(std::string("--axes: ") + e.what());
    }
    in.measured_on_workpiece = a.measured_on == "workpiece";
    in.model = a.model == "closed-form" ? app::RegressorModel::ClosedForm : app::RegressorModel::Engine;
    in.device = a.device == "opencl" ? force_model::Device::OpenCL : force_model::Device::Cpu;
    in.material_name = a.name;
    for (const std::string& text : a.tests) {
        app::CalibrationTest t = parse_test(text, a.feed_deg);
        try {
            force_model::validate_cut_test(t.test, in.tool);
        } catch (const force_model::SpecError& e) {
            throw UsageError(fmt::format("--test `{}`: {}", text, e.what()));
        }
        in.tests.push_back(t);
    }
    app::Calibration cal;
    try {
        cal = app::calibrate(in);
    } catch (const force_model::SteadyError& e) {
        throw UsageError(fmt::format(
            "{} ({})", e.what(),
            e.need == force_model::SteadyError::Need::Window
                ? "as the 7th --test field FROM_S-TO_S, in the record's time"
                : "as the 8th --test field ZERO_FX,ZERO_FY,ZERO_FZ: the record's reading with no load at its "
                  "first sample, in its own channels"));
    } catch (const force_model::MeasurementError& e) {
        throw UsageError(e.what());
    }
    for (std::size_t i = 0; i < in.tests.size(); ++i) {
        const app::CalibrationTest& t = in.tests[i];
        const force_model::SteadyForce& steady = cal.tests[i].steady;
        const auto& mean = cal.tests[i].mean_feed_frame_N;
        const auto drift = steady.drift_N();
        std::printf("%s: %s, %.6g rpm, %.6g mm/min, ap %.6g mm, ae %.6g mm: steady %.4f-%.4f s (%d rev, %s), zero "
                    "(%.3f, %.3f, %.3f) N removed (%s), drift (%.3f, %.3f, %.3f) N over the window (%s), mean F "
                    "(%.3f, %.3f, %.3f) N\n",
                    t.file.c_str(), force_model::immersion_name(t.test.mode), t.test.spindle_rpm, t.test.feed_mm_min,
                    t.test.axial_mm, t.test.radial_mm, steady.t_start_s, steady.t_end_s, steady.revolutions,
                    steady.window_given ? "window given" : "detected", steady.zero_N[0], steady.zero_N[1],
                    steady.zero_N[2], zero_phrase(steady.zero.source), drift[0], drift[1], drift[2],
                    drift_phrase(steady.zero.drift_source), mean[0], mean[1], mean[2]);
    }
    const force_model::CalibrationFit& fit = cal.fit;
    const auto k = force_model::coefficients_of(fit.material);
    std::printf("fit (%s regressors, %zu equations): rms residual %.3f N (%.2f %% of the mean forces), condition "
                "number %.3g\n",
                a.model.c_str(), fit.equations, fit.rms_residual_N, 100 * fit.relative_rms_residual,
                fit.condition_number);
    for (std::size_t i = 0; i < in.tests.size(); ++i)
        std::printf("  %s: residual rms %.3f N\n", in.tests[i].file.c_str(), fit.group_rms_residual_N[i]);
    for (std::size_t i = 0; i < 6; ++i) std::printf("  %-10s %10.4f\n", force_model::kCoefficientKeys[i], k[i]);
    warn_out_of_spec(fit.material);

    const std::string tmp = a.out + ".tmp";
    {
        std::ofstream out(tmp, std::ios::trunc);
        if (!out) throw UsageError("cannot write " + tmp);
        out << force_model::material_json(fit.material).dump(2) << "\n";
        if (!out) throw UsageError("writing " + tmp + " failed");
    }
    if (std::rename(tmp.c_str(), a.out.c_str()) != 0) throw UsageError("cannot rename " + tmp + " to " + a.out);
    std::printf("material -> %s\n", a.out.c_str());
}

void add_calibrate(CLI::App& app) {
    auto a = std::make_shared<CalibrateArgs>();
    auto* cmd = app.add_subcommand("calibrate", "Identify cutting coefficients from dynamometer tests");
    cmd->add_option("--tool", a->tool, "TOOL.json: the run spec's tool object (or a whole RUN.json)")
        ->required()
        ->check(CLI::ExistingFile);
    cmd->add_option("--test", a->tests,
                    std::string(kTestFields) +
                        ": mode slot|up|down; optional steady window (record time) and zero offset (the record's "
                        "channels at its start); repeat per test")
        ->required();
    cmd->add_option("--axes", a->axes, "Dynamometer-to-machine axis matrix, nine numbers, row-major");
    cmd->add_option("--out", a->out, "MATERIAL.json: the run spec's material object")->required();
    cmd->add_option("--name", a->name, "Material name written to the file")->capture_default_str();
    cmd->add_option("--feed-deg", a->feed_deg, "Feed direction in machine XY, degrees counter-clockwise from +X")
        ->capture_default_str();
    cmd->add_option("--model", a->model, "Regressors: engine (any tool shape) or closed-form (flat end mill)")
        ->check(CLI::IsMember({"engine", "closed-form"}))
        ->capture_default_str();
    cmd->add_option("--measured-on", a->measured_on, "What the dynamometer carries: workpiece or tool")
        ->check(CLI::IsMember({"workpiece", "tool"}))
        ->capture_default_str();
    cmd->add_option("--device", a->device, "Engine device for the regressors")
        ->check(CLI::IsMember({"cpu", "opencl"}))
        ->capture_default_str();
    cmd->callback([a] {
        check_output_path(a->out, "--out");
        run_calibrate(*a);
    });
}

const bool registered = register_command("calibrate", &add_calibrate);

}  // namespace
}  // namespace cutload::cli
