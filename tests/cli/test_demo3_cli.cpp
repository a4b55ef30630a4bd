// The five-axis demo end to end, as a user runs it: `cutload predict data/demo3_dryrun.csv --spec
// data/demo3_run.json --machine data/machines/ac_table_table.json`. The ring groove it cuts by
// turning the C table has a closed-form volume, pi (41^2 - 32^2) x 2 mm = 4128.2 mm^3 (tool centre
// on R35 then R38, D6, 2 mm deep), and the tool cuts nothing until it plunges.
#include "cli/run_cli.hpp"

#include <fmt/format.h>

#include <algorithm>

#include <fstream>
#include <map>
#include <numbers>
#include <sstream>

using namespace cutload;
namespace fs = std::filesystem;

namespace {

// BLOCKS.csv: block -> (peak force N, removed mm^3). Block names here hold no commas or quotes.
std::map<std::string, std::pair<double, double>> read_blocks(const fs::path& path) {
    std::ifstream in(path);
    std::string line;
    std::getline(in, line);
    std::vector<std::string> head;
    {
        std::stringstream ss(line);
        for (std::string c; std::getline(ss, c, ',');) head.push_back(c);
    }
    const auto col = [&](const std::string& name) {
        const auto it = std::find(head.begin(), head.end(), name);
        REQUIRE(it != head.end());
        return std::size_t(it - head.begin());
    };
    const std::size_t peak = col("peak_force_N"), removed = col("removed_mm3");
    std::map<std::string, std::pair<double, double>> out;
    while (std::getline(in, line)) {
        std::vector<std::string> f;
        std::stringstream ss(line);
        for (std::string c; std::getline(ss, c, ',');) f.push_back(c);
        REQUIRE(f.size() > std::max(peak, removed));
        auto& [p, v] = out[f[0]];
        p = std::max(p, std::stod(f[peak]));
        v += std::stod(f[removed]);
    }
    return out;
}

}  // namespace

TEST_CASE("demo3: predict --machine cuts the ring groove by turning the C table", "[cli][five_axis][demo3]") {
    const fs::path dir = clitest::scratch("demo3_cli");
    const clitest::Result r = clitest::run(
        "predict " + clitest::source("data/demo3_dryrun.csv") + " --spec " + clitest::source("data/demo3_run.json") +
        " --machine " + clitest::source("data/machines/ac_table_table.json") + " --tool-length-mm 0 --device cpu -q --out " +
        (dir / "forces.csv").string() + " --blocks " + (dir / "blocks.csv").string());
    INFO(r.output);
    REQUIRE(r.exit_code == 0);
    const auto blocks = read_blocks(dir / "blocks.csv");
    double removed = 0;
    for (const auto& [name, b] : blocks) removed += b.second;
    const double groove_mm3 = std::numbers::pi * (41.0 * 41.0 - 32.0 * 32.0) * 2;
    CHECK(removed == Approx(groove_mm3).epsilon(0.01));
    // Above the stock (the approach rapid, the last retract) nothing is cut; the turns cut.
    for (const char* above : {"N30", "N90"}) {
        REQUIRE(blocks.count(above));
        CHECK(blocks.at(above).first == 0);
        CHECK(blocks.at(above).second == 0);
    }
    REQUIRE(blocks.count("N50"));
    REQUIRE(blocks.count("N70"));
    CHECK(blocks.at("N50").first > 50);
    CHECK(blocks.at("N70").first > 50);
    // The G93 turn cuts the full groove (R32..R38 less the plunge hole), the G94 one widens it
    // (R38..R41): their volumes in that ratio within a few percent.
    const double n50_mm3 = std::numbers::pi * (38.0 * 38.0 - 32.0 * 32.0) * 2 - std::numbers::pi * 9 * 2;
    CHECK(blocks.at("N50").second == Approx(n50_mm3).epsilon(0.03));
}

TEST_CASE("demo3: predict --machine --program compares the C-turned groove with its program", "[cli][five_axis][demo3]") {
    const fs::path dir = clitest::scratch("demo3_program_cli");
    const std::string base = "predict " + clitest::source("data/demo3_dryrun.csv") + " --spec " +
                             clitest::source("data/demo3_run.json") + " --machine " +
                             clitest::source("data/machines/ac_table_table.json") + " --tool-length-mm 0 --device cpu --out " +
                             (dir / "forces.csv").string() + " --program " + clitest::source("data/demo3_program.nc");
    const clitest::Result r = clitest::run(base + " --work-offset G54=-350,-275,-460");
    INFO(r.output);
    REQUIRE(r.exit_code == 0);
    // The comparison rows: block, then the programmed feed as the tip's speed against the part:
    // N50's G93 turn 2 pi 35 x 13.642 = 3000 mm/min, N70's 3600 deg/min at R38 = 2388 mm/min.
    auto row = [&](const std::string& block) {
        std::istringstream in(r.output);
        for (std::string line; std::getline(in, line);)
            if (line.rfind(block + " ", 0) == 0) return line;
        return std::string();
    };
    auto feed_of = [&](const std::string& block) {
        std::istringstream f(row(block));
        std::string name;
        double feed = 0;
        f >> name >> feed;
        return feed;
    };
    CHECK(feed_of("N50") == Approx(3000).margin(1));
    CHECK(feed_of("N70") == Approx(2388).margin(1));

    // The wrong work offset puts the program's groove elsewhere on the part: refused in one line.
    const clitest::Result wrong = clitest::run(base);
    INFO(wrong.output);
    CHECK(wrong.exit_code != 0);
    CHECK(std::count(wrong.output.begin(), wrong.output.end(), '\n') == 1);
}
