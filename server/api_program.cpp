// Routes of runs uploaded with an NC program: the commanded-vs-actual comparison, the program as
// uploaded, and feed optimizations (jobs that recommend per-block feeds and write the program back).
#include "core.hpp"
#include "db/optimizations.hpp"
#include "db/runs.hpp"
#include "jobs.hpp"
#include "library.hpp"
#include "program.hpp"

#include <fmt/format.h>

#include <cctype>
#include <fstream>
#include <sstream>

namespace cutload::server {
namespace fs = std::filesystem;
namespace {

json optimization_json(const db::OptimizationRecord& o) {
    return {{"id", o.id},
            {"run_id", o.run_id},
            {"state", db::to_text(o.state)},
            {"progress", o.progress},
            {"error", or_null(o.error)},
            {"params", json::parse(o.params_json)},
            {"result", stored_json(o.result_json)},
            {"created_at", o.created_at},
            {"started_at", or_null(o.started_at)},
            {"finished_at", or_null(o.finished_at)},
            {"links",
             {{"self", fmt::format("/api/v1/optimizations/{}", o.id)},
              {"program", fmt::format("/api/v1/optimizations/{}/program", o.id)},
              {"run", fmt::format("/api/v1/runs/{}", o.run_id)}}}};
}

json load_optimization(db::Session& s, std::int64_t id) {
    const auto o = s.optimizations().get(id);
    if (!o) not_found(fmt::format("optimization {} does not exist", id));
    return optimization_json(*o);
}

db::RunRecord require_run(db::Session& s, std::int64_t run_id) {
    auto run = s.runs().get(run_id);
    if (!run) not_found(fmt::format("run {} does not exist", run_id));
    return std::move(*run);
}

void get_program(Core& core, Ctx& x) {
    const auto id = x.id();
    auto s = core.session();
    require_done(*s, id);
    json body = require_program(*s, id);
    if (x.wants_csv()) {
        x.res.status = 200;
        x.res.set_content(comparison_csv(body["blocks"]), "text/csv");
        return;
    }
    body["run_id"] = id;
    x.reply(200, body);
}

void get_program_source(Core& core, Ctx& x) {
    const auto id = x.id();
    const db::RunRecord run = require_run(*core.session(), id);
    const json inputs = json::parse(run.inputs_json);
    if (!inputs.contains("nc_program"))
        throw ApiError(404, "no_program", fmt::format("run {} was uploaded without an NC program", id));
    std::ifstream in(core.data_dir / run.upload_dir / inputs["nc_program"]["stored_as"].get<std::string>(), std::ios::binary);
    if (!in) not_found(fmt::format("run {}: the stored NC program is gone", id));
    std::ostringstream ss;
    ss << in.rdbuf();
    x.res.status = 200;
    x.res.set_content(ss.str(), "text/plain; charset=utf-8");
}

void create_optimization(Core& core, Ctx& x) {
    const auto run_id = x.id();
    json params = optimization_params(x.json_body().value_or(json::object()));
    auto s = core.session();
    require_done(*s, run_id);
    const db::RunRecord run = require_run(*s, run_id);
    const json inputs = json::parse(run.inputs_json);
    if (!inputs.contains("nc_program"))
        throw ApiError(409, "no_program",
                       fmt::format("run {} was uploaded without an NC program: feeds are recommended per program block", run_id));
    // The optimizer predicts the log's motion as it stands (three axes); a five-axis run's log is
    // the machine's axes, which only the run's own prediction turns into the tool's motion.
    if (inputs.contains("kinematics"))
        throw ApiError(409, "kinematics_unsupported",
                       fmt::format("run {} was uploaded with the machine's kinematics: feed optimization of five-axis runs "
                                   "is not built yet (docs/five_axis.md)",
                                   run_id));
    // The job would fail on these; say so now.
    const auto spec = force_model::parse_run_spec(inputs["spec"]);
    const auto& l = spec.limits;
    if (l.force_N <= 0 && l.torque_Nm <= 0 && l.power_kW <= 0 && l.chip_mm <= 0 && l.bending_MPa <= 0)
        throw ApiError(409, "no_limits",
                       fmt::format("run {}: its spec sets none of limits.force_N, torque_Nm, power_kW, chip_mm, bending_MPa, "
                                   "so there is nothing to aim the feeds at",
                                   run_id));
    if (params["max_feed_mm_min"].is_null()) {
        // The machine's feed range when the run names a machine that states one; never above 90 %
        // of the rapid feed, where a cutting move would read as a rapid in the log.
        double max_feed = 0.9 * l.rapid_feed_mm_min;
        if (run.machine_id)
            if (const auto m = library_body(*s, db::LibraryKind::Machine, *run.machine_id); m && (*m).value("max_feed_mm_min", 0.0) > 0)
                max_feed = std::min(max_feed, (*m)["max_feed_mm_min"].get<double>());
        params["max_feed_mm_min"] = max_feed;
    }
    if (!(params["min_feed_mm_min"].get<double>() < params["max_feed_mm_min"].get<double>()))
        bad_request(fmt::format("min_feed_mm_min {} is not below the highest cutting feed {} mm/min", params["min_feed_mm_min"].dump(),
                                params["max_feed_mm_min"].dump()));
    if (const auto pending = s->jobs().count(db::kOptimizationQueue, {db::JobState::Queued, db::JobState::Running});
        pending >= core.opt.max_pending_jobs) {
        x.res.set_header("Retry-After", "30");
        throw ApiError(429, "too_many_jobs",
                       fmt::format("{} optimizations are queued or running (limit {})", pending, core.opt.max_pending_jobs));
    }
    const std::int64_t id = s->optimizations().create(run_id, params.dump(), db::now_iso());
    core.jobs->notify();
    x.res.set_header("Location", fmt::format("/api/v1/optimizations/{}", id));
    x.reply(202, load_optimization(*s, id));
}

void list_optimizations(Core& core, Ctx& x) {
    const auto run_id = x.id();
    auto s = core.session();
    require_run(*s, run_id);   // 404 for an unknown run
    json items = json::array();
    for (const auto& o : s->optimizations().of_run(run_id)) items.push_back(optimization_json(o));
    x.reply(200, {{"items", items}});
}

void get_optimized_program(Core& core, Ctx& x) {
    const auto id = x.id();
    auto s = core.session();
    const auto opt = s->optimizations().program(id);
    if (!opt) not_found(fmt::format("optimization {} does not exist", id));
    if (opt->state != db::JobState::Done)
        throw ApiError(409, "not_done",
                       fmt::format("optimization {} is {}: its program exists once it is done", id, db::to_text(opt->state)));
    const json inputs = json::parse(require_run(*s, opt->run_id).inputs_json);
    std::string stem = fs::path(inputs["nc_program"].value("filename", std::string("program.nc"))).stem().string();
    for (char& ch : stem)
        if (!(std::isalnum(static_cast<unsigned char>(ch)) || ch == '-' || ch == '_' || ch == '.')) ch = '_';
    x.res.status = 200;
    x.res.set_header("Content-Disposition", fmt::format("attachment; filename=\"{}_opt.nc\"", stem));
    x.res.set_content(opt->program.value_or(""), "text/plain; charset=utf-8");
}

void cancel_optimization(Core& core, Ctx& x) {
    const auto id = x.id();
    auto s = core.session();
    if (!s->jobs().cancel_queued(db::kOptimizationQueue, id, db::now_iso())) {
        const auto o = s->optimizations().get(id);
        if (!o) not_found(fmt::format("optimization {} does not exist", id));
        if (o->state != db::JobState::Running || !core.jobs->cancel_running(db::kOptimizationQueue, id))
            throw ApiError(409, "conflict", fmt::format("optimization {} is {}: only queued or running ones can be cancelled",
                                                        id, db::to_text(o->state)));
    }
    x.reply(202, load_optimization(*s, id));
}

void delete_optimization(Core& core, Ctx& x) {
    const auto id = x.id();
    auto s = core.session();
    const auto o = s->optimizations().get(id);
    if (!o) not_found(fmt::format("optimization {} does not exist", id));
    if (o->state == db::JobState::Running)
        throw ApiError(409, "conflict",
                       fmt::format("optimization {} is running: cancel it first (POST /api/v1/optimizations/{}/cancel)", id, id));
    s->optimizations().remove_unless_running(id);
    x.res.status = 204;
}

}  // namespace

void add_program_routes(Core& core) {
    core.route({"GET", "/api/v1/runs/{id}/program", Role::Read,
                {path_id(), query_string("format", "csv: the blocks as CSV (same as Accept: text/csv)").one_of({"json", "csv"})}},
               [&core](Ctx& x) { get_program(core, x); });
    core.route({"GET", "/api/v1/runs/{id}/program/source", Role::Read, {path_id()}},
               [&core](Ctx& x) { get_program_source(core, x); });
    core.route({"POST", "/api/v1/runs/{id}/optimizations", Role::Write, {path_id()}, Body::OptionalJson},
               [&core](Ctx& x) { create_optimization(core, x); });
    core.route({"GET", "/api/v1/runs/{id}/optimizations", Role::Read, {path_id()}},
               [&core](Ctx& x) { list_optimizations(core, x); });
    core.route({"GET", "/api/v1/optimizations/{id}", Role::Read, {path_id()}}, [&core](Ctx& x) {
        auto s = core.session();
        x.reply(200, load_optimization(*s, x.id()));
    });
    core.route({"GET", "/api/v1/optimizations/{id}/program", Role::Read, {path_id()}},
               [&core](Ctx& x) { get_optimized_program(core, x); });
    core.route({"POST", "/api/v1/optimizations/{id}/cancel", Role::Write, {path_id()}},
               [&core](Ctx& x) { cancel_optimization(core, x); });
    core.route({"DELETE", "/api/v1/optimizations/{id}", Role::Write, {path_id()}},
               [&core](Ctx& x) { delete_optimization(core, x); });
}

}  // namespace cutload::server
