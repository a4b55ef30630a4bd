// cutload calibrate --tool TOOL.json --test FILE:SPINDLE_RPM:FEED_MM_MIN:AXIAL_MM:RADIAL_MM:MODE ...
//                   [--axes MATRIX] --out MATERIAL.json
// Identifies Ktc, Krc, Kac, Kte, Kre, Kae from the steady mean forces of straight dynamometer tests
// and saves them as the run spec's `material` object (docs/compare_calibrate.md).
#include "commands.hpp"
#include "app/calibrate.hpp"
#include "app/inputs.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <fstream>
#include <memory>

namespace cutload::cli {
namespace {

struct CalibrateArgs {
    std::string tool, axes, out, name = "calibrated", model = "engine", measured_on = "workpiece", device = "cpu";
    std::vector<std::string> tests;
    double feed_deg = 0;
};

// FILE:RPM:FEED:AXIAL:RADIAL:MODE, split from the right so the file name may hold colons.
app::CalibrationTest parse_test(const std::string& text, double feed_deg) {
    std::vector<std::string> parts;
    std::string rest = text;
    for (int i = 0; i < 5; ++i) {
        const auto colon = rest.rfind(':');
        if (colon == std::string::npos)
            throw UsageError(fmt::format("--test `{}`: expected FILE:SPINDLE_RPM:FEED_MM_MIN:AXIAL_MM:RADIAL_MM:MODE",
                                         text));
        parts.insert(parts.begin(), rest.substr(colon + 1));
        rest.resize(colon);
    }
    app::CalibrationTest t;
    t.file = rest;
    static const char* fields[4] = {"SPINDLE_RPM", "FEED_MM_MIN", "AXIAL_MM", "RADIAL_MM"};
    double v[4];
    for (int i = 0; i < 4; ++i) {
        try {
            std::size_t used = 0;
            v[i] = std::stod(parts[static_cast<std::size_t>(i)], &used);
            if (used != parts[static_cast<std::size_t>(i)].size()) throw std::invalid_argument("trailing");
        } catch (const std::exception&) {
            throw UsageError(fmt::format("--test `{}`: {} `{}` is not a number", text, fields[i], parts[i]));
        }
    }
    t.test.spindle_rpm = v[0];
    t.test.feed_mm_min = v[1];
    t.test.axial_mm = v[2];
    t.test.radial_mm = v[3];
    try {
        t.test.mode = force_model::parse_immersion(parts[4]);
    } catch (const force_model::SpecError& e) {
        throw UsageError(fmt::format("--test `{}`: {}", text, e.what()));
    }
    t.test.feed_direction_deg = feed_deg;
    return t;
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
    } catch (const force_model::MeasurementError& e) {
        throw UsageError(e.what());
    }
    for (std::size_t i = 0; i < in.tests.size(); ++i) {
        const app::CalibrationTest& t = in.tests[i];
        const force_model::SteadyForce& steady = cal.tests[i].steady;
        const auto& mean = cal.tests[i].mean_feed_frame_N;
        std::printf("%s: %s, %.6g rpm, %.6g mm/min, ap %.6g mm, ae %.6g mm: steady %.4f-%.4f s (%d rev), zero %s, "
                    "mean F (%.3f, %.3f, %.3f) N\n",
                    t.file.c_str(), force_model::immersion_name(t.test.mode), t.test.spindle_rpm, t.test.feed_mm_min,
                    t.test.axial_mm, t.test.radial_mm, steady.t_start_s, steady.t_end_s, steady.revolutions,
                    steady.zeroed ? fmt::format("({:.3f}, {:.3f}, {:.3f}) N removed", steady.zero_N[0],
                                                steady.zero_N[1], steady.zero_N[2])
                                        .c_str()
                                  : "not removed (no idle revolutions before the cut)",
                    mean[0], mean[1], mean[2]);
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
                    "FILE:SPINDLE_RPM:FEED_MM_MIN:AXIAL_MM:RADIAL_MM:MODE, mode slot|up|down; repeat per test")
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
