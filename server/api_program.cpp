// Routes of runs uploaded with an NC program: the commanded-vs-actual comparison, the program as
// uploaded, and feed optimizations (jobs that recommend per-block feeds and write the program back).
#include "core.hpp"
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

constexpr const char* kOptColumns =
    "id, run_id, state, progress, error, params, result, created_at, started_at, finished_at";

json optimization_json(const db::Stmt& st) {
    const std::int64_t id = st.i64(0), run = st.i64(1);
    auto opt_text = [&](int col) { return st.is_null(col) ? json(nullptr) : json(st.text(col)); };
    return {{"id", id},
            {"run_id", run},
            {"state", st.text(2)},
            {"progress", st.real(3)},
            {"error", opt_text(4)},
            {"params", column_json(st, 5)},
            {"result", column_json(st, 6)},
            {"created_at", st.text(7)},
            {"started_at", opt_text(8)},
            {"finished_at", opt_text(9)},
            {"links",
             {{"self", fmt::format("/api/v1/optimizations/{}", id)},
              {"program", fmt::format("/api/v1/optimizations/{}/program", id)},
              {"run", fmt::format("/api/v1/runs/{}", run)}}}};
}

json load_optimization(db::Connection& c, std::int64_t id) {
    auto st = c.prepare(fmt::format("SELECT {} FROM optimizations WHERE id = ?", kOptColumns));
    st.bind(1, id);
    if (!st.step()) not_found(fmt::format("optimization {} does not exist", id));
    return optimization_json(st);
}

json run_inputs(db::Connection& c, std::int64_t run_id, fs::path* upload_dir = nullptr) {
    auto st = c.prepare("SELECT inputs, upload_dir FROM runs WHERE id = ?");
    st.bind(1, run_id);
    if (!st.step()) not_found(fmt::format("run {} does not exist", run_id));
    if (upload_dir) *upload_dir = st.text(1);
    return json::parse(st.text(0));
}

void get_program(Core& core, Ctx& x) {
    const auto id = x.id();
    auto c = core.pool.get();
    require_done(*c, id);
    json body = require_program(*c, id);
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
    auto c = core.pool.get();
    fs::path dir;
    const json inputs = run_inputs(*c, id, &dir);
    if (!inputs.contains("nc_program"))
        throw ApiError(404, "no_program", fmt::format("run {} was uploaded without an NC program", id));
    std::ifstream in(core.data_dir / dir / inputs["nc_program"]["stored_as"].get<std::string>(), std::ios::binary);
    if (!in) not_found(fmt::format("run {}: the stored NC program is gone", id));
    std::ostringstream ss;
    ss << in.rdbuf();
    x.res.status = 200;
    x.res.set_content(ss.str(), "text/plain; charset=utf-8");
}

void create_optimization(Core& core, Ctx& x) {
    const auto run_id = x.id();
    json params = optimization_params(x.req.body.empty() ? json::object() : parse_json_body(x.req.body));
    auto c = core.pool.get();
    require_done(*c, run_id);
    const json inputs = run_inputs(*c, run_id);
    if (!inputs.contains("nc_program"))
        throw ApiError(409, "no_program",
                       fmt::format("run {} was uploaded without an NC program: feeds are recommended per program block", run_id));
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
        auto st = c->prepare("SELECT machine_id FROM runs WHERE id = ?");
        st.bind(1, run_id);
        if (st.step() && !st.is_null(0))
            if (const auto m = library_body(*c, "machines", st.i64(0)); m && (*m).value("max_feed_mm_min", 0.0) > 0)
                max_feed = std::min(max_feed, (*m)["max_feed_mm_min"].get<double>());
        params["max_feed_mm_min"] = max_feed;
    }
    if (!(params["min_feed_mm_min"].get<double>() < params["max_feed_mm_min"].get<double>()))
        bad_request(fmt::format("min_feed_mm_min {} is not below the highest cutting feed {} mm/min", params["min_feed_mm_min"].dump(),
                                params["max_feed_mm_min"].dump()));
    {
        auto st = c->prepare("SELECT count(*) FROM optimizations WHERE state IN ('queued','running')");
        st.step();
        if (st.i64(0) >= core.opt.max_pending_jobs) {
            x.res.set_header("Retry-After", "30");
            throw ApiError(429, "too_many_jobs",
                           fmt::format("{} optimizations are queued or running (limit {})", st.i64(0), core.opt.max_pending_jobs));
        }
    }
    c->prepare("INSERT INTO optimizations(run_id, state, params, created_at) VALUES (?, 'queued', ?, ?)")
        .bind(1, run_id)
        .bind(2, params.dump())
        .bind(3, db::now_iso())
        .run();
    const std::int64_t id = c->last_insert_id();
    core.jobs->notify();
    x.res.set_header("Location", fmt::format("/api/v1/optimizations/{}", id));
    x.reply(202, load_optimization(*c, id));
}

void list_optimizations(Core& core, Ctx& x) {
    const auto run_id = x.id();
    auto c = core.pool.get();
    run_inputs(*c, run_id);   // 404 for an unknown run
    auto st = c->prepare(fmt::format("SELECT {} FROM optimizations WHERE run_id = ? ORDER BY id DESC", kOptColumns));
    st.bind(1, run_id);
    json items = json::array();
    while (st.step()) items.push_back(optimization_json(st));
    x.reply(200, {{"items", items}});
}

void get_optimized_program(Core& core, Ctx& x) {
    const auto id = x.id();
    auto c = core.pool.get();
    auto st = c->prepare(
        "SELECT o.state, o.program, r.inputs FROM optimizations o JOIN runs r ON r.id = o.run_id WHERE o.id = ?");
    st.bind(1, id);
    if (!st.step()) not_found(fmt::format("optimization {} does not exist", id));
    if (st.text(0) != "done")
        throw ApiError(409, "not_done", fmt::format("optimization {} is {}: its program exists once it is done", id, st.text(0)));
    const json inputs = json::parse(st.text(2));
    std::string stem = fs::path(inputs["nc_program"].value("filename", std::string("program.nc"))).stem().string();
    for (char& ch : stem)
        if (!(std::isalnum(static_cast<unsigned char>(ch)) || ch == '-' || ch == '_' || ch == '.')) ch = '_';
    x.res.status = 200;
    x.res.set_header("Content-Disposition", fmt::format("attachment; filename=\"{}_opt.nc\"", stem));
    x.res.set_content(st.text(1), "text/plain; charset=utf-8");
}

void cancel_optimization(Core& core, Ctx& x) {
    const auto id = x.id();
    auto c = core.pool.get();
    c->prepare("UPDATE optimizations SET state = 'cancelled', finished_at = ? WHERE id = ? AND state = 'queued'")
        .bind(1, db::now_iso())
        .bind(2, id)
        .run();
    if (c->changes() == 0) {
        const json o = load_optimization(*c, id);
        if (o["state"] != "running" || !core.jobs->cancel_running(Jobs::Kind::Optimization, id))
            throw ApiError(409, "conflict", fmt::format("optimization {} is {}: only queued or running ones can be cancelled",
                                                        id, o["state"].get<std::string>()));
    }
    x.reply(202, load_optimization(*c, id));
}

void delete_optimization(Core& core, Ctx& x) {
    const auto id = x.id();
    auto c = core.pool.get();
    const json o = load_optimization(*c, id);
    if (o["state"] == "running")
        throw ApiError(409, "conflict",
                       fmt::format("optimization {} is running: cancel it first (POST /api/v1/optimizations/{}/cancel)", id, id));
    c->prepare("DELETE FROM optimizations WHERE id = ? AND state != 'running'").bind(1, id).run();
    x.res.status = 204;
}

}  // namespace

void add_program_routes(Core& core) {
    core.route("GET", "/api/v1/runs/{id}/program", Role::Read, [&core](Ctx& x) { get_program(core, x); });
    core.route("GET", "/api/v1/runs/{id}/program/source", Role::Read, [&core](Ctx& x) { get_program_source(core, x); });
    core.route("POST", "/api/v1/runs/{id}/optimizations", Role::Write, [&core](Ctx& x) { create_optimization(core, x); });
    core.route("GET", "/api/v1/runs/{id}/optimizations", Role::Read, [&core](Ctx& x) { list_optimizations(core, x); });
    core.route("GET", "/api/v1/optimizations/{id}", Role::Read, [&core](Ctx& x) {
        auto c = core.pool.get();
        x.reply(200, load_optimization(*c, x.id()));
    });
    core.route("GET", "/api/v1/optimizations/{id}/program", Role::Read, [&core](Ctx& x) { get_optimized_program(core, x); });
    core.route("POST", "/api/v1/optimizations/{id}/cancel", Role::Write, [&core](Ctx& x) { cancel_optimization(core, x); });
    core.route("DELETE", "/api/v1/optimizations/{id}", Role::Write, [&core](Ctx& x) { delete_optimization(core, x); });
}

}  // namespace cutload::server
