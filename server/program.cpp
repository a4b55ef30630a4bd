#include "program.hpp"

#include "jobs.hpp"
#include "results.hpp"
#include "db/optimizations.hpp"
#include "db/runs.hpp"

#include "textio/csv.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <iterator>
#include <regex>

namespace cutload::server {
namespace fs = std::filesystem;
namespace {

[[noreturn]] void bad_option(const std::string& key, const std::string& why) {
    throw ApiError(400, "bad_request", fmt::format("nc_options.{}: {}", key, why));
}

double number_in(const json& o, const char* key, double lo, double hi, const char* unit) {
    const json& v = o[key];
    if (!v.is_number()) bad_option(key, "must be a number");
    const double x = v.get<double>();
    if (!(x >= lo && x <= hi)) bad_option(key, fmt::format("{} is outside {}..{}{}", x, lo, hi, unit));
    return x;
}

std::string one_of(const json& o, const char* key, std::initializer_list<const char*> allowed) {
    const json& v = o[key];
    std::string names;
    for (const char* a : allowed) {
        if (v.is_string() && v.get<std::string>() == a) return a;
        names += fmt::format("{}\"{}\"", names.empty() ? "" : " or ", a);
    }
    bad_option(key, "must be " + names);
}

bool boolean(const json& o, const char* key) {
    if (!o[key].is_boolean()) bad_option(key, "must be true or false");
    return o[key].get<bool>();
}

json mapping_json(const app::ProgramRun& run) {
    const auto& q = run.mapping.quality;
    return {{"source", run.mapped ? "mapping" : "log"},
            {"samples", q.samples},
            {"matched", q.matched},
            {"matched_fraction", q.matched_fraction},
            {"counted_matched_fraction", q.counted_matched_fraction},
            {"excluded_fraction", q.excluded_fraction},
            {"excluded_samples", {{"at_rest", q.excluded_at_rest}, {"away", q.excluded_away}, {"tool_change", q.excluded_tool_change}}},
            {"mean_distance_mm", q.mean_distance_mm},
            {"p95_distance_mm", q.p95_distance_mm},
            {"max_distance_mm", q.max_distance_mm},
            {"coverage", q.coverage},
            {"agreement", q.agreement ? json(*q.agreement) : json(nullptr)},
            {"estimated_lead_ms", run.estimated_lead_s ? json(*run.estimated_lead_s * 1e3) : json(nullptr)},
            {"blocks_without_samples", q.blocks_without_samples}};
}

json comparison_json(const force_model::BlockComparison& r) {
    return {{"block", r.block},
            {"rapid", r.rapid},
            {"programmed_feed_mm_min", r.programmed_feed_mm_min},
            {"samples", r.samples},
            {"max_deviation_mm", r.max_deviation_mm},
            {"mean_deviation_mm", r.mean_deviation_mm},
            {"actual_min_feed_mm_min", r.actual_min_feed_mm_min},
            {"actual_mean_feed_mm_min", r.actual_mean_feed_mm_min},
            {"actual_max_feed_mm_min", r.actual_max_feed_mm_min},
            {"feed_deficit_pct", r.feed_deficit_pct},
            {"feed_surge_pct", r.feed_surge_pct},
            {"commanded_duration_s", r.commanded_duration_s},
            {"actual_duration_s", r.actual_duration_s},
            {"commanded_peak_force_N", r.commanded_peak_force_N},
            {"actual_peak_force_N", r.actual_peak_force_N},
            {"force_difference_N", r.force_difference_N},
            {"force_difference_pct", r.force_difference_pct}};
}

double peak_force_of(const force_model::Prediction& p, const std::string& block) {
    for (const auto& b : p.blocks)
        if (b.block == block) return b.peak_force_N;
    return 0;
}

}  // namespace

app::ProgramSettings program_settings(const json& o) {
    if (!o.is_object()) throw ApiError(400, "bad_request", "nc_options: must be a JSON object");
    app::ProgramSettings s;
    static const std::regex work_system("G5[4-9]");
    for (const auto& [key, v] : o.items()) {
        if (key == "work_offsets_mm") {
            if (!v.is_object()) bad_option(key, "must be an object like {\"G55\": [x, y, z]}");
            for (const auto& [name, xyz] : v.items()) {
                if (!std::regex_match(name, work_system)) bad_option(key, fmt::format("'{}' is not G54..G59", name));
                if (!xyz.is_array() || xyz.size() != 3 || !xyz[0].is_number() || !xyz[1].is_number() || !xyz[2].is_number())
                    bad_option(key + "." + name, "must be [x, y, z] in mm");
                s.work_offsets_mm[name] = {xyz[0].get<double>(), xyz[1].get<double>(), xyz[2].get<double>()};
            }
        } else if (key == "ignore_words") {
            if (!v.is_array()) bad_option(key, "must be an array of words like [\"G28\", \"H\"]");
            static const std::regex word("[A-Za-z]([0-9]+(\\.[0-9]+)?)?");
            for (const auto& w : v) {
                if (!w.is_string() || !std::regex_match(w.get<std::string>(), word))
                    bad_option(key, fmt::format("{} is not a letter or a code like \"G28\" or \"H\"", w.dump()));
                s.ignore_words.push_back(w.get<std::string>());
            }
        } else if (key == "rapid_feed_mm_min") {
            s.rapid_mm_min = number_in(o, "rapid_feed_mm_min", s.limits.min_rapid_mm_min, s.limits.max_rapid_mm_min, " mm/min");
        } else if (key == "arc_centers") {
            s.arc_centers = one_of(o, "arc_centers", {"incremental", "absolute"}) == std::string("absolute")
                                ? motion_io::ArcCenters::Absolute
                                : motion_io::ArcCenters::Incremental;
        } else if (key == "program_units") {
            s.program_units = one_of(o, "program_units", {"mm", "in"}) == std::string("in") ? motion_io::ProgramUnits::Inch
                                                                                          : motion_io::ProgramUnits::Mm;
        } else if (key == "arc_tolerance_mm") {
            s.arc_tolerance_mm = number_in(o, "arc_tolerance_mm", 0, 10, " mm");
        } else if (key == "tool_change_on_t") {
            s.tool_change_on_t = boolean(o, "tool_change_on_t");
        } else if (key == "block_skip") {
            s.block_skip = boolean(o, "block_skip");
        } else if (key == "min_match") {
            s.min_match = number_in(o, "min_match", 0, 1, "");
        } else if (key == "block_lead_ms") {
            s.block_lead_ms = number_in(o, "block_lead_ms", 0, 10000, " ms");
        } else if (key == "map_blocks") {
            s.map_blocks = boolean(o, "map_blocks");
        } else if (key == "decimal_less_is_increment") {
            s.decimal_less_is_increment = boolean(o, "decimal_less_is_increment");
        } else if (key == "rotary_feed") {
            s.rotary_feed = one_of(o, "rotary_feed", {"combined", "linear_only"}) == std::string("linear_only")
                                ? motion_io::RotaryFeed::LinearOnly
                                : motion_io::RotaryFeed::Combined;
        } else {
            throw ApiError(400, "bad_request",
                           fmt::format("nc_options: unknown key '{}' (known: work_offsets_mm, ignore_words, rapid_feed_mm_min, "
                                       "block_lead_ms, map_blocks, decimal_less_is_increment, arc_centers, program_units, "
                                       "arc_tolerance_mm, tool_change_on_t, block_skip, min_match, rotary_feed)",
                                       key));
        }
    }
    return s;
}

app::ProgramSource program_source(const json& nc, const fs::path& upload_dir) {
    app::ProgramSource source;
    source.path = (upload_dir / nc.at("stored_as").get<std::string>()).string();
    source.name = nc.value("filename", std::string("program.nc"));
    source.settings = program_settings(nc.value("options", json::object()));
    return source;
}

json program_body(const ProgramResult& r, const json& commanded_summary) {
    // Where each block is written and the spindle speed it runs at, for the page's NC listing.
    std::map<std::string, const motion_io::NcBlock*> source;
    for (const auto& b : r.run.program.blocks) source.try_emplace(b.name, &b);
    json blocks = json::array();
    for (const auto& row : r.prediction.blocks) {
        json j = comparison_json(row);
        if (const auto it = source.find(row.block); it != source.end()) {
            j["line"] = it->second->line;
            j["spindle_rpm"] = it->second->spindle_rpm;
        }
        blocks.push_back(std::move(j));
    }
    return {{"filename", r.filename},
            {"program_blocks", r.run.program.blocks.size()},
            {"tools", motion_io::program_tools(r.run.program)},
            {"mapping", mapping_json(r.run)},
            {"commanded", commanded_summary},
            {"blocks", blocks}};
}

std::string comparison_csv(const json& blocks) {
    std::string out;
    for (const auto& c : force_model::comparison_columns()) out += (out.empty() ? "" : ",") + c;
    out += '\n';
    for (const auto& b : blocks) {
        bool first = true;
        for (const auto& c : force_model::comparison_columns()) {
            if (!first) out += ',';
            first = false;
            const json& v = b.at(c);
            if (v.is_string())
                textio::append_field(out, v.get<std::string>());
            else if (v.is_boolean())
                out += v.get<bool>() ? "1" : "0";
            else if (v.is_number_float())
                out += fmt::format("{:.6g}", v.get<double>());
            else
                out += v.dump();
        }
        out += '\n';
    }
    return out;
}

json optimization_params(const json& body) {
    if (!body.is_object()) bad_request("request body: must be a JSON object");
    json p{{"target", 0.8},      {"min_feed_mm_min", 10.0}, {"max_feed_mm_min", nullptr}, {"basis", "actual"},
           {"max_predictions", 8}, {"only_flagged", false},  {"never_raise", false},      {"feed_step_mm_min", 50.0}};
    auto number = [&](const std::string& key, double lo, double hi) {
        const json& v = body[key];
        if (!v.is_number()) bad_request(fmt::format("{}: must be a number", key));
        const double x = v.get<double>();
        if (!(x >= lo && x <= hi)) bad_request(fmt::format("{}: {} is outside {}..{}", key, x, lo, hi));
        return x;
    };
    for (const auto& [key, v] : body.items()) {
        if (key == "target") {
            p[key] = number(key, 0.05, 1.0);
        } else if (key == "min_feed_mm_min") {
            p[key] = number(key, 1e-3, 1e6);
        } else if (key == "max_feed_mm_min") {
            if (!v.is_null()) p[key] = number(key, 1e-3, 1e6);
        } else if (key == "basis") {
            if (v != "actual" && v != "commanded") bad_request("basis: must be \"actual\" or \"commanded\"");
            p[key] = v;
        } else if (key == "max_predictions") {
            if (!v.is_number_integer()) bad_request("max_predictions: must be an integer");
            p[key] = static_cast<int>(number(key, 2, 20));
        } else if (key == "only_flagged" || key == "never_raise") {
            if (!v.is_boolean()) bad_request(fmt::format("{}: must be true or false", key));
            p[key] = v;
        } else if (key == "feed_step_mm_min") {
            p[key] = number(key, 0, 1000);
        } else {
            bad_request(fmt::format("unknown key '{}' (known: target, min_feed_mm_min, max_feed_mm_min, basis, max_predictions, "
                                    "only_flagged, never_raise, feed_step_mm_min)",
                                    key));
        }
    }
    if (!p["max_feed_mm_min"].is_null() && p["max_feed_mm_min"].get<double>() <= p["min_feed_mm_min"].get<double>())
        bad_request(fmt::format("max_feed_mm_min ({}) must be above min_feed_mm_min ({})", p["max_feed_mm_min"].dump(),
                                p["min_feed_mm_min"].dump()));
    return p;
}

bool run_optimization(db::Store& store, const fs::path& data_dir, bool use_opencl, std::int64_t id,
                      const std::string& claim, const std::atomic<bool>& cancel,
                      const std::function<void(double)>& progress) {
    json params, inputs;
    fs::path dir;
    std::optional<std::int64_t> base_run;
    {
        auto s = store.session();
        const auto o = s->optimizations().get(id);
        const auto run = o ? s->runs().get(o->run_id) : std::nullopt;
        if (!run) return false;   // deleted meanwhile
        params = json::parse(o->params_json);
        inputs = json::parse(run->inputs_json);
        dir = data_dir / run->upload_dir;
        base_run = run->base_run;
    }
    app::RunInput run = run_input(inputs, dir, use_opencl);
    app::OptimizeInput in;
    in.log_path = run.log_path;
    in.read = run.read;
    in.spec = run.spec;
    in.program = program_source(inputs.at("nc_program"), dir);
    in.device = run.device;
    const force_model::StockPtr base = load_base_stock(store, base_run);
    in.base_stock = base.get();
    in.search.target = params["target"].get<double>();
    in.search.min_feed_mm_min = params["min_feed_mm_min"].get<double>();
    in.search.max_feed_mm_min = params["max_feed_mm_min"].is_null() ? 0.0 : params["max_feed_mm_min"].get<double>();
    in.search.max_predictions = params["max_predictions"].get<int>();
    in.search.basis = params["basis"] == "commanded" ? force_model::FeedBasis::Commanded : force_model::FeedBasis::Actual;

    // Optimizations stored before these options existed ran without them.
    in.search.only_flagged = params.value("only_flagged", false);
    in.search.never_raise = params.value("never_raise", false);
    in.search.feed_step_mm_min = params.value("feed_step_mm_min", 0.0);

    app::Control control;
    control.cancel = &cancel;
    control.progress = [&](app::Phase, double f) { progress(f); };
    const app::OptimizeResult o = app::optimize_feeds(in, control);
    const force_model::FeedOptimization& r = o.feeds;

    json blocks = json::array();
    for (const auto& b : r.blocks) {
        std::vector<std::string> cleared;
        std::set_difference(b.flags_before.begin(), b.flags_before.end(), b.flags_after.begin(), b.flags_after.end(),
                            std::back_inserter(cleared));
        blocks.push_back({{"block", b.block},
                          {"programmed_feed_mm_min", b.programmed_feed_mm_min},
                          {"recommended_feed_mm_min", b.recommended_feed_mm_min},
                          {"binding", b.binding},
                          {"ratio_before", b.ratio_before},
                          {"ratio_after", b.ratio_after},
                          {"at_feed_limit", b.at_feed_limit},
                          {"peak_force_before_N", peak_force_of(r.before, b.block)},
                          {"peak_force_after_N", peak_force_of(r.after, b.block)},
                          {"flags_before", b.flags_before},
                          {"flags_after", b.flags_after},
                          {"flags_cleared", cleared}});
    }
    const json result{{"blocks", blocks},
                      {"predictions", r.predictions},
                      {"target_met", r.target_met},
                      {"max_ratio_after", r.max_ratio_after},
                      {"max_ratio_block", r.max_ratio_block},
                      {"exceeds_limit", r.max_ratio_after > 1},
                      {"changed_blocks", o.changed_blocks},
                      {"cycle_before_s", r.before.stats.simulated_s},
                      {"cycle_after_s", r.after.stats.simulated_s}};
    if (cancel) throw force_model::Cancelled();
    auto s = store.session();
    db::Transaction tx(*s);
    if (!s->jobs().holds(db::kOptimizationQueue, id, claim)) return false;
    const bool stored = s->optimizations().mark_done(id, result.dump(), o.program_text, db::now_iso());
    tx.commit();
    return stored;
}

}  // namespace cutload::server
