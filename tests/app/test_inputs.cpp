// The run-spec pieces both front ends check on their own: a tool (CLI --tool, the service's tool
// part and library), a material (the library, a calibration saved as one), the probe spec.
#include "app_fixtures.hpp"

#include "app/inputs.hpp"

#include <nlohmann/json.hpp>

using namespace cutload;
using namespace cutload::apptest;

TEST_CASE("probe_spec is a valid run spec, parse_tool and parse_material check one part, naming the key", "[app][inputs]") {
    const force_model::RunSpec probe = force_model::parse_run_spec(app::probe_spec());
    CHECK(probe.tool.diameter_mm == 8);

    const nlohmann::json demo = nlohmann::json::parse(read_text(source_path("data/demo_run.json")));
    const force_model::ToolSpec tool = app::parse_tool(demo["tool"]);
    const force_model::RunSpec spec = force_model::load_run_spec(source_path("data/demo_run.json"));
    CHECK(tool.diameter_mm == spec.tool.diameter_mm);
    CHECK(tool.flutes == spec.tool.flutes);
    CHECK(tool.holder.diameter_mm == spec.tool.holder.diameter_mm);
    const force_model::Material m = app::parse_material(demo["material"]);
    CHECK(m.Ktc_N_mm2 == spec.material.Ktc_N_mm2);
    CHECK(m.name == spec.material.name);

    nlohmann::json bad = demo["tool"];
    bad["diameter_mm"] = -8;
    CHECK_THROWS_WITH(app::parse_tool(bad), Catch::Contains("tool.diameter_mm"));
    nlohmann::json bad_material = demo["material"];
    bad_material["Ktc_N_mm2"] = "hard";
    CHECK_THROWS_WITH(app::parse_material(bad_material), Catch::Contains("material.Ktc_N_mm2"));
}

TEST_CASE("load_tool takes a tool object or a whole run spec, its errors start with the path", "[app][inputs]") {
    const Scratch dir("load_tool");
    const force_model::RunSpec spec = force_model::load_run_spec(source_path("data/demo_run.json"));
    const force_model::ToolSpec whole = app::load_tool(source_path("data/demo_run.json"));
    CHECK(whole.diameter_mm == spec.tool.diameter_mm);
    CHECK(whole.stickout_mm == spec.tool.stickout_mm);
    write_text(dir / "tool.json", nlohmann::json::parse(read_text(source_path("data/demo_run.json")))["tool"].dump());
    CHECK(app::load_tool((dir / "tool.json").string()).flute_length_mm == spec.tool.flute_length_mm);

    write_text(dir / "bad.json", R"({"shape": "flat", "diameter_mm": -8})");
    CHECK_THROWS_WITH(app::load_tool((dir / "bad.json").string()),
                      Catch::StartsWith((dir / "bad.json").string() + ": ") && Catch::Contains("tool.diameter_mm"));
    write_text(dir / "broken.json", R"({"shape": )");
    CHECK_THROWS_WITH(app::load_tool((dir / "broken.json").string()), Catch::Contains("not valid JSON"));
    CHECK_THROWS_WITH(app::load_tool((dir / "missing.json").string()), Catch::Contains("cannot open the tool file"));
}
