// The registry of job kinds `cutload serve` runs, and their handlers: a run (predict the forces
// of an uploaded dry run, and of its NC program's commanded motion) and a feed optimization.
// A new kind: its table (a migration with the job columns, db/jobs.hpp), its repository for what
// it stores, a handler here and one entry in service_job_kinds().
#include "jobs.hpp"

#include "program.hpp"
#include "results.hpp"
#include "db/runs.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <exception>
#include <functional>
#include <string_view>


namespace cutload::server {
namespace fs = std::filesystem;
namespace {

constexpr std::string_view kSpoolPrefix = "forces-";

// Predicts run ctx.id from its stored inputs and stores the results, alerts and webhook deliveries
// with state done. The use case checks ctx.cancel between its phases (ingest, program, mapping,
// predict, commanded) and every few angle steps; storing checks it before its commit.
std::optional<std::string> predict_run(JobContext& ctx, db::Store& store, const ServerOptions& opt,
                                       const fs::path& data_dir, Metrics& metrics, const std::function<void()>& on_alerts) {
    const std::int64_t id = ctx.id;
    json inputs;
    fs::path dir;
    std::optional<std::int64_t> base_run;
    {
        const auto run = store.session()->runs().get(id);
        if (!run) return std::nullopt;   // deleted meanwhile
        dir = data_dir / run->upload_dir;
        inputs = json::parse(run->inputs_json);
        base_run = run->base_run;
    }
    app::RunInput in = run_input(inputs, dir, opt.use_opencl);
    in.limits = work_limits(opt);
    const force_model::StockPtr base = load_base_stock(store, base_run);
    in.base_stock = base.get();

    // The forces series is built as the engine writes its rows, spooled beside the uploads, so
    // the job's memory does not grow with the log's length. One spool per claim: a claimant that
    // lost its lease (stalled) may still be writing its own while the next one writes another.
    std::optional<ForceSeriesSpool> forces;
    const std::string spool_name = fmt::format("{}{:016x}.spool", kSpoolPrefix, std::hash<std::string>{}(ctx.claim));
    in.rows_out = app::RunInput::RowsOut{
        [&](const std::vector<std::string>&, double expected_rows) {
            forces.emplace(dir / spool_name, force_series_first_level(expected_rows, opt.max_raw_rows));
        },
        [&](std::span<const force_model::ForceSample> rows) { forces->add(rows); }};
    // A run of the log alone is walked as it is read: its motion series is spooled beside the
    // forces rather than held whole (app::RunInput::keep_motion).
    in.keep_motion = false;
    in.motion_out = [&](const motion_io::MotionModel& piece) { forces->add_motion(piece); };

    // Stock checkpoints for the windows recomputed later (app/checkpoints.hpp), beside the uploads.
    // An earlier claim's (a process that died) may be of another device or version: this claim
    // makes its own.
    const fs::path checkpoints = checkpoints_dir(dir);
    app::remove_checkpoints(checkpoints);
    if (opt.checkpoint_every_s > 0) in.checkpoints = app::CheckpointFolder{checkpoints, opt.checkpoint_every_s};

    app::Control control;
    control.cancel = &ctx.cancel;
    control.progress = [&](app::Phase, double f) { ctx.progress(f); };
    // A run that fails or is stopped is never recomputed: its checkpoints go when anything below
    // throws, while this claim still holds the run (a claim lost to another process is cancelled
    // too, and must leave that one's files).
    struct DropCheckpointsOnThrow {
        const fs::path& dir;
        db::Store& store;
        const JobContext& ctx;
        int exceptions = std::uncaught_exceptions();
        ~DropCheckpointsOnThrow() {
            if (std::uncaught_exceptions() <= exceptions) return;
            try {
                if (store.session()->jobs().holds(db::kRunQueue, ctx.id, ctx.claim)) app::remove_checkpoints(dir);
            } catch (const std::exception& e) {
                spdlog::warn("run {}: its stock checkpoints were not removed: {}", ctx.id, e.what());
            }
        }
    } drop_on_throw{checkpoints, store, ctx};
    const app::RunResult r = app::predict_run(in, control);
    if (forces) forces->finish();
    for (const std::string& w : r.warnings) spdlog::info("run {}: {}", id, w);
    if (ctx.cancel) throw force_model::Cancelled();   // nothing stored for a run cancelled at the finish
    int alerts = 0;
    {
        auto s = store.session();
        std::optional<ProgramResult> program_result;
        if (r.program) program_result.emplace(ProgramResult{*r.program, *r.commanded, inputs["nc_program"].value("filename", "")});
        // Only the claim that holds the run stores it: one whose lease ended (the process stalled
        // and another claimed the run) finds the run no longer its own and stores nothing.
        db::Transaction tx(*s);
        if (!s->jobs().holds(db::kRunQueue, id, ctx.claim)) return std::nullopt;
        const json kinematics = kinematics_summary(r.tool_axis, r.tool_lean_deg, r.fixed_tilt, r.turning);
        alerts = store_result(*s, id, r.motion, r.prediction, program_result ? &*program_result : nullptr,
                              opt.limit_alerts, &ctx.cancel, forces ? &*forces : nullptr, in.machine ? &kinematics : nullptr,
                              r.motion_tool_axis);
        tx.commit();
        // Spools of earlier claims of this run whose process died: the run is stored, they are not needed.
        std::error_code ec;
        for (const auto& e : fs::directory_iterator(dir, ec)) {
            const std::string name = e.path().filename().string();
            if (name.starts_with(kSpoolPrefix) && name.ends_with(".spool")) fs::remove(e.path(), ec);
        }
        app::remove_unfinished_checkpoints(checkpoints);
        // One run's results are one transaction, so the WAL grew by about their size: empty it
        // now rather than leave it at the journal_size_limit until the next checkpoint
        // (docs/api.md, "Disk").
        try {
            s->reclaim_space();
        } catch (const std::exception& e) {   // the run is stored; a busy checkpoint is retried by the next
            spdlog::warn("run {}: checkpoint after storing: {}", id, e.what());
        }
    }
    if (alerts > 0) {
        metrics.alerts_raised(alerts);
        on_alerts();
    }
    return fmt::format(" ({} samples, {} alerts{})", r.rows, alerts,
                       r.program ? ", with the commanded prediction" : "");
}

}  // namespace

std::vector<JobKind> service_job_kinds(db::Store& store, const ServerOptions& opt, const fs::path& data_dir,
                                       Metrics& metrics, std::function<void()> on_alerts) {
    std::vector<JobKind> kinds;
    kinds.push_back(JobKind{
        "run", db::kRunQueue, {},
        [&store, &opt, data_dir, &metrics, on_alerts](JobContext& ctx) {
            return predict_run(ctx, store, opt, data_dir, metrics, on_alerts);
        },
        {"cutload_jobs_total", "Prediction jobs finished, by final state.", "cutload_jobs_queued", "Runs waiting for a worker."}});
    kinds.push_back(JobKind{
        "optimization", db::kOptimizationQueue, {},
        [&store, &opt, data_dir](JobContext& ctx) -> std::optional<std::string> {
            if (!run_optimization(store, data_dir, opt.use_opencl, ctx.id, ctx.claim, ctx.cancel, ctx.progress)) return std::nullopt;
            return std::string();
        },
        {"cutload_optimizations_total", "Feed optimization jobs finished, by final state.", "cutload_optimizations_queued",
         "Feed optimizations waiting for a worker."}});
    return kinds;
}

}  // namespace cutload::server
