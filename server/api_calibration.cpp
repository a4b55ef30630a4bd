// Route: POST /api/v1/calibrations: identify Ktc, Krc, Kac, Kte, Kre, Kae from uploaded straight
// dynamometer tests (issue 6), the way `cutload calibrate` does, and optionally store the result as a
// library material.
//
// Synchronous: each test costs about 0.3 s of engine time (six short predictions), so the number of
// tests is capped; the body size is capped by the server as for every route (413).
#include "app/calibrate.hpp"
#include "app/inputs.hpp"
#include "core.hpp"
#include "json_in.hpp"
#include "library.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>

namespace cutload::server {
namespace {

constexpr std::size_t kMaxTests = 20;

std::optional<std::string> part(const httplib::Request& req, const char* name) {
    if (!req.has_file(name)) return std::nullopt;
    if (req.files.count(name) > 1) bad_request(fmt::format("part {} is given more than once", name));
    return client_text(req.get_file_value(name).content, fmt::format("part {}", name));
}

json json_part(const char* name, const std::string& text) {
    return parse_client_json(text, fmt::format("part {}", name), "bad_request");
}

// The `tool` part (the run spec's tool object) or `tool_id` (a library tool), checked by the engine.
force_model::ToolSpec tool_from_parts(Core& core, const httplib::Request& req) {
    const auto tool_text = part(req, "tool");
    const auto id_text = part(req, "tool_id");
    if (tool_text.has_value() == id_text.has_value())
        bad_request("give exactly one of part 'tool' (the run spec's tool object) and part 'tool_id' (a library tool)");
    json tool;
    if (tool_text) {
        tool = json_part("tool", *tool_text);
    } else {
        std::int64_t id = 0;
        try {
            std::size_t used = 0;
            id = std::stoll(*id_text, &used);
            if (used != id_text->size()) throw std::invalid_argument(*id_text);
        } catch (const std::exception&) {
            bad_request(fmt::format("part tool_id: '{}' is not an integer", *id_text));
        }
        const auto stored = library_body(*core.session(), db::LibraryKind::Tool, id);
        if (!stored) not_found(fmt::format("tool {} does not exist", id));
        tool = stored->at("tool");
    }
    try {
        return app::parse_tool(tool);
    } catch (const force_model::SpecError& e) {
        throw ApiError(400, "bad_spec", e.what());
    }
}

double number_field(const json& cond, const std::string& file, const char* key) {
    if (!cond.contains(key)) bad_request(fmt::format("part tests: '{}': {} is missing", file, key));
    const json& v = cond[key];
    if (!v.is_number() || !std::isfinite(v.get<double>()))
        bad_request(fmt::format("part tests: '{}': {} must be a number", file, key));
    return v.get<double>();
}

force_model::CutTest cut_test_of(const json& cond, const std::string& file, const force_model::ToolSpec& tool) {
    if (!cond.is_object()) bad_request(fmt::format("part tests: '{}': conditions must be an object", file));
    for (const auto& [key, value] : cond.items()) {
        static const char* known[] = {"spindle_rpm", "feed_mm_min", "axial_mm", "radial_mm", "mode",
                                      "feed_direction_deg", "from_s", "to_s", "zero_N"};
        if (std::find_if(std::begin(known), std::end(known), [&](const char* k) { return key == k; }) == std::end(known))
            bad_request(fmt::format("part tests: '{}': unknown key {}", file, key));
    }
    force_model::CutTest t;
    t.spindle_rpm = number_field(cond, file, "spindle_rpm");
    t.feed_mm_min = number_field(cond, file, "feed_mm_min");
    t.axial_mm = number_field(cond, file, "axial_mm");
    if (!cond.contains("mode") || !cond["mode"].is_string())
        bad_request(fmt::format("part tests: '{}': mode must be slot, up or down", file));
    try {
        t.mode = force_model::parse_immersion(cond["mode"].get<std::string>());
    } catch (const force_model::SpecError& e) {
        bad_request(fmt::format("part tests: '{}': {}", file, e.what()));
    }
    if (t.mode != force_model::Immersion::Slot || cond.contains("radial_mm"))
        t.radial_mm = number_field(cond, file, "radial_mm");
    if (cond.contains("feed_direction_deg")) t.feed_direction_deg = number_field(cond, file, "feed_direction_deg");
    try {
        force_model::validate_cut_test(t, tool);
    } catch (const force_model::SpecError& e) {
        bad_request(fmt::format("part tests: '{}': {}", file, e.what()));
    }
    return t;
}

std::vector<app::CalibrationTest> tests_from_parts(const httplib::Request& req, const force_model::ToolSpec& tool) {
    const auto range = req.files.equal_range("test");
    const auto count = static_cast<std::size_t>(std::distance(range.first, range.second));
    if (count == 0) bad_request("part 'test' is missing: upload one dynamometer record per test (DynoWare or plain CSV)");
    if (count > kMaxTests)
        throw ApiError(413, "too_many_tests", fmt::format("{} tests uploaded; the limit is {}", count, kMaxTests));
    const auto conditions_text = part(req, "tests");
    if (!conditions_text)
        bad_request("part 'tests' is missing: a JSON object giving each test file's conditions by file name");
    const json conditions = json_part("tests", *conditions_text);
    if (!conditions.is_object()) bad_request("part tests: must be a JSON object keyed by test file name");

    std::vector<app::CalibrationTest> tests;
    for (auto it = range.first; it != range.second; ++it) {
        const auto& f = it->second;
        if (f.filename.empty()) bad_request("a 'test' part has no file name: conditions are matched by file name");
        // Matched against the JSON's (UTF-8) keys, so decoded like any client text.
        const std::string filename = client_text(f.filename, "file name of a 'test' part");
        for (const auto& other : tests)
            if (other.file == filename) bad_request(fmt::format("test file name '{}' is used twice", filename));
        if (!conditions.contains(filename))
            bad_request(fmt::format("part tests: no conditions for test file '{}'", filename));
        const json& cond = conditions[filename];
        app::CalibrationTest t;
        t.file = filename;
        t.content = f.content;
        t.test = cut_test_of(cond, filename, tool);
        if (cond.contains("from_s")) t.from_s = number_field(cond, filename, "from_s");
        if (cond.contains("to_s")) t.to_s = number_field(cond, filename, "to_s");
        if (t.from_s && t.to_s && !(*t.to_s > *t.from_s))
            bad_request(fmt::format("part tests: '{}': to_s must be after from_s", filename));
        if (cond.contains("zero_N")) {
            const json& z = cond["zero_N"];
            if (!z.is_array() || z.size() != 3 ||
                !std::all_of(z.begin(), z.end(), [](const json& v) { return v.is_number() && std::isfinite(v.get<double>()); }))
                bad_request(fmt::format("part tests: '{}': zero_N must be three numbers (Fx, Fy, Fz in the record's "
                                        "channels)",
                                        filename));
            t.zero_dyn_N = std::array<double, 3>{z[0].get<double>(), z[1].get<double>(), z[2].get<double>()};
        }
        tests.push_back(std::move(t));
    }
    for (const auto& [name, cond] : conditions.items())
        if (std::none_of(tests.begin(), tests.end(), [&](const app::CalibrationTest& t) { return t.file == name; }))
            bad_request(fmt::format("part tests: conditions for '{}' but no test file of that name", name));
    return tests;
}

json vec3(const std::array<double, 3>& v) { return json::array({v[0], v[1], v[2]}); }

[[noreturn]] void material_name_taken(const std::string& name) {
    throw ApiError(409, "name_taken", fmt::format("a material named '{}' already exists", name));
}

void ensure_material_name_free(Core& core, const std::string& name) {
    if (core.session()->library().find_by_name(db::LibraryKind::Material, name)) material_name_taken(name);
}

void calibrate(Core& core, Ctx& x) {
    const auto& req = x.req;
    app::CalibrationInput in;
    in.tool = tool_from_parts(core, req);
    in.tests = tests_from_parts(req, in.tool);

    if (auto a = part(req, "axes")) {
        try {
            in.axes = force_model::parse_axis_matrix(*a);
        } catch (const force_model::MeasurementError& e) {
            throw ApiError(400, "bad_measurement", fmt::format("part axes: {}", e.what()));
        }
    }
    if (auto m = part(req, "measured_on")) {
        if (*m != "workpiece" && *m != "tool") bad_request(fmt::format("part measured_on: '{}' is not workpiece or tool", *m));
        in.measured_on_workpiece = *m == "workpiece";
    }
    const std::optional<std::string> save_as = part(req, "save_as");
    if (save_as) {
        if (save_as->empty() || save_as->size() > 200) bad_request("part save_as: a material name of 1..200 characters");
        ensure_material_name_free(core, *save_as);   // before the work; the insert checks again
    }
    in.material_name = save_as.value_or("calibrated");

    // The same use case as `cutload calibrate`, with engine regressors on the CPU.
    app::Calibration cal;
    try {
        cal = app::calibrate(in);
    } catch (const app::SteadyInputNeeded& e) {
        throw ApiError(400, "bad_measurement",
                       fmt::format("{} ({})", e.what(),
                                   e.need == force_model::SteadyError::Need::Window
                                       ? fmt::format("from_s and to_s in the conditions of '{}', record time", e.file)
                                       : fmt::format("zero_N in the conditions of '{}': the record's reading with "
                                                     "no load at its first sample, in its own channels",
                                                     e.file)));
    } catch (const force_model::MeasurementError& e) {
        throw ApiError(400, "bad_measurement", e.what());
    } catch (const force_model::SpecError& e) {
        throw ApiError(400, "bad_tests", e.what());
    }
    const force_model::CalibrationFit& fit = cal.fit;
    const json material = force_model::material_json(fit.material);

    json per_test = json::array();
    for (std::size_t i = 0; i < in.tests.size(); ++i) {
        const auto& t = in.tests[i].test;
        const auto& s = cal.tests[i].steady;
        per_test.push_back({{"file", in.tests[i].file},
                            {"mode", force_model::immersion_name(t.mode)},
                            {"spindle_rpm", t.spindle_rpm},
                            {"feed_mm_min", t.feed_mm_min},
                            {"axial_mm", t.axial_mm},
                            {"radial_mm", t.radial_mm},
                            {"steady_from_s", s.t_start_s},
                            {"steady_to_s", s.t_end_s},
                            {"window_source", s.window_given ? "given" : "detected"},
                            {"revolutions", s.revolutions},
                            {"zero_removed", s.zeroed},
                            {"zero_N", vec3(s.zero_N)},
                            {"zero_source", force_model::zero_source_name(s.zero.source)},
                            {"drift_source", force_model::drift_source_name(s.zero.drift_source)},
                            {"drift_N_per_s", vec3(s.zero.drift_N_per_s)},
                            {"drift_N", vec3(s.drift_N())},
                            {"mean_force_feed_frame_N", vec3(cal.tests[i].mean_feed_frame_N)},
                            {"residual_rms_N", fit.group_rms_residual_N[i]}});
    }
    json out{{"material", material},
             {"fit",
              {{"equations", fit.equations},
               {"rms_residual_N", fit.rms_residual_N},
               {"relative_rms_residual", fit.relative_rms_residual},
               {"condition_number", fit.condition_number}}},
             {"tests", per_test},
             {"saved", nullptr}};
    if (!save_as) return x.reply(200, out);

    // Stored only if the engine accepts it, as POST /api/v1/materials would.
    try {
        app::parse_material(material);
    } catch (const force_model::SpecError& e) {
        throw ApiError(400, "bad_tests",
                       fmt::format("the identified coefficients are not a valid material ({}); nothing was saved", e.what()));
    }
    json stored = material;
    stored.erase("name");
    const auto saved = core.session()->library().create(db::LibraryKind::Material, *save_as, stored.dump(), db::now_iso());
    if (!saved) material_name_taken(*save_as);
    const std::int64_t id = *saved;
    x.res.set_header("Location", fmt::format("/api/v1/materials/{}", id));
    out["saved"] = {{"id", id}, {"name", *save_as}};
    x.reply(201, out);
}

}  // namespace

void add_calibration_routes(Core& core) {
    core.route({"POST", "/api/v1/calibrations", Role::Write, {}, Body::Multipart,
                ": 'tool' or 'tool_id', 'tests', one 'test' file per test"},
               [&core](Ctx& x) { calibrate(core, x); });
}

}  // namespace cutload::server
