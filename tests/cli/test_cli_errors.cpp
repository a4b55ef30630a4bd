// The CLI's promise for bad input: a non-zero exit, one line "cutload: error: ..." naming the
// place and the reason, and no output file written.
#include "cli/run_cli.hpp"

#include <filesystem>
#include <string>

namespace fs = std::filesystem;
using namespace cutload::clitest;

namespace {

void require_one_error_line(const Result& r, const std::string& must_contain) {
    INFO(r.output);
    CHECK(r.exit_code == 2);
    CHECK(r.output.rfind("cutload: error: ", 0) == 0);
    CHECK(r.output.find('\n') == r.output.size() - 1);
    CHECK(r.output.find(must_contain) != std::string::npos);
}

}  // namespace

TEST_CASE("predict checks every output place before computing", "[cli]") {
    const fs::path dir = scratch("predict_out");
    const fs::path forces = dir / "forces.csv";
    const Result r = run("predict " + source("data/demo_dryrun.csv") + " --spec " + source("data/demo_run.json") +
                         " --out " + forces.string() + " --blocks " + (dir / "missing" / "blocks.csv").string());
    require_one_error_line(r, "--blocks");
    CHECK(r.output.find("does not exist") != std::string::npos);
    CHECK_FALSE(fs::exists(forces));   // nothing computed, nothing half-written
}

TEST_CASE("an output path that is a folder is refused", "[cli]") {
    const fs::path dir = scratch("resample_out");
    const Result r = run("resample " + source("data/demo_dryrun.csv") + " --step-ms 1 --out " + dir.string());
    require_one_error_line(r, "is a folder");
}

TEST_CASE("option parse errors use the one-line error format", "[cli]") {
    require_one_error_line(run("inspect " + source("data/demo_dryrun.csv") + " --units furlong"), "--units");
    require_one_error_line(run("no-such-command"), "no-such-command");
}

TEST_CASE("the resampling step is bounded", "[cli]") {
    const fs::path dir = scratch("step");
    const fs::path out = dir / "motion.csv";
    require_one_error_line(run("resample " + source("data/demo_dryrun.csv") + " --step-ms 0.000001 --out " + out.string()),
                           "0.01 to 1000 ms");
    CHECK_FALSE(fs::exists(out));
}

TEST_CASE("a map key the log's format cannot use is an error, not ignored", "[cli]") {
    // CSV logs take maps too (docs/formats.md), but an SHDR-only key must not be half-applied.
    const fs::path dir = scratch("map");
    const fs::path map = dir / "map.json";
    FILE* f = std::fopen(map.c_str(), "w");
    REQUIRE(f != nullptr);
    std::fputs("{\"position\": [\"pos\"]}", f);
    std::fclose(f);
    require_one_error_line(run("inspect " + source("data/demo_dryrun.csv") + " --map " + map.string()),
                           "key 'position' is an SHDR 3-D path position");
}

TEST_CASE("--help and --version exit 0", "[cli]") {
    CHECK(run("--help").exit_code == 0);
    const Result v = run("--version");
    CHECK(v.exit_code == 0);
    CHECK(v.output.find("cutload 0.1.0") != std::string::npos);
}
