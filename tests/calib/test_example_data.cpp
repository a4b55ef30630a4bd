// Generator for the worked example of docs/compare_calibrate.md (hidden: run it by name).
//   CUTLOAD_CALIB_EXAMPLE_DIR=/tmp/ex build/tests/test_calib "[example]"
// writes TOOL.json, FORCES_down.csv (a prediction) and dyno_*.csv (DynoWare-style records of the same
// cuts with the seed's axis matrix, runout, noise, a zero offset and a delay).
#include "calib/dyno_fixture.hpp"
#include "force_model/calibrate.hpp"

#include <catch2/catch.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>

using namespace cutload;
using namespace cutload::calibtest;

TEST_CASE("write the worked example's files", "[.][example]") {
    const char* env = std::getenv("CUTLOAD_CALIB_EXAMPLE_DIR");
    REQUIRE(env != nullptr);
    const std::filesystem::path dir(env);
    std::filesystem::create_directories(dir);
    force_model::RunSpec spec;
    spec.tool = test_tool();
    spec.stock.max_mm[0] = spec.stock.max_mm[1] = spec.stock.max_mm[2] = 1;
    spec.material = true_material();
    std::ofstream(dir / "TOOL.json") << force_model::to_json(spec)["tool"].dump(2) << "\n";

    struct Test {
        const char* name;
        double feed_per_tooth_mm;
        Side side;
        double radial_mm;
    };
    const Test tests[] = {{"slot_f04", 0.04, Side::Slot, 0}, {"slot_f08", 0.08, Side::Slot, 0},
                          {"slot_f12", 0.12, Side::Slot, 0}, {"slot_f16", 0.16, Side::Slot, 0},
                          {"down_f08", 0.08, Side::Down, 2}, {"down_f14", 0.14, Side::Down, 2}};
    unsigned seed = 300;
    for (const Test& t : tests) {
        const StraightCut cut = straight_cut(t.feed_per_tooth_mm, 2, t.side, t.radial_mm);
        force_model::PredictOptions o;
        o.device = force_model::Device::Cpu;
        const force_model::Prediction p = force_model::predict(cut.motion, cut.spec, o);
        DynoOptions dyno;
        dyno.seed = seed++;
        write_dyno_file(p, (dir / fmt::format("dyno_{}.csv", t.name)).string(), dyno);
        if (std::string(t.name) == "down_f08") force_model::write_forces_csv(p, (dir / "FORCES_down.csv").string());
    }
    CHECK(std::filesystem::exists(dir / "FORCES_down.csv"));
}
