// Routes: /api/v1/runs (upload + queue, list, get, delete, cancel) and the result queries
// (blocks, forces, motion) with window decimation and CSV.
#include "app/ingest.hpp"
#include "app/library_tools.hpp"
#include "app/predict_run.hpp"
#include "app/program_source.hpp"
#include "app/tool_centre_point.hpp"
#include "app/work_bounds.hpp"
#include "core.hpp"
#include "freed_memory.hpp"
#include "json_in.hpp"
#include "spec_refs.hpp"
#include "db/optimizations.hpp"
#include "db/runs.hpp"
#include "durable_file.hpp"
#include "gzip.hpp"
#include "jobs.hpp"
#include "library.hpp"
#include "number_text.hpp"
#include "program.hpp"
#include "results.hpp"
#include "series.hpp"

#include "textio/csv.hpp"
#include "textio/text.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <openssl/rand.h>
#include <unistd.h>

#include <charconv>
#include <chrono>
#include <cmath>
#include <limits>
#include <mutex>
#include <cstdlib>
#include <fstream>
#include <regex>
#include <stdexcept>
#include <sstream>

namespace cutload::server {
namespace fs = std::filesystem;
namespace {

json run_json(const db::RunRecord& r) {
    const std::int64_t id = r.id;
    json run{{"id", id},
             {"name", or_null(r.name)},
             {"program", or_null(r.program)},
             {"machine_id", or_null(r.machine_id)},
             {"tool_id", or_null(r.tool_id)},
             {"material_id", or_null(r.material_id)},
             {"base_run", or_null(r.base_run)},
             {"state", db::to_text(r.state)},
             {"progress", r.progress},
             {"error", or_null(r.error)},
             {"attempts", r.attempts},
             {"inputs", json::parse(r.inputs_json)},
             {"summary", stored_json(r.summary_json)},
             {"flagged", r.flagged},
             {"created_at", r.created_at},
             {"started_at", or_null(r.started_at)},
             {"finished_at", or_null(r.finished_at)},
             {"links",
              {{"self", fmt::format("/api/v1/runs/{}", id)},
               {"blocks", fmt::format("/api/v1/runs/{}/blocks", id)},
               {"forces", fmt::format("/api/v1/runs/{}/forces", id)},
               {"motion", fmt::format("/api/v1/runs/{}/motion", id)}}}};
    // A live run (docs/live.md) runs from its start until it closes: 'live' rather than 'running'.
    if (run["inputs"].is_object() && run["inputs"].contains("live")) {
        if (r.state == db::JobState::Running) run["state"] = "live";
        run["links"]["live"] = fmt::format("/api/v1/live/{}", id);
    }
    if (run["inputs"].is_object() && run["inputs"].contains("nc_program")) {
        run["links"]["program"] = fmt::format("/api/v1/runs/{}/program", id);
        run["links"]["optimizations"] = fmt::format("/api/v1/runs/{}/optimizations", id);
    }
    return run;
}

json load_run(db::Session& s, std::int64_t id) {
    const auto run = s.runs().get(id);
    if (!run) not_found(fmt::format("run {} does not exist", id));
    return run_json(*run);
}

std::string random_hex(std::size_t bytes) {
    std::vector<unsigned char> b(bytes);
    RAND_bytes(b.data(), static_cast<int>(bytes));
    std::string s;
    for (auto v : b) s += fmt::format("{:02x}", v);
    return s;
}


void fsync_dir(const fs::path& p) {
    int fd = ::open(p.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd >= 0) {
        ::fsync(fd);
        ::close(fd);
    }
}

// Removes a directory unless released: a rejected upload leaves nothing on disk.
class DirGuard {
public:
    explicit DirGuard(fs::path p) : p_(std::move(p)) {}
    ~DirGuard() {
        if (!p_.empty()) {
            std::error_code ec;
            fs::remove_all(p_, ec);
        }
    }
    void release() { p_.clear(); }
    void retarget(fs::path p) { p_ = std::move(p); }

private:
    fs::path p_;
};

// A text part, decoded (client_text): what is echoed or stored is UTF-8.
std::optional<std::string> part(const httplib::Request& req, const char* name) {
    if (!req.has_file(name)) return std::nullopt;
    return client_text(req.get_file_value(name).content, fmt::format("part {}", name));
}

std::optional<std::int64_t> id_from(const json& spec, const httplib::Request& req, const char* key) {
    std::optional<std::int64_t> id;
    if (spec.contains(key)) {
        if (!spec[key].is_number_integer()) throw ApiError(400, "bad_spec", fmt::format("{}: must be an integer id", key));
        id = spec[key].get<std::int64_t>();
    }
    if (auto p = part(req, key)) {
        try {
            std::size_t used = 0;
            id = std::stoll(*p, &used);
            if (used != p->size()) throw std::invalid_argument(*p);
        } catch (const std::exception&) {
            throw ApiError(400, "bad_request", fmt::format("part {}: '{}' is not an integer id", key, *p));
        }
    }
    return id;
}

}  // namespace

// resolve_spec (spec_refs.hpp): inlines library references (tool_id, tools[k].tool_id, material_id)
// and fills limits the spec leaves at 0 from the tool's limits, then the machine's spindle power and torque.
Resolved resolve_spec(db::Session& s, json spec, const httplib::Request& req) {
    if (!spec.is_object()) throw ApiError(400, "bad_spec", "spec: must be a JSON object");
    Resolved r;
    r.machine_id = id_from(spec, req, "machine_id");
    r.tool_id = id_from(spec, req, "tool_id");
    r.material_id = id_from(spec, req, "material_id");
    for (const char* k : {"machine_id", "tool_id", "material_id"}) spec.erase(k);

    json tool_limits = json::object();
    if (r.tool_id) {
        if (spec.contains("tool")) throw ApiError(400, "bad_spec", "tool_id: give either tool or tool_id, not both");
        auto t = library_body(s, db::LibraryKind::Tool, *r.tool_id);
        if (!t) throw ApiError(404, "not_found", fmt::format("tool_id {}: no such tool", *r.tool_id));
        spec["tool"] = (*t)["tool"];
        tool_limits = (*t).value("limits", json::object());
    }
    // A tool table's entries may name library tools too: {"number": 11, "tool_id": 3}.
    try {
        spec = app::resolve_library_tools(std::move(spec), [&s](std::int64_t id) {
            return library_body(s, db::LibraryKind::Tool, id);
        });
    } catch (const app::UnknownLibraryTool& e) {
        throw ApiError(404, "not_found", e.what());
    } catch (const app::InputError& e) {
        throw ApiError(400, "bad_spec", e.what());
    }
    if (r.material_id) {
        if (spec.contains("material"))
            throw ApiError(400, "bad_spec", "material_id: give either material or material_id, not both");
        auto m = library_body(s, db::LibraryKind::Material, *r.material_id);
        if (!m) throw ApiError(404, "not_found", fmt::format("material_id {}: no such material", *r.material_id));
        spec["material"] = *m;
    }
    json machine_limits = json::object();
    if (r.machine_id) {
        auto m = library_body(s, db::LibraryKind::Machine, *r.machine_id);
        if (!m) throw ApiError(404, "not_found", fmt::format("machine_id {}: no such machine", *r.machine_id));
        machine_limits = {{"power_kW", (*m)["spindle_power_kW"]}, {"torque_Nm", (*m)["spindle_torque_Nm"]}};
    }
    auto parsed = force_model::parse_run_spec(spec);
    auto fill = [](double& v, const json& from, const char* key) {
        if (v == 0 && from.contains(key) && from[key].is_number()) v = from[key].get<double>();
    };
    for (const json* src : {&tool_limits, &machine_limits}) {
        fill(parsed.limits.force_N, *src, "force_N");
        fill(parsed.limits.torque_Nm, *src, "torque_Nm");
        fill(parsed.limits.power_kW, *src, "power_kW");
        fill(parsed.limits.chip_mm, *src, "chip_mm");
        fill(parsed.limits.bending_MPa, *src, "bending_MPa");
    }
    r.spec = force_model::to_json(parsed);
    return r;
}

namespace {

std::string log_extension(const std::string& filename) {
    static const std::regex ok(R"(\.(csv|txt|shdr|log))", std::regex::icase);
    const std::string ext = fs::path(filename).extension().string();
    return std::regex_match(ext, ok) ? ext : std::string(".log");
}

std::string replace_all(std::string s, const std::string& from, const std::string& to) {
    if (from.empty()) return s;
    for (std::size_t p = s.find(from); p != std::string::npos; p = s.find(from, p + to.size())) s.replace(p, from.size(), to);
    return s;
}

// The machine's kinematic chain (docs/machines.md), with its geometric errors and the tool length,
// stored beside the log: the log's x, y, z and a, b, c are then that machine's axes, turned into the
// tool's motion against the part (docs/five_axis.md). Read once here, so a bad file is a 400 now
// rather than a failed job later. Null without a part 'kinematics'; `machine` gets the machine read,
// whose rotary axes ("AC") the log must hold and an NC program uploaded with it is read in.
json store_kinematics(const httplib::Request& req, const fs::path& dir, std::shared_ptr<const machine::Machine>& machine) {
    const auto length = part(req, "tool_length_mm");
    if (!req.has_file("kinematics")) {
        if (req.has_file("kinematics_errors") || length)
            bad_request(fmt::format("part {}: given without part kinematics (the machine definition it belongs to)",
                                    length ? "tool_length_mm" : "kinematics_errors"));
        return nullptr;
    }
    json k{{"stored_as", "kinematics.json"}};
    const auto def = req.get_file_value("kinematics");
    if (def.content.empty()) throw ApiError(400, "bad_kinematics", "part 'kinematics' is empty");
    k["filename"] = def.filename.empty() ? "kinematics.json"
                                         : fs::path(client_text(def.filename, "file name of part 'kinematics'")).filename().string();
    write_durable(dir / "kinematics.json", client_text(def.content, "part kinematics"));
    if (req.has_file("kinematics_errors")) {
        const auto errors = req.get_file_value("kinematics_errors");
        if (errors.content.empty()) throw ApiError(400, "bad_kinematics", "part 'kinematics_errors' is empty");
        write_durable(dir / "kinematics_errors.json", client_text(errors.content, "part kinematics_errors"));
        k["errors"] = "kinematics_errors.json";
    }
    double tool_length_mm = 0;
    if (length) {
        char* end = nullptr;
        tool_length_mm = std::strtod(length->c_str(), &end);
        if (length->empty() || end != length->c_str() + length->size() || !(tool_length_mm >= 0 && tool_length_mm <= 1000))
            bad_request(fmt::format("part tool_length_mm: '{}' is not a length from 0 to 1000 mm", *length));
    }
    k["tool_length_mm"] = tool_length_mm;
    try {
        machine = app::load_machine_definition(kinematics_files(dir, k));
    } catch (const app::InputError& e) {
        throw ApiError(400, "bad_kinematics", e.what());
    }
    return k;
}

// The uploaded program as read, for the work it implies.
struct UploadedProgram {
    motion_io::NcProgram program;
    double rapid_mm_min = 0;
};

// Stores the uploaded NC program beside the log and reads it once, so a bad program is a 400 now
// rather than a failed job later. Positions are checked again by the job, against the log.
json store_nc_program(const httplib::Request& req, const fs::path& dir, const json& spec_json,
                      const std::optional<std::array<double, 3>>& start_mm, const std::string& rotary_axes,
                      const std::shared_ptr<const motion_io::ToolCentrePointKinematics>& tool_centre_point,
                      std::optional<UploadedProgram>& read) {
    const auto f = req.get_file_value("nc_program");
    if (f.content.empty()) throw ApiError(400, "bad_program", "part 'nc_program' is empty");
    const std::string name = f.filename.empty() ? "program.nc" : fs::path(client_text(f.filename, "file name of part 'nc_program'")).filename().string();
    // Stored decoded, so comments and messages read as written (a Latin-1 "(Fräsen)" included).
    std::string text;
    try {
        text = textio::decode(f.content, name);
    } catch (const textio::TextError& e) {
        throw ApiError(400, "bad_program", e.what());
    }
    json options = json::object();
    if (auto o = part(req, "nc_options")) {
        options = parse_client_json(*o, "part nc_options", "bad_request");
    }
    app::ProgramSource source;
    source.settings = program_settings(options);
    // With kinematics the program is in the machine's axes (A/B/C words); the job reads it again
    // from where the log's axes start, and turns it into the tip's path against the part.
    source.settings.rotary_axes = rotary_axes;
    source.settings.tool_centre_point = tool_centre_point;
    source.name = name;
    source.text = text;
    const force_model::RunSpec spec = force_model::parse_run_spec(spec_json);
    try {
        // From where the log starts, as the job will read it (the inspect report's first sample).
        auto program = app::read_program(source, spec, start_mm);
        if (std::none_of(program.blocks.begin(), program.blocks.end(), motion_io::block_moves))
            throw ApiError(400, "bad_program", fmt::format("{}: the program has no motion block", name));
        read.emplace(UploadedProgram{std::move(program), source.settings.rapid_mm_min});
    } catch (const motion_io::NcProgramError& e) {
        throw ApiError(400, "bad_program", e.what());
    }
    write_durable(dir / "program.nc", text);
    return {{"filename", name}, {"bytes", f.content.size()}, {"sha256", sha256_hex(f.content)}, {"stored_as", "program.nc"},
            {"options", options}};
}

void create_run(Core& core, Ctx& x) {
    const auto& req = x.req;
    if (!req.has_file("log")) bad_request("part 'log' is missing: attach the dry-run log (CSV or SHDR)");
    auto spec_text = part(req, "spec");
    if (!spec_text) bad_request("part 'spec' is missing: attach the run spec (JSON)");
    auto log_part = req.get_file_value("log");
    if (log_part.content.empty()) throw ApiError(400, "bad_log", "part 'log' is empty");
    log_part.filename = client_text(log_part.filename, "file name of part 'log'");

    auto s = core.session();
    if (const auto pending = s->jobs().count(db::kRunQueue, {db::JobState::Queued, db::JobState::Running});
        pending >= core.opt.max_pending_jobs) {
        x.res.set_header("Retry-After", "30");
        throw ApiError(429, "too_many_jobs",
                       fmt::format("{} runs are queued or running (limit {}): retry when some finish", pending,
                                   core.opt.max_pending_jobs));
    }

    json spec_json = parse_client_json(*spec_text, "part spec", "bad_spec");
    Resolved r = resolve_spec(*s, std::move(spec_json), req);

    json log{{"filename", log_part.filename}, {"bytes", log_part.content.size()}};
    app::LogFormat format;
    format.format = part(req, "format").value_or("auto");
    format.length_unit = part(req, "units");
    format.feed_unit = part(req, "feed_units");
    motion_io::ReadOptions ro;
    try {
        ro = app::read_options(format);
    } catch (const app::InputError& e) {
        bad_request(fmt::format("part {}", e.what()));
    }
    log["format"] = format.format;
    if (format.length_unit) log["units"] = *format.length_unit;
    if (format.feed_unit) log["feed_units"] = *format.feed_unit;

    std::optional<std::int64_t> base_run;
    if (auto b = part(req, "base_run")) {
        try {
            base_run = std::stoll(*b);
        } catch (const std::exception&) {
            bad_request(fmt::format("part base_run: '{}' is not a run id", *b));
        }
        const auto base = s->runs().status(*base_run);
        if (!base) not_found(fmt::format("base_run {}: no such run", *base_run));
        if (base->state != db::JobState::Done || !s->runs().has_final_stock(*base_run))
            throw ApiError(409, "conflict", fmt::format("base_run {}: run is {}, its final stock exists once it is done",
                                                        *base_run, db::to_text(base->state)));
    }

    // Store the upload, then validate the stored file; any failure removes the directory.
    const fs::path tmp = core.data_dir / "tmp" / random_hex(12);
    fs::create_directories(tmp);
    DirGuard guard(tmp);
    const std::string stored_as = "log" + log_extension(log_part.filename);
    write_durable(tmp / stored_as, log_part.content);
    log["stored_as"] = stored_as;
    log["sha256"] = sha256_hex(log_part.content);
    if (auto m = part(req, "mapping")) {
        // The name of a bundled preset, or a map of one's own (JSON).
        const auto presets = motion_io::map_presets();
        if (std::find(presets.begin(), presets.end(), *m) != presets.end()) {
            log["mapping_preset"] = *m;
            ro.map_file = *m;
        } else {
            write_durable(tmp / "mapping.json", *m);
            log["mapping"] = "mapping.json";
            ro.map_file = (tmp / "mapping.json").string();
        }
    }

    std::shared_ptr<const machine::Machine> machine;
    const json kinematics = store_kinematics(req, tmp, machine);
    const std::string rotary_axes = machine ? app::machine_rotary_axes(*machine) : std::string();

    motion_io::IngestReport report;
    // With a machine, the orientation the tool cuts at, from the same read: a fixed tilt's stock is
    // laid out turned, and the work estimate below must count the cells the job will.
    app::CuttingOrientation orientation;
    try {
        const double tool_length_mm = kinematics.is_object() ? kinematics.value("tool_length_mm", 0.0) : 0.0;
        app::InspectedLog inspected = app::inspect_run_log((tmp / stored_as).string(), ro, force_model::parse_run_spec(r.spec),
                                                           machine.get(), tool_length_mm);
        report = std::move(inspected.report);
        orientation = inspected.orientation;
    } catch (const motion_io::IngestError& e) {
        // Name the uploaded file, not the server's temporary path.
        std::string msg = replace_all(e.what(), (tmp / stored_as).string(), log_part.filename.empty() ? "log" : log_part.filename);
        msg = replace_all(msg, (tmp / "mapping.json").string(), "mapping");
        throw ApiError(400, "bad_log", msg);
    }
    if (machine) {
        // A rotary axis of the machine without its column fails the job once it has ingested the
        // log: said now, from the report the upload has just made.
        try {
            app::check_log_axes(*machine, report.rotary_axes);
        } catch (const app::InputError& e) {
            throw ApiError(400, "bad_log", fmt::format("{}: {} (part kinematics)", log_part.filename.empty() ? "log" : log_part.filename,
                                                       e.what()));
        }
    }
    json nc_program;
    std::optional<UploadedProgram> program_read;
    if (req.has_file("nc_program"))
        nc_program = store_nc_program(req, tmp, r.spec, report.first_position_mm, rotary_axes,
                                      machine ? app::tool_centre_point_kinematics(machine, kinematics.value("tool_length_mm", 0.0)) : nullptr,
                                      program_read);
    else if (part(req, "nc_options"))
        bad_request("part nc_options: given without nc_program (the options are for reading the NC program)");
    std::size_t rows = 0;
    for (const auto& [name, ch] : report.channels) rows = std::max(rows, ch.samples);
    if (rows > core.opt.max_log_rows)
        throw ApiError(413, "too_many_rows", fmt::format("the log has {} rows; the limit is {}", rows, core.opt.max_log_rows));
    // The work the run implies, before it is queued: the job checks the same figures again.
    {
        app::CommandedWork commanded;
        if (program_read) {
            commanded.program = &program_read->program;
            commanded.options.step_s = ro.step_ms * 1e-3;
            commanded.options.rapid_mm_min = program_read->rapid_mm_min;
        }
        try {
            // The job streams the actual rows (job_kinds.cpp).
            app::check_run_work(app::estimate_run_work(report, force_model::parse_run_spec(r.spec), orientation, commanded, true),
                                work_limits(core.opt), orientation);
        } catch (const app::TooMuchWork& e) {
            throw ApiError(400, "too_much_work", e.what());
        }
    }
    // Coarse data is said out loud before any prediction (docs/formats.md, "Coarse data").
    const motion_io::SamplingCheck sampling = motion_io::check_sampling(report, force_model::max_flutes(force_model::parse_run_spec(r.spec)));
    json warnings = json::array();
    for (const std::vector<motion_io::IngestWarning>* list :
         std::initializer_list<const std::vector<motion_io::IngestWarning>*>{&report.warnings, &sampling.warnings})
        for (const auto& w : *list)
            warnings.push_back({{"code", w.code},
                                {"message", replace_all(w.message, (tmp / stored_as).string(), log_part.filename.empty() ? "log" : log_part.filename)},
                                {"count", w.count}});
    json data_quality = motion_io::to_json(sampling);
    data_quality.erase("warnings");
    json inputs{{"log", log},
                {"spec", r.spec},
                {"ingest",
                 {{"format", report.format},
                  {"duration_s", report.duration_s},
                  {"sessions", report.sessions},
                  {"blocks", report.blocks},
                  {"rows", rows},
                  {"data_quality", data_quality},
                  {"warnings", warnings}}}};
    if (!nc_program.is_null()) inputs["nc_program"] = nc_program;
    if (!kinematics.is_null()) inputs["kinematics"] = kinematics;

    const auto name = part(req, "name");
    const auto program = part(req, "program");
    db::Transaction tx(*s);
    const std::int64_t id =
        s->runs().create({name, program, r.machine_id, r.tool_id, r.material_id, base_run, inputs.dump(), db::now_iso()});
    const std::string rel = fmt::format("uploads/{}", id);
    s->runs().set_upload_dir(id, rel);
    fs::rename(tmp, core.data_dir / rel);
    guard.retarget(core.data_dir / rel);
    fsync_dir(core.data_dir / "uploads");
    tx.commit();
    guard.release();
    core.jobs->notify();

    x.res.set_header("Location", fmt::format("/api/v1/runs/{}", id));
    x.reply(202, load_run(*s, id));
}

void list_runs(Core& core, Ctx& x) {
    db::RunFilter f;
    f.limit = *x.param_int("limit");
    f.before_id = x.param_int("cursor");
    f.machine_id = x.param_int("machine_id");
    f.program = x.param("program");
    if (const auto state = x.param("state")) f.state = db::job_state_from_text(*state);
    f.flagged = x.param_bool("flagged");
    f.created_since = x.param("created_since");
    f.created_until = x.param("created_until");
    const std::int64_t limit = f.limit;
    f.limit = limit + 1;   // one more than a page: there is a next page
    auto s = core.session();
    json items = json::array();
    for (const auto& run : s->runs().list(f)) items.push_back(run_json(run));
    json next = nullptr;
    if (static_cast<std::int64_t>(items.size()) > limit) {
        items.erase(items.end() - 1);
        next = std::to_string(items.back()["id"].get<std::int64_t>());
    }
    x.reply(200, {{"items", items}, {"next_cursor", next}});
}

// How long DELETE of a running run waits for its worker to stop before removing its files.
constexpr double kDeleteWaitS = 10;

void delete_run(Core& core, Ctx& x) {
    const auto id = x.id();
    auto s = core.session();
    db::Transaction tx(*s);
    const auto run = s->runs().status(id);
    if (!run) not_found(fmt::format("run {} does not exist", id));
    // A running run is cancelled first and then deleted: its worker stops at its next cancel check
    // (a failure meanwhile, its files gone, ends as a cancel too) and its storing finds no row.
    if (run->state == db::JobState::Running) core.jobs->cancel_running(db::kRunQueue, id);
    const fs::path dir = core.data_dir / run->upload_dir;
    // Its optimizations go with it; one being computed is stopped rather than left to run on
    // (after the commit: a worker claiming a job holds the job lock while it writes).
    const std::vector<std::int64_t> optimizing = s->optimizations().ids_of_run(id, db::JobState::Running);
    s->runs().remove(id);
    tx.commit();
    for (const std::int64_t oid : optimizing) core.jobs->cancel_running(db::kOptimizationQueue, oid);
    // Its files go once its worker has let go (each phase checks the flag within a fraction of a
    // second); one still busy after this reads from files already open or ends as cancelled.
    if (run->state == db::JobState::Running) core.jobs->wait_released(db::kRunQueue, id, kDeleteWaitS);
    core.series_cache.forget_run(id);
    std::error_code ec;
    fs::remove_all(dir, ec);
    // The run's rows are the bulk of the database: give their pages back and empty the WAL now,
    // so the file shrinks with every DELETE (docs/api.md, "Disk").
    // The run is gone either way: a failure here (a busy checkpoint) is logged, not answered.
    try {
        const auto f = s->reclaim_space();
        spdlog::info("run {} deleted: store {} -> {} bytes{}", id, f.before_bytes, f.after_bytes,
                     f.wal_emptied ? "" : " (the WAL is kept while a reader uses it)");
    } catch (const std::exception& e) {
        spdlog::warn("run {} deleted; giving its space back: {}", id, e.what());
    }
    x.res.status = 204;
}

void cancel_run(Core& core, Ctx& x) {
    const auto id = x.id();
    auto s = core.session();
    if (!s->jobs().cancel_queued(db::kRunQueue, id, db::now_iso())) {
        const auto run = s->runs().status(id);
        if (!run) not_found(fmt::format("run {} does not exist", id));
        if (run->state != db::JobState::Running || !core.jobs->cancel_running(db::kRunQueue, id))
            throw ApiError(409, "conflict", fmt::format("run {} is {}: only queued or running runs can be cancelled", id,
                                                        db::to_text(run->state)));
    }
    x.reply(202, load_run(*s, id));
}

}  // namespace

// Results exist only for finished runs; anything else is a conflict, not an empty answer.
RunRef require_done(db::Session& s, std::int64_t id) {
    const auto run = s.runs().status(id);
    if (!run) not_found(fmt::format("run {} does not exist", id));
    if (run->state != db::JobState::Done)
        throw ApiError(409, "not_done", fmt::format("run {} is {}: results exist once it is done", id, db::to_text(run->state)));
    return RunRef{id, run->finished_at.value_or("")};
}

json require_program(db::Session& s, std::int64_t id) {
    const auto body = s.runs().program_body(id);
    if (!body)
        throw ApiError(404, "no_program",
                       fmt::format("run {} was uploaded without an NC program (multipart part nc_program)", id));
    return json::parse(*body);
}

namespace {

void list_blocks(Core& core, Ctx& x) {
    const auto id = x.id();
    const auto limit = *x.param_int("limit");
    auto s = core.session();
    require_done(*s, id);
    const auto rows = s->runs().blocks(id, *x.param_int("cursor"), x.param_bool("flagged"), limit + 1);
    // The stored bodies are JSON written by store_result: joined as they are, not parsed again.
    std::string out = fmt::format(R"({{"run_id":{},"items":[)", id);
    std::int64_t count = 0, last = -1;
    for (const auto& row : rows) {
        if (++count > limit) break;   // one more than a page: there is a next page
        last = row.idx;
        if (count > 1) out += ',';
        out += row.body_json;
    }
    out += count > limit ? fmt::format(R"(],"next_cursor":"{}"}})", last + 1) : std::string(R"(],"next_cursor":null})");
    x.res.status = 200;
    x.res.body = std::move(out);
    x.res.set_header("Content-Type", "application/json");
}

// Block names of a finished run as CSV fields (quoted where they must be) and as JSON strings,
// decoded once per run.
struct BlockNames {
    std::vector<std::string> csv, json;
};

std::shared_ptr<const BlockNames> block_names(db::Session& s, SeriesCache& cache, const RunRef& run) {
    const SeriesCache::Key key{run.id, run.version, SeriesCache::Kind::BlockNames, 0, 0, 0};
    return cache.get<BlockNames>(key, [&] {
        auto names = std::make_shared<BlockNames>();
        std::size_t bytes = sizeof(BlockNames);
        if (const auto text = s.runs().block_names(run.id)) {
            for (const auto& n : json::parse(*text)) {
                names->csv.push_back(textio::csv_field(n.get<std::string>()));
                names->json.push_back(body_text(n));
                bytes += 2 * (sizeof(std::string) + names->csv.back().size());
            }
        }
        return std::pair{std::shared_ptr<const BlockNames>(std::move(names)), bytes};
    });
}

// channels=a,b selects what is written (default all); unknown names are an error.
std::vector<bool> wanted_channels(const Ctx& x, const std::vector<std::string>& ch) {
    std::vector<bool> wanted(ch.size(), !x.param("channels"));
    if (auto list = x.param("channels")) {
        std::stringstream ss(*list);
        for (std::string name; std::getline(ss, name, ',');) {
            auto pos = std::find(ch.begin(), ch.end(), name);
            if (pos == ch.end()) bad_request(fmt::format("query parameter channels: unknown channel '{}'", name));
            wanted[static_cast<std::size_t>(pos - ch.begin())] = true;
        }
    }
    return wanted;
}

// Writes into a buffer sized for the worst case, then trims: no reallocation, no per-number
// string. Numbers come from number_text.hpp.
class TextOut {
public:
    explicit TextOut(std::size_t max_chars) { s_.resize(max_chars); p_ = s_.data(); }
    TextOut& operator<<(const char* text) {
        p_ = detail::write_text(p_, text);
        return *this;
    }
    TextOut& operator<<(const std::string& text) {
        std::memcpy(p_, text.data(), text.size());
        p_ += text.size();
        return *this;
    }
    TextOut& operator<<(char ch) {
        *p_++ = ch;
        return *this;
    }
    void value(float v, const char* nonfinite) { p_ = write_float(p_, v, nonfinite); }
    void time(double t_s) { p_ = write_time(p_, t_s); }
    std::string done() && {
        s_.resize(static_cast<std::size_t>(p_ - s_.data()));
        return std::move(s_);
    }

private:
    std::string s_;
    char* p_;
};

std::string series_csv(const Window& w, const std::vector<std::string>& ch, const std::vector<bool>& wanted,
                       std::size_t block_col, const BlockNames& names) {
    const std::size_t n = w.t_s.size();
    std::size_t longest_name = 0;
    for (const auto& b : names.csv) longest_name = std::max(longest_name, b.size());
    std::size_t header = 32, per_row = 2 * kTimeChars + 2;
    for (std::size_t j = 0; j < ch.size(); ++j)
        if (wanted[j]) {
            header += 2 * ch[j].size() + 10;
            per_row += 2 * kValueChars + 2 + longest_name;
        }
    TextOut out(header + n * per_row);
    out << (w.decimated ? "t_s,t_end_s" : "t_s");
    for (std::size_t j = 0; j < ch.size(); ++j)
        if (wanted[j]) out << ',' << ch[j] << (w.decimated ? "_min," : "") << (w.decimated ? ch[j] + "_max" : "");
    out << '\n';
    for (std::size_t i = 0; i < n; ++i) {
        out.time(w.t_s[i]);
        if (w.decimated) {
            out << ',';
            out.time(w.t_end_s[i]);
        }
        for (std::size_t j = 0; j < ch.size(); ++j) {
            if (!wanted[j]) continue;
            out << ',';
            if (w.decimated) {
                out.value(w.lo[j][i], "");
                out << ',';
                out.value(w.hi[j][i], "");
            } else if (j == block_col) {
                const auto b = static_cast<std::size_t>(std::max(0.0f, w.lo[j][i]));
                out << (b < names.csv.size() ? names.csv[b] : std::string());
            } else {
                out.value(w.lo[j][i], "");
            }
        }
        out << '\n';
    }
    return std::move(out).done();
}

std::string series_json(std::int64_t id, double from_s, double to_s, std::size_t max_points, const Window& w,
                        const std::vector<std::string>& ch, const std::vector<bool>& wanted, std::size_t block_col,
                        const BlockNames& names, std::optional<double> recomputed_from_s = std::nullopt) {
    const std::size_t n = w.t_s.size();
    // Block indices that occur in the window, for block_names.
    std::vector<char> seen(names.json.size(), 0);
    const auto& blo = w.lo[block_col];
    const auto& bhi = w.decimated ? w.hi[block_col] : w.lo[block_col];
    for (std::size_t i = 0; i < blo.size(); ++i) {
        const auto first = static_cast<std::int64_t>(blo[i]), last = static_cast<std::int64_t>(bhi[i]);
        for (auto b = std::max<std::int64_t>(first, 0); b <= last && b < static_cast<std::int64_t>(seen.size()); ++b)
            seen[static_cast<std::size_t>(b)] = 1;
    }
    std::size_t names_chars = 2;
    for (std::size_t b = 0; b < seen.size(); ++b)
        if (seen[b]) names_chars += names.json[b].size() + 24;
    std::size_t value_arrays = 0;
    for (std::size_t j = 0; j < ch.size(); ++j)
        if (wanted[j]) value_arrays += w.decimated ? 2 : 1;
    const std::size_t time_arrays = w.decimated ? 2 : 1;
    TextOut out(512 + names_chars + time_arrays * n * (kTimeChars + 1) + value_arrays * (n * (kValueChars + 1) + 32));

    // from_s and to_s go through the same rounding as the times, so every time lies between them.
    out << fmt::format(R"({{"run_id":{},"from_s":)", id);
    out.time(from_s);
    out << ",\"to_s\":";
    out.time(to_s);
    out << fmt::format(R"(,"decimated":{},"level":{},"count":{})", w.decimated, w.level, n);
    if (recomputed_from_s) {
        out << R"(,"recomputed":true,"walked_from_s":)";
        out.time(*recomputed_from_s);
    }
    auto times = [&](const char* key, const std::vector<double>& t) {
        out << ",\"" << key << "\":[";
        for (std::size_t i = 0; i < n; ++i) {
            if (i) out << ',';
            out.time(t[i]);
        }
        out << ']';
    };
    auto values = [&](const std::vector<float>& v) {
        out << '[';
        for (std::size_t i = 0; i < n; ++i) {
            if (i) out << ',';
            out.value(v[i], "null");
        }
        out << ']';
    };
    times("t_s", w.t_s);
    if (w.decimated) {
        out << fmt::format(R"(,"bucket_s":{})", (to_s - from_s) / static_cast<double>(max_points));
        times("t_end_s", w.t_end_s);
    }
    for (std::size_t j = 0; j < ch.size(); ++j) {
        if (!wanted[j]) continue;
        out << ",\"" << ch[j] << "\":";
        if (w.decimated) {
            out << "{\"min\":";
            values(w.lo[j]);
            out << ",\"max\":";
            values(w.hi[j]);
            out << '}';
        } else {
            values(w.lo[j]);
        }
    }
    out << ",\"block_names\":{";
    bool first = true;
    for (std::size_t b = 0; b < seen.size(); ++b) {
        if (!seen[b]) continue;
        out << (first ? "\"" : ",\"") << std::to_string(b) << "\":" << names.json[b];
        first = false;
    }
    out << "}}";
    return std::move(out).done();
}

// The longest window /forces?resolution=full recomputes: 3e5 rows at 10000 rpm and 2 deg steps.
constexpr double kMaxRecomputedWindowS = 10;

// /forces?resolution=full: the window predicted again from the run's stored inputs, at full
// resolution whatever the run stored (force_model::PredictOptions::window: the very rows the whole
// run gave there). One at a time per process: each walks the motion before its window.
void recomputed_forces_route(Core& core, Ctx& x) {
    static std::mutex one_at_a_time;
    const auto id = x.id();
    if (x.param("source") == "commanded")
        bad_request("resolution=full recomputes the actual forces (source=actual); the commanded ones are stored whole");
    if (!x.given("from_s") || !x.given("to_s"))
        bad_request(fmt::format("resolution=full needs a window: from_s and to_s, at most {} s apart", kMaxRecomputedWindowS));
    const double from_s = *x.param_double("from_s"), to_s = *x.param_double("to_s");
    if (!(to_s > from_s)) bad_request(fmt::format("to_s ({}) must be after from_s ({})", to_s, from_s));
    if (to_s - from_s > kMaxRecomputedWindowS)
        bad_request(fmt::format("resolution=full recomputes at most {} s at once; this window spans {:.6g} s",
                                kMaxRecomputedWindowS, to_s - from_s));
    const auto max_points = static_cast<std::size_t>(*x.param_int("max_points"));
    const std::vector<std::string>& ch = series_channels(SeriesId::Forces);
    const std::vector<bool> wanted = wanted_channels(x, ch);
    json inputs;
    fs::path dir;
    std::optional<std::int64_t> base_run;
    RunRef run;
    {
        auto session = core.session();
        run = require_done(*session, id);
        const auto r = session->runs().get(id);
        if (!r) not_found(fmt::format("run {}", id));
        dir = core.data_dir / r->upload_dir;
        inputs = json::parse(r->inputs_json);
        base_run = r->base_run;
        double t0 = 0, t1 = 0;
        if (!series_extent(*session, core.series_cache, run, SeriesId::Forces, &t0, &t1) || to_s < t0 || from_s > t1)
            bad_request(fmt::format("the window {} .. {} s holds none of run {}'s force rows ({} .. {} s)", from_s, to_s, id,
                                    t0, t1));
    }
    if (inputs.contains("live"))
        throw ApiError(409, "not_recomputable", fmt::format("run {} was followed live: no log was stored to recompute it from", id));
    if (inputs.contains("kinematics"))
        throw ApiError(409, "not_recomputable",
                       fmt::format("run {} was predicted through a five-axis machine's kinematics: its windows are not "
                                   "recomputed yet (resolution=stored answers from the stored rows)",
                                   id));
    std::unique_lock lock(one_at_a_time, std::try_to_lock);
    if (!lock) {
        x.res.set_header("Retry-After", "1");
        throw ApiError(503, "busy", "another window is being recomputed; try again in a moment");
    }
    const ReleaseFreedMemoryOnExit release_freed_memory;   // the log's motion model and two stocks
    app::RunInput in = run_input(inputs, dir, core.opt.use_opencl);
    in.limits = work_limits(core.opt);
    in.keep_final_stock = false;
    // [from_s, to_s] as the stored answers take it: to_s included.
    in.window = force_model::TimeWindow{from_s, std::nextafter(to_s, std::numeric_limits<double>::infinity())};
    app::Control control;
    control.cancel = &core.stopping;   // a server that stops does not wait out a long walk
    // The walk resumes at the run's last stock checkpoint before the window (app/checkpoints.hpp),
    // else starts where the run started; one that cannot be used is a warning, logged.
    const auto t0 = std::chrono::steady_clock::now();
    force_model::StockPtr base;
    try {
        base = load_base_stock(*core.store, base_run);
    } catch (const std::runtime_error& e) {
        throw ApiError(409, "not_recomputable", fmt::format("run {}: {}", id, e.what()));
    }
    in.base_stock = base.get();
    in.checkpoints = app::CheckpointFolder{checkpoints_dir(dir)};
    app::RunResult r;
    try {
        r = app::predict_run(in, control);
    } catch (const app::TooMuchWork& e) {
        throw ApiError(400, "too_much_work", e.what());
    } catch (const force_model::SpecError& e) {
        throw ApiError(409, "not_recomputable", fmt::format("run {}: {}", id, e.what()));
    } catch (const app::InputError& e) {
        throw ApiError(409, "not_recomputable", fmt::format("run {}: {}", id, e.what()));
    } catch (const force_model::Cancelled&) {
        throw ApiError(503, "stopping", "the server is stopping; the window was not recomputed");
    }
    for (const std::string& w : r.warnings) spdlog::warn("run {}: {}", id, w);
    spdlog::info("run {}: window {:.3f} .. {:.3f} s recomputed in {:.2f} s, walked from {:.1f} s{}", id, from_s, to_s,
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), r.walked_from_s,
                 r.resumed ? " (a stock checkpoint)" : "");
    const SeriesData d = force_series(r.prediction);
    const std::size_t block_col = static_cast<std::size_t>(std::find(ch.begin(), ch.end(), "block") - ch.begin());
    std::vector<bool> read = wanted;
    read[block_col] = true;
    const Window w = window_from_rows(d, from_s, to_s, max_points, read);
    std::shared_ptr<const BlockNames> names;
    {
        auto session = core.session();
        names = block_names(*session, core.series_cache, run);
    }
    const bool csv = x.wants_csv();
    std::string text = csv ? series_csv(w, ch, wanted, block_col, *names)
                           : series_json(id, from_s, to_s, max_points, w, ch, wanted, block_col, *names,
                                         r.walked_from_s);
    if (accepts_gzip(x.req)) {
        text = gzip_fast(text);
        x.res.set_header("Content-Encoding", "gzip");
    }
    x.res.body = std::move(text);
    x.res.status = 200;
    x.res.set_header("Content-Type", csv ? "text/csv" : "application/json");
}

void series_route(Core& core, Ctx& x, SeriesId s) {
    const auto id = x.id();
    if (s == SeriesId::Forces && x.param("resolution") == "full") return recomputed_forces_route(core, x);
    if (s == SeriesId::Forces && x.param("source") == "commanded") s = SeriesId::CommandedForces;
    const auto max_points = *x.param_int("max_points");
    // /motion also answers a turning tool's axis per sample (SeriesId::ToolAxis, stored on the
    // motion's times): three more channels after the motion's own, for runs that stored it.
    std::vector<std::string> ch = series_channels(s);
    const std::size_t own_channels = ch.size();
    if (s == SeriesId::Motion) {
        const auto& axis = series_channels(SeriesId::ToolAxis);
        ch.insert(ch.end(), axis.begin(), axis.end());
    }
    std::vector<bool> wanted = wanted_channels(x, ch);
    auto session = core.session();
    db::Session& c = *session;
    const RunRef run = require_done(c, id);
    if (s == SeriesId::CommandedForces) require_program(c, id);
    bool with_axis = false;
    if (ch.size() > own_channels) {
        double t0 = 0, t1 = 0;
        with_axis = series_extent(c, core.series_cache, run, SeriesId::ToolAxis, &t0, &t1);
        if (!with_axis) {
            // Asked for by name from a run without them: said, not answered empty.
            if (x.param("channels") && std::find(wanted.begin() + std::ptrdiff_t(own_channels), wanted.end(), true) != wanted.end())
                throw ApiError(404, "no_tool_axis",
                               fmt::format("run {} has no tool axis per sample: only a run whose tool turned while it "
                                           "cut (summary.kinematics.turning) stores one; any other stands at "
                                           "summary.kinematics.tool_axis, or along +Z without a machine",
                                           id));
            ch.resize(own_channels);
            wanted.resize(own_channels);
        }
    }
    const bool csv = x.wants_csv();
    const bool gzip = accepts_gzip(x.req);
    const bool whole_run = !x.given("from_s") && !x.given("to_s");
    std::int64_t mask = 0;
    for (std::size_t j = 0; j < ch.size(); ++j)
        if (wanted[j]) mask |= std::int64_t{1} << j;
    const SeriesCache::Key answer_key{id, run.version, SeriesCache::Kind::Answer, static_cast<int>(s),
                                      static_cast<int>(max_points), (mask << 2) | (csv ? 2 : 0) | (gzip ? 1 : 0)};
    auto answer = [&]() -> std::string {
        double t0 = 0, t1 = 0;
        if (!series_extent(c, core.series_cache, run, s, &t0, &t1)) t0 = t1 = 0;
        const double from_s = x.param_double("from_s").value_or(t0);
        const double to_s = x.param_double("to_s").value_or(t1);
        if (to_s < from_s) bad_request(fmt::format("to_s ({}) is before from_s ({})", to_s, from_s));

        // The block channel is read even when not written: block_names lists the blocks in the window.
        const std::size_t block_col = static_cast<std::size_t>(std::find(ch.begin(), ch.end(), "block") - ch.begin());
        std::vector<bool> read = wanted;
        read[block_col] = true;
        Window w = query_window(c, core.series_cache, run, s, from_s, to_s, static_cast<std::size_t>(max_points),
                                std::vector<bool>(read.begin(), read.begin() + std::ptrdiff_t(own_channels)));
        if (with_axis) {
            const Window a = query_window(c, core.series_cache, run, SeriesId::ToolAxis, from_s, to_s,
                                          static_cast<std::size_t>(max_points),
                                          std::vector<bool>(read.begin() + std::ptrdiff_t(own_channels), read.end()));
            // Stored on the motion's times with the motion's chunking: the windows are the same buckets.
            if (a.t_s != w.t_s || a.t_end_s != w.t_end_s || a.decimated != w.decimated)
                throw std::logic_error(fmt::format("run {}: the tool axis series does not line up with the motion", id));
            w.lo.insert(w.lo.end(), a.lo.begin(), a.lo.end());
            w.hi.insert(w.hi.end(), a.hi.begin(), a.hi.end());
        }
        const auto names = block_names(c, core.series_cache, run);
        std::string text = csv ? series_csv(w, ch, wanted, block_col, *names)
                               : series_json(id, from_s, to_s, static_cast<std::size_t>(max_points), w, ch, wanted,
                                             block_col, *names);
        if (gzip) return gzip_fast(text);
        return text;
    };
    // Only the whole-run answer repeats often enough to keep: zoom windows hardly ever recur.
    auto kept_answer = [&] {
        auto text = std::make_shared<const std::string>(answer());
        return std::pair{text, sizeof(std::string) + text->size()};
    };
    std::string body = whole_run ? *core.series_cache.get<std::string>(answer_key, kept_answer) : answer();
    // Gzipped here rather than after routing, so the kept whole-run answer is kept compressed.
    if (gzip) x.res.set_header("Content-Encoding", "gzip");
    x.res.body = std::move(body);
    x.res.status = 200;
    x.res.set_header("Content-Type", csv ? "text/csv" : "application/json");
}

// The window and shape parameters /forces and /motion share; `channels`: what that parameter
// names there.
std::vector<Param> series_params(const Core& core, const std::string& channels) {
    return {path_id(),
            query_number("from_s", "window start (default: first sample)"),
            query_number("to_s", "window end (default: last sample)"),
            query_int("max_points", "most rows/buckets returned (at most cutload serve --max-points); wider windows are "
                                    "min/max-envelope decimated")
                .range(2, core.opt.max_points)
                .or_else(2000),
            query_string("channels", "comma-separated channels to return (default: all): " + channels),
            query_string("format", "csv: same as Accept: text/csv").one_of({"json", "csv"})};
}

}  // namespace

void add_run_routes(Core& core) {
    std::vector<std::string> states;
    for (const db::JobState st : db::job_states()) states.emplace_back(db::to_text(st));
    static const std::string iso_time = R"(\d{4}-\d{2}-\d{2}(T\d{2}:\d{2}(:\d{2}(\.\d{1,3})?)?Z?)?)";
    static const std::string iso_says = "an ISO 8601 UTC time (2024-05-01T08:00:00Z)";

    core.route({"POST", "/api/v1/runs", Role::Write, {}, Body::Multipart,
                " with parts 'log' (the dry-run log) and 'spec' (JSON)"},
               [&core](Ctx& x) { create_run(core, x); });
    core.route({"GET", "/api/v1/runs", Role::Read,
                {query_int("cursor", "next_cursor of the previous page"),
                 query_int("limit", "page size").range(1, 500).or_else(50),
                 query_int("machine_id", "machine"),
                 query_string("program", "exact program name"),
                 query_string("state", "state").one_of(states),
                 query_bool("flagged", "has flagged blocks or alerts"),
                 query_string("created_since", "ISO 8601 UTC, inclusive").matching(iso_time, iso_says),
                 query_string("created_until", "ISO 8601 UTC, inclusive").matching(iso_time, iso_says)}},
               [&core](Ctx& x) { list_runs(core, x); });
    core.route({"GET", "/api/v1/runs/{id}", Role::Read, {path_id()}}, [&core](Ctx& x) {
        auto s = core.session();
        x.reply(200, load_run(*s, x.id()));
    });
    core.route({"DELETE", "/api/v1/runs/{id}", Role::Write, {path_id()}}, [&core](Ctx& x) { delete_run(core, x); });
    core.route({"POST", "/api/v1/runs/{id}/cancel", Role::Write, {path_id()}}, [&core](Ctx& x) { cancel_run(core, x); });
    core.route({"GET", "/api/v1/runs/{id}/blocks", Role::Read,
                {path_id(), query_int("cursor", "next_cursor of the previous page").or_else(0),
                 query_int("limit", "page size").range(1, 10000).or_else(1000),
                 query_bool("flagged", "only blocks with flags")}},
               [&core](Ctx& x) { list_blocks(core, x); });
    std::vector<Param> forces = series_params(core, fmt::format("{}", fmt::join(series_channels(SeriesId::Forces), ", ")));
    forces.push_back(query_string("source",
                                  "commanded: forces predicted from the NC program's path at programmed feed (runs uploaded "
                                  "with nc_program; 404 no_program otherwise). Same channels and block_names as actual.")
                         .one_of({"actual", "commanded"})
                         .or_else("actual"));
    forces.push_back(query_string("resolution",
                                  "full: the window (from_s and to_s, at most 10 s apart) predicted again from the run's "
                                  "stored log and inputs, every row at full resolution, the very rows the whole run gave "
                                  "there, whatever the run stored (a long run keeps envelopes); the answer says "
                                  "\"recomputed\": true. It walks the motion before the window from the run's last stock "
                                  "checkpoint before it (walked_from_s; about 6 ms a second of motion on 2 cores), one at "
                                  "a time per server (503 busy). Actual forces only; 409 "
                                  "not_recomputable for live and five-axis runs. stored: from the stored series")
                         .one_of({"stored", "full"})
                         .or_else("stored"));
    core.route({"GET", "/api/v1/runs/{id}/forces", Role::Read, forces},
               [&core](Ctx& x) { series_route(core, x, SeriesId::Forces); });
    std::vector<Param> motion = series_params(
        core, fmt::format("{}, and for a run whose tool turned while it cut (summary.kinematics.turning) {}: its axis per "
                          "sample (unit, tip to spindle, stock axes); asked for by name from any other run, 404 no_tool_axis",
                          fmt::join(series_channels(SeriesId::Motion), ", "),
                          fmt::join(series_channels(SeriesId::ToolAxis), ", ")));
    motion.push_back(query_string("source", "actual only (the logged motion): only /forces has a commanded counterpart")
                         .one_of({"actual"})
                         .refused_as("actual (only /forces has a commanded counterpart; /motion is the log's)")
                         .or_else("actual"));
    core.route({"GET", "/api/v1/runs/{id}/motion", Role::Read, motion},
               [&core](Ctx& x) { series_route(core, x, SeriesId::Motion); });
}

}  // namespace cutload::server
