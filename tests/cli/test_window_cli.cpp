// `cutload predict --window FROM:TO` as a user runs it: on the bundled three-tool demo (tool
// changes, idle stretches, an inch post), the window's FORCES.csv rows are the whole run's rows in
// that time, byte for byte, and bad windows end in one line and a non-zero exit.
#include "cli/run_cli.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace fs = std::filesystem;
using namespace cutload::clitest;

namespace {

// The data lines of a FORCES.csv with from_s <= t_s < to_s (all of them when to_s is infinite).
std::string lines_between(const fs::path& p, double from_s, double to_s) {
    std::ifstream in(p, std::ios::binary);
    REQUIRE(in);
    std::string line, out;
    std::getline(in, line);   // header
    while (std::getline(in, line)) {
        const double t = std::stod(line.substr(0, line.find(',')));
        if (t >= from_s && t < to_s) out += line + "\n";
    }
    return out;
}

}  // namespace

TEST_CASE("cli window: the rows of --window are the whole run's rows there, byte for byte") {
    const fs::path dir = scratch("window_cli");
    const std::string common = source("data/demo2_dryrun.csv") + " --spec " + source("data/demo2_run.json") + " -q";
    const Result whole = run("predict " + common + " --out " + (dir / "whole.csv").string());
    REQUIRE(whole.exit_code == 0);
    // In T2's cut, and across the change from T2 to T3 (at 53.04 s in the demo's rows).
    for (const auto& [from_s, to_s] : {std::pair{30.0, 31.0}, std::pair{52.0, 54.5}}) {
        INFO(from_s << " .. " << to_s);
        std::ostringstream window;
        window << from_s << ":" << to_s;
        const fs::path out = dir / ("window_" + std::to_string(int(from_s)) + ".csv");
        const Result r = run("predict " + common + " --out " + out.string() + " --blocks " + (dir / "blocks.csv").string() +
                             " --window " + window.str());
        REQUIRE(r.exit_code == 0);
        CHECK(r.output.find("simulated " + std::to_string(to_s - from_s).substr(0, 5)) != std::string::npos);
        const std::string rows = lines_between(out, -1e300, 1e300);
        CHECK(rows.size() > 10000);
        CHECK(rows == lines_between(dir / "whole.csv", from_s, to_s));
        if (from_s == 52.0) {   // both tools' rows are there (the fourth column: tool)
            std::istringstream in(rows);
            std::string line;
            bool t2 = false, t3 = false;
            while (std::getline(in, line)) {
                std::istringstream fields(line);
                std::string field;
                for (int k = 0; k < 4; ++k) std::getline(fields, field, ',');
                t2 |= field == "2";
                t3 |= field == "3";
            }
            CHECK(t2);
            CHECK(t3);
        }
    }
}

TEST_CASE("cli window: bad windows and what a window cannot be combined with end in one line") {
    const fs::path dir = scratch("window_cli_errors");
    const std::string common = source("data/demo2_dryrun.csv") + " --spec " + source("data/demo2_run.json") + " -q --out " +
                               (dir / "f.csv").string();
    const auto refused = [&](const std::string& args, const std::string& words) {
        INFO(args);
        const Result r = run("predict " + common + " " + args);
        CHECK(r.exit_code != 0);
        CHECK(r.output.find(words) != std::string::npos);
        CHECK(std::count(r.output.begin(), r.output.end(), '\n') == 1);
        CHECK_FALSE(fs::exists(dir / "f.csv"));
    };
    refused("--window 12", "is not FROM:TO");
    refused("--window a:b", "is not FROM:TO");
    refused("--window 5:2", "must be below");
    refused("--window 500:501", "outside the log's motion");
    refused("--window 1:2 --save-stock " + (dir / "s.bin").string(), "excludes");
    refused("--checkpoints " + (dir / "ck").string() + " --machine " + source("data/machines/ac_table_table.json"), "excludes");
}

TEST_CASE("cli window: --checkpoints keeps a whole run's stock checkpoints, and a window of the same inputs walks from one") {
    const fs::path dir = scratch("window_cli_checkpoints");
    const std::string common = source("data/demo2_dryrun.csv") + " --spec " + source("data/demo2_run.json") + " -q";
    const std::string folder = (dir / "checkpoints").string();
    const Result whole = run("predict " + common + " --out " + (dir / "whole.csv").string() + " --checkpoints " + folder);
    REQUIRE(whole.exit_code == 0);
    // The 72 s demo: one checkpoint, at the first air move a minute in.
    std::size_t files = 0;
    for (const auto& e : fs::directory_iterator(folder)) files += e.path().filename().string().ends_with(".stock.gz") ? 1 : 0;
    CHECK(files == 1);
    const fs::path out = dir / "window.csv";
    const Result r = run("predict " + common + " --out " + out.string() + " --checkpoints " + folder + " --window 65:66");
    REQUIRE(r.exit_code == 0);
    CHECK(r.output.find("window walked from 60.4") != std::string::npos);
    CHECK(r.output.find("(a stock checkpoint)") != std::string::npos);
    const std::string rows = lines_between(out, -1e300, 1e300);
    CHECK(rows.size() > 10000);
    CHECK(rows == lines_between(dir / "whole.csv", 65, 66));
    // Other inputs (here the motion resampled at 2 ms) do not take another run's checkpoint.
    const Result other = run("predict " + common + " --step-ms 2 --out " + out.string() + " --checkpoints " + folder +
                             " --window 65:66");
    REQUIRE(other.exit_code == 0);
    CHECK(other.output.find("window walked from 0.0") != std::string::npos);
    CHECK(other.output.find("(the log's start)") != std::string::npos);
}
