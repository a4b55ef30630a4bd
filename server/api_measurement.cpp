// Routes: /api/v1/runs/{id}/measurement: attach a dynamometer record to a finished run, get the
// comparison with the run's predicted forces (issue 6), detach it.
//
// The record and its settings live in the run's upload directory (measurement.csv and
// measurement.json), written and validated (a full comparison) before the answer; the comparison is
// recomputed on GET, so a changed force engine never serves a stale report.
#include "app/compare.hpp"
#include "core.hpp"
#include "db/runs.hpp"
#include "durable_file.hpp"
#include "series.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <fstream>
#include <limits>
#include <optional>

namespace cutload::server {
namespace fs = std::filesystem;
namespace {

constexpr const char* kDataFile = "measurement.csv";
constexpr const char* kSettingsFile = "measurement.json";

struct DoneRun {
    RunRef ref;
    fs::path upload_dir;
};

DoneRun require_done_run(db::Session& s, const fs::path& data_dir, std::int64_t id) {
    const auto run = s.runs().status(id);
    if (!run) not_found(fmt::format("run {} does not exist", id));
    if (run->state != db::JobState::Done)
        throw ApiError(409, "not_done",
                       fmt::format("run {} is {}: a measurement is compared once it is done", id, db::to_text(run->state)));
    return DoneRun{RunRef{id, run->finished_at.value_or("")}, data_dir / run->upload_dir};
}


// The run's predicted forces at full rate, from the stored series.
force_model::PredictedTrace stored_trace(Core& core, db::Session& c, const RunRef& run) {
    force_model::PredictedTrace t;
    double t0 = 0, t1 = 0;
    if (!series_extent(c, core.series_cache, run, SeriesId::Forces, &t0, &t1)) return t;
    const auto& ch = series_channels(SeriesId::Forces);
    auto col = [&](const char* name) { return static_cast<std::size_t>(std::find(ch.begin(), ch.end(), name) - ch.begin()); };
    const std::size_t ca = col("spindle_angle_deg"), cb = col("block"), cx = col("fx_N"), cy = col("fy_N"), cz = col("fz_N");
    std::vector<bool> wanted(ch.size(), false);
    for (auto j : {ca, cb, cx, cy, cz}) wanted[j] = true;
    const Window w = query_window(c, core.series_cache, run, SeriesId::Forces, t0, t1,
                                  std::numeric_limits<std::size_t>::max() / 4, wanted);
    t.samples.resize(w.t_s.size());
    for (std::size_t i = 0; i < w.t_s.size(); ++i) {
        auto& s = t.samples[i];
        s.t_s = w.t_s[i];
        s.spindle_angle_deg = w.lo[ca][i];
        s.block = static_cast<std::int32_t>(w.lo[cb][i]);
        s.fx_N = w.lo[cx][i];
        s.fy_N = w.lo[cy][i];
        s.fz_N = w.lo[cz][i];
    }
    if (const auto names = c.runs().block_names(run.id))
        for (const auto& n : json::parse(*names)) t.block_names.push_back(n.get<std::string>());
    return t;
}

using Settings = app::CompareSettings;

json settings_json(const Settings& s) {
    json j{{"axes", s.axes},
           {"measured_on", s.measured_on_workpiece ? "workpiece" : "tool"},
           {"cutoff_Hz", s.options.cutoff_Hz}};
    j["offset_s"] = s.options.offset_s ? json(*s.options.offset_s) : json(nullptr);
    j["from_s"] = s.options.t_start_s > -1e299 ? json(s.options.t_start_s) : json(nullptr);
    j["to_s"] = s.options.t_end_s < 1e299 ? json(s.options.t_end_s) : json(nullptr);
    j["zero_N"] = s.zero_dyn_N ? json(*s.zero_dyn_N) : json(nullptr);
    return j;
}

Settings settings_from(const json& j) {
    Settings s;
    s.axes = j.at("axes").get<force_model::AxisMatrix>();
    s.measured_on_workpiece = j.at("measured_on") == "workpiece";
    s.options.cutoff_Hz = j.at("cutoff_Hz").get<double>();
    if (!j.at("offset_s").is_null()) s.options.offset_s = j["offset_s"].get<double>();
    if (!j.at("from_s").is_null()) s.options.t_start_s = j["from_s"].get<double>();
    if (!j.at("to_s").is_null()) s.options.t_end_s = j["to_s"].get<double>();
    // Absent in settings stored before the zero offset could be given.
    if (j.contains("zero_N") && !j["zero_N"].is_null()) s.zero_dyn_N = j["zero_N"].get<std::array<double, 3>>();
    return s;
}

// A text part, decoded (client_text): what is echoed or stored is UTF-8.
std::optional<std::string> part(const httplib::Request& req, const char* name) {
    if (!req.has_file(name)) return std::nullopt;
    return client_text(req.get_file_value(name).content, fmt::format("part {}", name));
}

std::optional<double> number_part(const httplib::Request& req, const char* name) {
    auto p = part(req, name);
    if (!p) return std::nullopt;
    try {
        std::size_t used = 0;
        const double v = std::stod(*p, &used);
        if (used != p->size() || !std::isfinite(v)) throw std::invalid_argument(*p);
        return v;
    } catch (const std::exception&) {
        throw ApiError(400, "bad_request", fmt::format("part {}: '{}' is not a number", name, *p));
    }
}

Settings settings_from_parts(const httplib::Request& req) {
    Settings s;
    if (auto a = part(req, "axes")) {
        try {
            s.axes = force_model::parse_axis_matrix(*a);
        } catch (const force_model::MeasurementError& e) {
            throw ApiError(400, "bad_measurement", fmt::format("part axes: {}", e.what()));
        }
    }
    if (auto m = part(req, "measured_on")) {
        if (*m != "workpiece" && *m != "tool")
            bad_request(fmt::format("part measured_on: '{}' is not workpiece or tool", *m));
        s.measured_on_workpiece = *m == "workpiece";
    }
    if (auto z = part(req, "zero_N")) {
        try {
            s.zero_dyn_N = force_model::parse_force_vector(*z);
        } catch (const force_model::MeasurementError& e) {
            bad_request(fmt::format("part zero_N: {}", e.what()));
        }
    }
    s.options.offset_s = number_part(req, "offset_s");
    if (auto v = number_part(req, "from_s")) s.options.t_start_s = *v;
    if (auto v = number_part(req, "to_s")) s.options.t_end_s = *v;
    if (s.options.t_end_s < s.options.t_start_s) bad_request("part to_s: before from_s");
    if (auto v = number_part(req, "cutoff_Hz")) {
        if (*v < 0) bad_request("part cutoff_Hz: must be 0 (no filter) or positive");
        s.options.cutoff_Hz = *v;
    }
    return s;
}

std::string replace_all(std::string s, const std::string& from, const std::string& to) {
    for (std::size_t p = s.find(from); p != std::string::npos; p = s.find(from, p + to.size())) s.replace(p, from.size(), to);
    return s;
}

using Compared = app::MeasurementComparison;

// Reads, maps and compares; a MeasurementError becomes 400 naming `shown_name`, not the disk path.
Compared compare_file(const force_model::PredictedTrace& trace, const fs::path& file, const std::string& shown_name,
                      const Settings& s) {
    try {
        return app::compare_measurement(trace, file.string(), s);
    } catch (const force_model::MeasurementError& e) {
        throw ApiError(400, "bad_measurement", replace_all(e.what(), file.string(), shown_name));
    }
}

json report_json(const Compared& r, const json& stored) {
    json j = force_model::to_json(r.comparison);
    j["measured"] = {{"file", stored.value("filename", "")},
                     {"format", r.measured.format},
                     {"rate_Hz", r.measured.rate_Hz},
                     {"samples", r.measured.size()},
                     {"ignored_channels", r.measured.ignored_channels}};
    j["settings"] = stored.at("settings");
    return j;
}

// The measured series as recorded (unfiltered), in tool / machine axes, shifted to prediction time
// and less the zero offset (and drift) the comparison removed, in [from_s, to_s]: raw when it fits max_points,
// else the min / max of each of max_points equal buckets, the shape of /forces answers.
json measured_series(const Compared& r, double from_s, double to_s, std::size_t max_points) {
    const force_model::Measurement& m = r.measured;
    const double shift_s = r.comparison.offset_s;
    auto t_of = [&](std::size_t i) { return m.t_s(i) + shift_s; };
    const std::vector<float>* ch[3] = {&m.fx_N, &m.fy_N, &m.fz_N};
    auto value = [&](int a, std::size_t i) {
        return (*ch[a])[i] - static_cast<float>(r.comparison.zero_removed ? r.comparison.zero.at(t_of(i))[static_cast<std::size_t>(a)] : 0.0);
    };
    auto index_at = [&](double t) {
        const double k = std::ceil((t - shift_s - m.t0_s) * m.rate_Hz - 1e-6);
        return static_cast<std::size_t>(std::clamp(k, 0.0, static_cast<double>(m.size())));
    };
    const std::size_t first = index_at(from_s);
    std::size_t last = index_at(to_s);
    while (last < m.size() && t_of(last) <= to_s) ++last;
    const std::size_t n = last > first ? last - first : 0;
    static const char* names[3] = {"fx_N", "fy_N", "fz_N"};
    json out{{"from_s", from_s}, {"to_s", to_s}};
    if (n <= max_points) {
        std::vector<double> t(n);
        std::vector<float> v[3];
        for (std::size_t i = 0; i < n; ++i) t[i] = t_of(first + i);
        for (int a = 0; a < 3; ++a)
            for (std::size_t i = first; i < last; ++i) v[a].push_back(value(a, i));
        out["decimated"] = false;
        out["count"] = n;
        out["t_s"] = t;
        for (int a = 0; a < 3; ++a) out[names[a]] = v[a];
        return out;
    }
    const double bucket_s = (to_s - from_s) / static_cast<double>(max_points);
    auto bucket_of = [&](double t) {
        return static_cast<std::size_t>(std::clamp(std::floor((t - from_s) / bucket_s), 0.0, static_cast<double>(max_points - 1)));
    };
    std::vector<double> t0, t1;
    std::vector<float> lo[3], hi[3];
    std::size_t current = max_points;
    for (std::size_t i = first; i < last; ++i) {
        const std::size_t b = bucket_of(t_of(i));
        if (b != current) {
            current = b;
            t0.push_back(t_of(i));
            t1.push_back(t_of(i));
            for (int a = 0; a < 3; ++a) lo[a].push_back(value(a, i)), hi[a].push_back(value(a, i));
            continue;
        }
        t1.back() = t_of(i);
        for (int a = 0; a < 3; ++a) {
            lo[a].back() = std::min(lo[a].back(), value(a, i));
            hi[a].back() = std::max(hi[a].back(), value(a, i));
        }
    }
    out["decimated"] = true;
    out["count"] = t0.size();
    out["bucket_s"] = bucket_s;
    out["t_s"] = t0;
    out["t_end_s"] = t1;
    for (int a = 0; a < 3; ++a) out[names[a]] = {{"min", lo[a]}, {"max", hi[a]}};
    return out;
}

void attach(Core& core, Ctx& x) {
    const auto id = x.id();
    const auto& req = x.req;
    if (!req.has_file("file")) bad_request("part 'file' is missing: attach the dynamometer record (DynoWare or plain CSV)");
    const auto file = req.get_file_value("file");
    if (file.content.empty()) throw ApiError(400, "bad_measurement", "part 'file' is empty");
    const Settings s = settings_from_parts(req);

    auto c = core.session();
    const DoneRun run = require_done_run(*c, core.data_dir, id);
    const auto trace = stored_trace(core, *c, run.ref);
    if (trace.samples.empty()) throw ApiError(409, "conflict", fmt::format("run {} has no predicted forces", id));

    // Stored and validated in a private file first: a rejected record leaves nothing behind and never
    // replaces the one attached.
    const std::string shown = file.filename.empty() ? "file" : client_text(file.filename, "file name of part 'file'");
    // Unique per request: two attachments to one run may arrive at once; the last rename wins.
    static std::atomic<std::uint64_t> serial{0};
    const std::string unique = fmt::format("{}-{}", ::getpid(), serial.fetch_add(1));
    const fs::path tmp = run.upload_dir / fmt::format(".measurement-{}.tmp", unique);
    const fs::path tmp_settings = run.upload_dir / fmt::format(".measurement-{}.json.tmp", unique);
    struct Remove {
        fs::path a, b;
        ~Remove() {
            std::error_code ec;
            fs::remove(a, ec);
            fs::remove(b, ec);
        }
    } remove_tmp{tmp, tmp_settings};
    write_durable(tmp, file.content);
    const Compared r = compare_file(trace, tmp, shown, s);

    const json stored{{"filename", shown},
                      {"bytes", file.content.size()},
                      {"sha256", sha256_hex(file.content)},
                      {"attached_at", db::now_iso()},
                      {"attached_by", x.actor},
                      {"settings", settings_json(s)}};
    write_durable(tmp_settings, stored.dump());
    fs::rename(tmp, run.upload_dir / kDataFile);
    fs::rename(tmp_settings, run.upload_dir / kSettingsFile);
    x.res.set_header("Location", fmt::format("/api/v1/runs/{}/measurement", id));
    x.reply(201, {{"run_id", id}, {"report", report_json(r, stored)}});
}

void get_comparison(Core& core, Ctx& x) {
    const auto id = x.id();
    const auto max_points = *x.param_int("max_points");
    auto c = core.session();
    const DoneRun run = require_done_run(*c, core.data_dir, id);
    std::ifstream in(run.upload_dir / kSettingsFile);
    if (!in) not_found(fmt::format("run {} has no measurement attached (POST /api/v1/runs/{}/measurement)", id, id));
    const json stored = json::parse(in);
    const auto trace = stored_trace(core, *c, run.ref);
    const Compared r = compare_file(trace, run.upload_dir / kDataFile, stored.at("filename"), settings_from(stored.at("settings")));
    const auto& t_s = r.comparison.t_s;
    const double t0 = t_s.empty() ? 0 : t_s.front(), t1 = t_s.empty() ? 0 : t_s.back();
    const double from_s = x.param_double("from_s").value_or(t0), to_s = x.param_double("to_s").value_or(t1);
    if (to_s < from_s) bad_request(fmt::format("to_s ({}) is before from_s ({})", to_s, from_s));
    x.reply(200, {{"run_id", id},
                  {"report", report_json(r, stored)},
                  {"series", measured_series(r, from_s, to_s, static_cast<std::size_t>(max_points))}});
}

void detach(Core& core, Ctx& x) {
    const auto id = x.id();
    const auto run = core.session()->runs().status(id);
    if (!run) not_found(fmt::format("run {} does not exist", id));
    const fs::path dir = core.data_dir / run->upload_dir;
    std::error_code ec;
    if (!fs::remove(dir / kSettingsFile, ec)) not_found(fmt::format("run {} has no measurement attached", id));
    fs::remove(dir / kDataFile, ec);
    x.res.status = 204;
}

}  // namespace

void add_measurement_routes(Core& core) {
    core.route({"POST", "/api/v1/runs/{id}/measurement", Role::Write, {path_id()}, Body::Multipart,
                " with part 'file' (the dynamometer record)"},
               [&core](Ctx& x) { attach(core, x); });
    core.route({"GET", "/api/v1/runs/{id}/measurement", Role::Read,
                {path_id(), query_number("from_s", "series window start (default: first compared sample)"),
                 query_number("to_s", "series window end (default: last compared sample)"),
                 query_int("max_points", "most rows/buckets in the series (at most cutload serve --max-points)")
                     .range(2, core.opt.max_points)
                     .or_else(2000)}},
               [&core](Ctx& x) { get_comparison(core, x); });
    core.route({"DELETE", "/api/v1/runs/{id}/measurement", Role::Write, {path_id()}}, [&core](Ctx& x) { detach(core, x); });
}

}  // namespace cutload::server
