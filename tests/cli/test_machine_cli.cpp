// `cutload predict --machine`: a log with rotary axes through a machine definition, as a user runs
// it; without one the rotary axes are said to be ignored, and a pose the engine cannot take is one
// line and a non-zero exit.
#include "cli/run_cli.hpp"

#include <fmt/format.h>

#include <fstream>

using namespace cutload;
namespace fs = std::filesystem;

namespace {

// Readings every 4 ms: the tool standing 100 mm off the AC machine's C line while C turns 30 deg/s
// (shown 0 to 360) and A holds a_deg; spindle 10 000 rpm.
std::string turning_table_log(double a_deg) {
    std::string csv = "t,x,y,z,a,c,spindle\n";
    for (int k = 0; k <= 500; ++k) {
        const double t = 0.004 * k;
        csv += fmt::format("{:.3f},-250.000,-275.000,-400.000,{:.3f},{:.3f},10000\n", t, a_deg,
                           std::fmod(350 + 30 * t, 360.0));
    }
    return csv;
}

}  // namespace

TEST_CASE("predict --machine: rotary axes become the tool's motion, a tilted tool is refused in one line",
          "[cli][five_axis]") {
    const fs::path dir = clitest::scratch("machine_cli");
    const std::string spec = clitest::source("data/demo_run.json");
    const std::string machine = clitest::source("data/machines/ac_table_table.json");
    std::ofstream(dir / "level.csv") << turning_table_log(0);
    std::ofstream(dir / "tilted.csv") << turning_table_log(-15);
    auto predict = [&](const std::string& log, const std::string& extra) {
        return clitest::run("predict " + (dir / log).string() + " --spec " + spec + " --device cpu -q --out " +
                            (dir / "forces.csv").string() + extra);
    };

    const clitest::Result plain = predict("level.csv", "");
    INFO(plain.output);
    CHECK(plain.exit_code == 0);
    CHECK_THAT(plain.output, Catch::Contains("holds rotary axes (ac) but no machine definition"));

    const clitest::Result level = predict("level.csv", " --machine " + machine + " --tool-length-mm 0");
    INFO(level.output);
    CHECK(level.exit_code == 0);
    CHECK_THAT(level.output, !Catch::Contains("no machine definition"));
    CHECK(fs::file_size(dir / "forces.csv") > 0);

    const std::string forces_before = [&] {
        std::ifstream in(dir / "forces.csv", std::ios::binary);
        return std::string(std::istreambuf_iterator<char>(in), {});
    }();
    const clitest::Result tilted = predict("tilted.csv", " --machine " + machine);
    INFO(tilted.output);
    CHECK(tilted.exit_code != 0);
    CHECK_THAT(tilted.output, Catch::Contains("leans 15 deg") && Catch::Contains("multi-direction stock"));
    CHECK(std::count(tilted.output.begin(), tilted.output.end(), '\n') == 1);
    // Refused before any row: the earlier FORCES.csv is untouched and no temporary file is left.
    {
        std::ifstream in(dir / "forces.csv", std::ios::binary);
        CHECK(std::string(std::istreambuf_iterator<char>(in), {}) == forces_before);
    }
    std::size_t files = 0;
    for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++files;
    CHECK(files == 3);   // level.csv, tilted.csv, forces.csv

    const clitest::Result bad = predict("level.csv", " --machine " + spec);
    INFO(bad.output);
    CHECK(bad.exit_code != 0);
    CHECK_THAT(bad.output, Catch::Contains("demo_run.json"));
}
