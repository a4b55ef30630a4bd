// cutload predict LOG --spec RUN.json --out FORCES.csv [--blocks BLOCKS.csv] [--device opencl|cpu]
// Reads and repairs the dry-run log, predicts cutting forces over it and writes the per-step and
// per-block results; prints a short summary with the flagged blocks.
#include "commands.hpp"
#include "predict_program.hpp"
#include "app/predict_run.hpp"

#include <cstdio>
#include <initializer_list>
#include <memory>
#include <unistd.h>

namespace cutload::cli {
namespace {

struct PredictArgs {
    std::string log, spec, out, blocks, device = "auto", start_stock, save_stock, machine, machine_errors;
    double tool_length_mm = 0;
    std::string window;   // FROM:TO in seconds of the log's time
    std::string checkpoints;   // folder of stock checkpoints
    bool quiet = false;
    double step_ms = motion_io::ReadOptions{}.step_ms;
    app::LogFormat format;
    ProgramOptions program;
    app::WorkLimits limits;
};

// "12.5:14" -> [12.5, 14) s.
force_model::TimeWindow parse_window(const std::string& text) {
    const std::size_t colon = text.find(':');
    force_model::TimeWindow w;
    std::size_t used_from = 0, used_to = 0;
    try {
        if (colon == std::string::npos) throw std::invalid_argument("no colon");
        const std::string from = text.substr(0, colon), to = text.substr(colon + 1);
        w.from_s = std::stod(from, &used_from);
        w.to_s = std::stod(to, &used_to);
        if (used_from != from.size() || used_to != to.size()) throw std::invalid_argument("trailing text");
    } catch (const std::exception&) {
        throw CLI::ValidationError("--window", "'" + text + "' is not FROM:TO in seconds of the log's time (e.g. 120:121.5)");
    }
    return w;
}

void run_predict(const PredictArgs& a) {
    // A long prediction must not end in "cannot write": check every output place first.
    for (const auto& [path, option] : {std::pair{a.out, "--out"}, {a.blocks, "--blocks"}, {a.save_stock, "--save-stock"},
                                       {a.program.compare_csv, "--compare"}, {a.program.commanded_out, "--commanded-out"}})
        if (!path.empty()) check_output_path(path, option);
    app::RunInput in;
    // Opened while the spec and the log are read.
    in.device_ready = app::prepare_device(a.device);
    in.spec = force_model::load_run_spec(a.spec);
    in.log_path = a.log;
    in.read = reader_options(a.format, a.step_ms);
    in.program = program_source(a.program);
    in.commanded_from_log = a.program.commanded_from_log;
    force_model::StockPtr base;
    if (!a.start_stock.empty()) base = force_model::load_stock(a.start_stock);
    in.base_stock = base.get();
    in.limits = a.limits;
    in.keep_final_stock = !a.save_stock.empty();
    if (!a.machine.empty()) in.machine = app::load_machine_definition(a.machine, a.machine_errors);
    in.tool_length_mm = a.tool_length_mm;
    if (!a.window.empty()) in.window = parse_window(a.window);
    if (!a.checkpoints.empty()) in.checkpoints = app::CheckpointFolder{a.checkpoints};
    in.keep_motion = false;   // nothing below reads it: a log alone is walked as it is read

    // The rows go to FORCES.csv (or FORCES.bin) as they come: an hour-long log writes about 10^8 of them.
    // With a machine the rows carry their forces in machine axes too (docs/formats.md, FORCES.csv).
    force_model::ForcesColumns columns;
    columns.machine_axes = in.machine != nullptr;
    const std::unique_ptr<force_model::ForcesWriter> forces = force_model::open_forces_writer(a.out, columns);
    in.rows_out = app::RunInput::RowsOut{[&](const std::vector<std::string>& names, double) { forces->set_block_names(names); },
                                         [&](std::span<const force_model::ForceSample> rows) { forces->write(rows); }};

    app::Control control;
    int last_pct = -1;
    const bool show_progress = !a.quiet && isatty(STDERR_FILENO);
    if (show_progress)
        control.progress = [&last_pct](app::Phase phase, double f) {
            if (phase != app::Phase::Predict && phase != app::Phase::Commanded) return;
            const int pct = int(f * 100);
            if (pct / 10 != last_pct / 10) std::fprintf(stderr, "\rpredicting... %3d%%", pct);
            last_pct = pct;
        };
    const app::RunResult r = app::predict_run(in, control);
    if (show_progress) std::fprintf(stderr, "\r                    \r");
    if (!r.device_note.empty()) std::fprintf(stderr, "cutload: note: %s\n", r.device_note.c_str());
    for (const std::vector<motion_io::IngestWarning>* list :
         std::initializer_list<const std::vector<motion_io::IngestWarning>*>{&r.ingest.warnings, &r.sampling.warnings})
        for (const auto& w : *list)
            // What changes what was predicted from: coarse data, and readings dropped as glitches or
            // kept although out of range (a run is never made from them silently).
            if (w.code == "position_quantized" || w.code == "sampling_coarse" || w.code == "glitch_dropped" ||
                w.code == "out_of_range")
                std::fprintf(stderr, "cutload: warning: %s: %s\n", w.code.c_str(), w.message.c_str());
    for (const std::string& w : r.warnings) std::fprintf(stderr, "cutload: warning: %s\n", w.c_str());
    const force_model::Prediction& p = r.prediction;

    forces->commit();
    // With a commanded path, BLOCKS.csv also carries the comparison: finish_program_run writes it.
    if (!a.blocks.empty() && !r.commanded) force_model::write_blocks_csv(p, a.blocks);
    if (!a.save_stock.empty()) force_model::save_stock(*p.final_stock, a.save_stock);

    const auto& s = p.stats;
    std::printf("device: %s\n", s.device.c_str());
    std::printf("simulated %.3f s in %.3f s wall (%.1fx real time); %zu angle steps, %zu cutting\n", s.simulated_s,
                s.wall_s, s.wall_s > 0 ? s.simulated_s / s.wall_s : 0.0, s.steps, s.cutting_steps);
    if (in.window) std::printf("window walked from %.3f s (%s)\n", r.walked_from_s, r.resumed ? "a stock checkpoint" : "the log's start");
    std::size_t flagged = 0;
    for (const auto& b : p.blocks) {
        if (b.flags.empty()) continue;
        ++flagged;
        std::printf("  %s%s:", b.block.c_str(), b.tool >= 0 ? (" (T" + std::to_string(b.tool) + ")").c_str() : "");
        for (const auto& f : b.flags) std::printf(" %s@%.3fs=%.4g", f.flag.c_str(), f.t_s, f.value);
        std::printf("\n");
    }
    std::printf("%zu of %zu blocks flagged; forces -> %s%s%s\n", flagged, p.blocks.size(), a.out.c_str(),
                a.blocks.empty() ? "" : ", blocks -> ", a.blocks.c_str());
    if (r.sampling.coarse())
        std::printf("data: COARSE (%s%s%s): the log cannot fully carry this prediction; see the warnings\n",
                    r.sampling.position_quantized ? "position_quantized" : "",
                    r.sampling.position_quantized && r.sampling.sampling_coarse ? ", " : "",
                    r.sampling.sampling_coarse ? "sampling_coarse" : "");
    finish_program_run(a.program, r, a.blocks);
}

void add_predict(CLI::App& app) {
    auto a = std::make_shared<PredictArgs>();
    auto* cmd = app.add_subcommand("predict", "Predict cutting forces from a dry-run log and flag overloaded blocks");
    cmd->add_option("LOG", a->log, "Dry-run motion log (CSV or SHDR)")->required()->check(CLI::ExistingFile);
    cmd->add_option("--spec", a->spec, "Run spec (RUN.json: tool, material, stock, limits, resolution)")
        ->required()
        ->check(CLI::ExistingFile);
    cmd->add_option("--out", a->out, "FORCES.csv: one row per angle step while cutting (a name ending in .bin: FORCES.bin, compact binary)")->required();
    cmd->add_option("--blocks", a->blocks, "BLOCKS.csv: one row per NC block with peaks and flags");
    cmd->add_option("--device", a->device, "opencl, cpu, or auto (OpenCL when a device exists)")
        ->check(CLI::IsMember({"opencl", "cpu", "auto"}))
        ->capture_default_str();
    cmd->add_option("--start-stock", a->start_stock, "Start from a stock saved by an earlier run (--save-stock)")
        ->check(CLI::ExistingFile);
    cmd->add_option("--save-stock", a->save_stock, "Save the final in-process stock (binary) for a later run");
    cmd->add_option("--step-ms", a->step_ms, "Resampling step of the motion model in ms (0.01 to 1000)")
        ->check(CLI::Range(0.01, 1000.0))
        ->capture_default_str();
    cmd->add_option("--machine", a->machine,
                    "Machine definition (JSON, docs/machines.md): the log's x, y, z and a, b, c are its axes, turned "
                    "into the tool's motion against the part (five-axis: wherever it can reach the stock the tool stands at "
                    "one orientation, vertical or tilted, a vertical one may turn about its axis, docs/five_axis.md); a "
                    "--program is then read in its axes (A/B/C words, or G43.4/G43.5 tool-centre-point blocks, docs/nc_program.md)")
        ->check(CLI::ExistingFile);
    cmd->add_option("--machine-errors", a->machine_errors, "Geometric errors of the --machine (JSON, docs/machines.md)")
        ->check(CLI::ExistingFile);
    cmd->add_option("--tool-length-mm", a->tool_length_mm, "With --machine: gauge point to tool tip in mm")
        ->check(CLI::Range(0.0, 1000.0))
        ->capture_default_str();
    auto* window = cmd->add_option("--window", a->window,
                                   "FROM:TO, seconds of the log's time: only that stretch is predicted, at full "
                                   "resolution, the very rows the whole run gives there (the motion before it is walked "
                                   "for its removal alone; docs/force_model.md, \"A window on demand\")");
    auto* checkpoints = cmd->add_option("--checkpoints", a->checkpoints,
                                        "Folder of stock checkpoints: a whole run keeps up to eight there (one a minute of "
                                        "motion at most, where the tool moves in air), a --window of the same log, spec and "
                                        "start stock walks from the last one before it (docs/force_model.md, \"Stock "
                                        "checkpoints\")");
    checkpoints->excludes("--machine");
    cmd->add_flag("-q,--quiet", a->quiet, "No progress display");
    add_work_limit_options(*cmd, a->limits.max_force_rows, a->limits.max_stock_cells, a->limits.max_job_memory_mb);
    add_program_options(*cmd, a->program, true);
    add_log_options(*cmd, a->format);
    for (const char* other : {"--save-stock", "--machine", "--compare", "--commanded-out", "--commanded-from-log"})
        window->excludes(other);
    cmd->callback([a] { run_predict(*a); });
}

const bool registered = register_command("predict", &add_predict);

}  // namespace
}  // namespace cutload::cli
