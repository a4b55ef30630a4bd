// cutload compare --predicted FORCES.csv --measured FILE [--frame workpiece|machine] [--axes MATRIX]
// [--offset-s S] [--json] ...
// Aligns a dynamometer record with a prediction and prints error metrics per axis, overall and per
// NC block (docs/compare_calibrate.md).
#include "commands.hpp"
#include "app/compare.hpp"

#include <nlohmann/json.hpp>

#include <array>
#include <cstdio>
#include <memory>
#include <optional>

namespace cutload::cli {
namespace {

struct CompareArgs {
    std::string predicted, measured, axes, measured_on = "workpiece", frame = "workpiece", average = "none", report_csv,
        trace_csv, zero;
    std::optional<double> offset_s, t_start_s, t_end_s;
    double cutoff_Hz = 1000;
    int flutes = 0;
    bool json = false, keep_zero = false;
};

force_model::Averaging averaging_of(const std::string& s) {
    if (s == "tooth") return force_model::Averaging::ToothPeriod;
    if (s == "rev") return force_model::Averaging::Revolution;
    return force_model::Averaging::None;
}

void print_scope(const force_model::ScopeMetrics& m) {
    static const char* axes[4] = {"x", "y", "z", "|F|"};
    for (int ax = 0; ax < 4; ++ax) {
        const auto& a = m.axes[ax];
        std::printf("%-12s %-3s %8zu %10.3f %9.3f %7.4f %10.3f %7.4f\n", ax == 0 ? m.scope.c_str() : "", axes[ax],
                    m.samples, a.mean_error_N, a.rmse_N, a.nrmse, a.peak_error_N, a.correlation);
    }
}

void print_zero(const force_model::Comparison& c, bool keep_zero) {
    if (!c.zero_removed) {
        std::printf("zero offset: not removed (%s)\n",
                    keep_zero ? "--keep-zero"
                              : "fewer than 100 samples where the prediction is in air; --zero-N gives it");
        return;
    }
    const char* source = "given";
    switch (c.zero.source) {
        case force_model::ZeroSource::LeadIn: source = "measured where the prediction is in air: idle lead-in"; break;
        case force_model::ZeroSource::IdleTail: source = "measured where the prediction is in air: idle tail"; break;
        case force_model::ZeroSource::Estimated:
            source = "measured where the prediction is in air: between tooth passes";
            break;
        case force_model::ZeroSource::Given:
        case force_model::ZeroSource::None: break;
    }
    std::printf("zero offset removed: (%.3f, %.3f, %.3f) N at %.4f s (%s); ", c.zero_N[0], c.zero_N[1], c.zero_N[2],
                c.zero.t_s, source);
    if (c.zero.drift_source == force_model::DriftSource::None)
        std::printf("drift: none found (none stands out from the noise, or the air samples span less than half "
                    "the window)\n");
    else
        std::printf("drift (%.4f, %.4f, %.4f) N/s (line through the air samples)\n", c.zero.drift_N_per_s[0],
                    c.zero.drift_N_per_s[1], c.zero.drift_N_per_s[2]);
}

void run_compare(const CompareArgs& a) {
    try {
        const force_model::PredictedTrace predicted = force_model::read_predicted_forces(a.predicted);
        app::CompareSettings settings;
        if (!a.axes.empty()) settings.axes = force_model::parse_axis_matrix(a.axes);
        settings.measured_on_workpiece = a.measured_on == "workpiece";
        settings.frame = a.frame == "machine" ? app::ForceFrame::Machine : app::ForceFrame::Workpiece;
        if (!a.zero.empty()) settings.zero_dyn_N = force_model::parse_force_vector(a.zero);
        force_model::CompareOptions& opt = settings.options;
        opt.offset_s = a.offset_s;
        if (a.t_start_s) opt.t_start_s = *a.t_start_s;
        if (a.t_end_s) opt.t_end_s = *a.t_end_s;
        opt.cutoff_Hz = a.cutoff_Hz;
        opt.averaging = averaging_of(a.average);
        opt.flutes = a.flutes;
        opt.remove_zero = !a.keep_zero;
        const app::MeasurementComparison r = app::compare_measurement(predicted, a.measured, settings);
        const force_model::Measurement& m = r.measured;
        const force_model::Comparison& c = r.comparison;

        if (!a.report_csv.empty()) force_model::write_comparison_csv(c, a.report_csv);
        if (!a.trace_csv.empty()) force_model::write_comparison_trace_csv(c, predicted.block_names, a.trace_csv);
        if (a.json) {
            nlohmann::json j = force_model::to_json(c);
            j["measured"] = {{"file", m.source}, {"format", m.format}, {"rate_Hz", m.rate_Hz}, {"samples", m.size()}};
            j["predicted"] = {{"file", a.predicted},
                              {"rows", predicted.samples.size()},
                              {"frame", app::force_frame_name(settings.frame)}};
            std::printf("%s\n", j.dump(2).c_str());
            return;
        }
        std::printf("measured: %s (%s, %.6g Hz, %zu samples, %.4f to %.4f s)\n", m.source.c_str(), m.format.c_str(),
                    m.rate_Hz, m.size(), m.t_s(0), m.t_s(m.size() - 1));
        // Said only when it is not the default, so the workpiece frame's report reads as before.
        if (settings.frame == app::ForceFrame::Machine)
            std::printf("frame: machine axes (predicted fx_machine_N, fy_machine_N, fz_machine_N)\n");
        if (c.offset_found)
            std::printf("offset: %+.6f s (cross-correlation, score %.4f): prediction time = measured time + offset\n",
                        c.offset_s, c.alignment_score);
        else
            std::printf("offset: %+.6f s (given)\n", c.offset_s);
        if (c.cutoff_Hz > 0)
            std::printf("filter: 4th-order Butterworth low-pass at %.6g Hz, forward and backward; ", c.cutoff_Hz);
        else
            std::printf("filter: none; ");
        std::printf("averaging: %s\n", force_model::averaging_name(c.averaging));
        print_zero(c, a.keep_zero);
        std::printf("%-12s %-3s %8s %10s %9s %7s %10s %7s\n", "scope", "ax", "samples", "mean_err_N", "rmse_N", "nrmse",
                    "peak_err_N", "corr");
        print_scope(c.overall);
        for (const auto& b : c.blocks) print_scope(b);
    } catch (const force_model::MeasurementError& e) {
        throw UsageError(e.what());
    }
}

void add_compare(CLI::App& app) {
    auto a = std::make_shared<CompareArgs>();
    auto* cmd = app.add_subcommand("compare", "Compare predicted forces with a dynamometer measurement");
    cmd->add_option("--predicted", a->predicted, "FORCES.csv or FORCES.bin written by cutload predict")
        ->required()
        ->check(CLI::ExistingFile);
    cmd->add_option("--measured", a->measured, "Dynamometer record: DynoWare CSV export or plain CSV t,fx,fy,fz")
        ->required()
        ->check(CLI::ExistingFile);
    cmd->add_option("--frame", a->frame,
                    "Axes the dynamometer measures in: workpiece (it turns with the part, as on a rotary table; "
                    "compared with fx_N, fy_N, fz_N) or machine (fixed to the bed; compared with fx_machine_N, "
                    "fy_machine_N, fz_machine_N of a prediction made with --machine). Without a machine, fx_N, "
                    "fy_N, fz_N are in machine axes too: keep workpiece")
        ->check(CLI::IsMember({"workpiece", "machine"}))
        ->capture_default_str();
    cmd->add_option("--axes", a->axes,
                    "Dynamometer-to-frame axis matrix (to --frame's axes), nine comma-separated numbers, row-major "
                    "(default identity)");
    cmd->add_option("--measured-on", a->measured_on,
                    "What the dynamometer carries: workpiece (its force is minus the tool's) or tool")
        ->check(CLI::IsMember({"workpiece", "tool"}))
        ->capture_default_str();
    cmd->add_option("--offset-s", a->offset_s,
                    "Time offset, prediction time = measured time + offset (default: by cross-correlation)");
    cmd->add_option("--from-s", a->t_start_s, "Start of the comparison window (prediction time)");
    cmd->add_option("--to-s", a->t_end_s, "End of the comparison window (prediction time)");
    cmd->add_option("--cutoff-hz", a->cutoff_Hz, "Zero-phase low-pass cut-off in Hz applied to both; 0: none")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
    cmd->add_option("--average", a->average, "Compare means per tooth period or per revolution")
        ->check(CLI::IsMember({"none", "tooth", "rev"}))
        ->capture_default_str();
    cmd->add_option("--flutes", a->flutes, "Number of flutes (for --average tooth)")->check(CLI::Range(1, 16));
    cmd->add_option("--report-csv", a->report_csv, "Write the metrics as CSV (scope, axis, metrics)");
    cmd->add_option("--trace-csv", a->trace_csv, "Write the compared series (for plots)");
    auto* zero_opt = cmd->add_option("--zero-N", a->zero,
                    "Zero offset FX,FY,FZ at the record's first sample, in its own channels (default: found where the "
                    "prediction is in air)");
    auto* keep = cmd->add_flag("--keep-zero", a->keep_zero,
                               "Keep the measured zero offset (default: subtract the zero offset and drift measured "
                               "where the prediction is in air)");
    keep->excludes(zero_opt);
    cmd->add_flag("--json", a->json, "Print the report as JSON");
    cmd->callback([a] {
        if (!a->report_csv.empty()) check_output_path(a->report_csv, "--report-csv");
        if (!a->trace_csv.empty()) check_output_path(a->trace_csv, "--trace-csv");
        run_compare(*a);
    });
}

const bool registered = register_command("compare", &add_compare);

}  // namespace
}  // namespace cutload::cli
