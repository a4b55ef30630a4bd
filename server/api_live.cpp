// Live runs: POST /api/v1/live starts one, POST /api/v1/live/{id}/stop closes it, GET
// /api/v1/live/{id} is what the run page polls while it is live (status, force rows after a
// cursor, blocks after an index). docs/api.md, "Live runs".
#include "core.hpp"
#include "live_runs.hpp"
#include "library.hpp"
#include "live_source.hpp"
#include "spec_refs.hpp"

#include "app/work_bounds.hpp"
#include "db/live.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <random>

namespace cutload::server {

namespace {

// The key map as a JSON object in the format of a --map file (docs/formats.md), read by the
// same loader: written to a scratch file in the data folder first.
motion_io::ShdrKeyMap key_map(Core& c, const json& j) {
    if (!j.is_object()) throw ApiError(400, "bad_request", "key_map: must be a JSON object (a channel map, docs/formats.md)");
    std::random_device rd;
    const auto dir = c.data_dir / "tmp";
    std::filesystem::create_directories(dir);
    const auto path = dir / fmt::format("key_map_{:016x}.json", (std::uint64_t(rd()) << 32) | rd());
    {
        std::ofstream out(path, std::ios::binary);
        out << j.dump();
    }
    try {
        auto m = motion_io::load_shdr_key_map(path.string());
        std::filesystem::remove(path);
        return m;
    } catch (const motion_io::IngestError& e) {
        std::filesystem::remove(path);
        std::string what = e.what();
        if (const auto at = what.find(path.string()); at != std::string::npos) what.replace(at, path.string().size(), "key_map");
        throw ApiError(400, "bad_request", what);
    }
}

double number_in(const json& body, const char* key, double fallback, double lo, double hi) {
    if (!body.contains(key)) return fallback;
    if (!body[key].is_number() || !std::isfinite(body[key].get<double>()) || body[key].get<double>() < lo ||
        body[key].get<double>() > hi)
        throw ApiError(400, "bad_request", fmt::format("{}: must be a number from {} to {}", key, lo, hi));
    return body[key].get<double>();
}

void create_live(Core& c, Ctx& x) {
    const json body = *x.json_body();
    if (!body.is_object()) bad_request("request body: must be a JSON object");
    if (!body.contains("spec")) throw ApiError(400, "bad_spec", "spec: required (a run spec, docs/run_spec.md)");
    for (const char* k : {"name", "program"})
        if (body.contains(k) && !body[k].is_string()) bad_request(fmt::format("{}: must be text", k));
    auto s = c.session();
    Resolved r = resolve_spec(*s, body["spec"], x.req);
    // Without a source the machine's own (spec.machine_id, its live_source in the library); the
    // request's key_map and sampling win over the machine's.
    json machine_source;
    if (!body.contains("source")) {
        if (!r.machine_id) bad_request("source: required (adapter HOST:PORT, or agent URL and device), or a spec.machine_id whose machine has a live_source");
        const auto m = library_body(*s, db::LibraryKind::Machine, *r.machine_id);
        if (!m || !m->contains("live_source"))
            bad_request(fmt::format("source: required: machine {} has no live_source in the library", *r.machine_id));
        machine_source = (*m)["live_source"];
    }
    const std::string source =
        body.contains("source") ? live_source_address(body["source"], "source") : live_source_address(machine_source, "machine live_source");
    auto from_machine = [&](const char* k) { return machine_source.is_object() ? machine_source.value(k, json(nullptr)) : json(nullptr); };
    const json key_map_json = body.contains("key_map") ? body["key_map"] : from_machine("key_map");
    app::LiveOptions opt;
    if (!key_map_json.is_null()) opt.keys = key_map(c, key_map_json);
    const json sampling = body.contains("sampling") ? body["sampling"] : from_machine("sampling");
    if (!sampling.is_null()) {
        if (!sampling.is_string() || (sampling != "event" && sampling != "polled"))
            bad_request("sampling: must be 'event' (values sent on change) or 'polled' (re-sent at a polling rate)");
        opt.polled = sampling == "polled";
    }
    opt.step_ms = number_in(body, "step_ms", 1.0, 0.01, 1000);
    opt.idle_timeout = std::chrono::milliseconds(std::llround(1000 * number_in(body, "idle_timeout_s", 300, 0, 86400)));
    opt.clock_batch_readings = std::size_t(number_in(body, "clock_batch_readings", 64, 16, 1024));
    opt.reorder_horizon_s = number_in(body, "reorder_horizon_s", 0.1, 0, 1);
    // A live run has no length to estimate up front: it closes at the job memory limit instead.
    opt.max_motion_samples = std::size_t(c.opt.max_job_memory_mb * 1e6 / app::kJobBytesPerMotionSample);
    opt.device = force_model::Device::Cpu;   // one live run must not hold the OpenCL device from the jobs
    opt.spec = force_model::parse_run_spec(r.spec);
    db::NewRun run;
    if (body.contains("name")) run.name = body["name"].get<std::string>();
    if (body.contains("program")) run.program = body["program"].get<std::string>();
    run.machine_id = r.machine_id;
    run.tool_id = r.tool_id;
    run.material_id = r.material_id;
    const json live{{"source", source},
                    {"sampling", opt.polled ? "polled" : "event"},
                    {"step_ms", opt.step_ms},
                    {"idle_timeout_s", double(opt.idle_timeout.count()) / 1000.0},
                    {"key_map", key_map_json}};
    run.inputs_json = json{{"live", live}, {"spec", r.spec}}.dump();
    run.created_at = db::now_iso();
    const std::int64_t id = c.live->start(run, live, source, std::move(opt));
    x.reply(201, {{"id", id},
                  {"state", "live"},
                  {"source", source},
                  {"links", {{"run", fmt::format("/api/v1/runs/{}", id)},
                             {"live", fmt::format("/api/v1/live/{}", id)},
                             {"stop", fmt::format("/api/v1/live/{}/stop", id)}}}});
}

json state_json(std::int64_t id, const LiveState& st) {
    return {{"id", id},
            {"state", st.open ? "live" : "closed"},
            {"connection", st.connection},
            {"lag_ms", st.lag_ms},
            {"machine_t_s", st.machine_t_s},
            {"rows", st.rows},
            {"alerts", st.alerts},
            {"gaps", st.gaps},
            {"end_reason", or_null(st.end_reason)}};
}

void get_live(Core& c, Ctx& x) {
    const std::int64_t id = x.id();
    const auto st = c.live->state(id);
    if (!st) not_found(fmt::format("run {} is not a live run", id));
    json out = state_json(id, *st);
    const std::int64_t after = *x.param_int("after");
    const std::int64_t from_block = *x.param_int("from_block");
    const auto max_points = std::size_t(*x.param_int("max_points"));
    auto s = c.session();
    // Rows after the cursor, at most 64 chunks an answer; decimated to max_points by keeping, of
    // each run of rows, the one with the largest resultant (a peak never disappears from the plot).
    const auto chunks = s->live().chunks(id, after, 64);
    std::vector<force_model::ForceSample> rows;
    std::int64_t next = after;
    for (const auto& ch : chunks) {
        const auto r = LiveRuns::unpack_rows(ch.data);
        rows.insert(rows.end(), r.begin(), r.end());
        next = ch.seq;
    }
    const std::size_t per = std::max<std::size_t>(1, (rows.size() + max_points - 1) / max_points);
    json t = json::array(), f = json::array(), fx = json::array(), fy = json::array(), fz = json::array();
    for (std::size_t i = 0; i < rows.size(); i += per) {
        std::size_t best = i;
        double best_f = -1;
        for (std::size_t k = i; k < std::min(rows.size(), i + per); ++k) {
            const auto& q = rows[k];
            const double v = std::sqrt(double(q.fx_N) * q.fx_N + double(q.fy_N) * q.fy_N + double(q.fz_N) * q.fz_N);
            if (v > best_f) best_f = v, best = k;
        }
        t.push_back(rows[best].t_s);
        f.push_back(best_f);
        fx.push_back(rows[best].fx_N);
        fy.push_back(rows[best].fy_N);
        fz.push_back(rows[best].fz_N);
    }
    out["forces"] = {{"t_s", t}, {"force_N", f}, {"fx_N", fx}, {"fy_N", fy}, {"fz_N", fz}};
    out["next_after"] = next;
    out["more"] = chunks.size() == 64;
    json blocks = json::array();
    for (const auto& b : s->live().blocks(id, from_block)) blocks.push_back(json::parse(b.body_json));
    out["blocks"] = blocks;
    out["next_block"] = from_block + std::int64_t(blocks.size());
    x.reply(200, out);
}

}  // namespace

void add_live_routes(Core& c) {
    c.route({"POST", "/api/v1/live", Role::Write, {}, Body::Json}, [&c](Ctx& x) { create_live(c, x); });
    c.route({"POST", "/api/v1/live/{id}/stop", Role::Write, {path_id()}}, [&c](Ctx& x) {
        const std::int64_t id = x.id();
        if (!c.live->stop(id)) {
            const auto st = c.live->state(id);
            if (!st) not_found(fmt::format("run {} is not a live run", id));
            throw ApiError(409, "not_live", fmt::format("live run {} is closed already", id));
        }
        x.reply(202, {{"id", id}, {"state", "stopping"}});
    });
    c.route({"GET", "/api/v1/live/{id}", Role::Read,
             {path_id(), query_int("after", "next_after of the previous answer: force rows stored after it").or_else(0),
              query_int("from_block", "next_block of the previous answer: blocks from this index").or_else(0),
              query_int("max_points", "force rows in the answer at most (peaks kept)").range(10, 20000).or_else(2000)}},
            [&c](Ctx& x) { get_live(c, x); });
}

}  // namespace cutload::server
