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

TEST_CASE("issue 19: 1e400 in a run spec, tool or map file is one line naming file, place and key", "[cli]") {
    const fs::path dir = scratch("json_overflow");
    auto write = [&](const std::string& name, const std::string& text) {
        const fs::path p = dir / name;
        FILE* f = std::fopen(p.c_str(), "w");
        REQUIRE(f != nullptr);
        std::fputs(text.c_str(), f);
        std::fclose(f);
        return p.string();
    };
    // The demo spec with one coefficient beyond a double (line 6 of the file).
    std::string spec;
    {
        FILE* f = std::fopen(source("data/demo_run.json").c_str(), "r");
        REQUIRE(f != nullptr);
        for (int c; (c = std::fgetc(f)) != EOF;) spec += static_cast<char>(c);
        std::fclose(f);
    }
    const auto at = spec.find("767.0");
    REQUIRE(at != std::string::npos);
    spec.replace(at, 5, "1e400");
    const std::string spec_path = write("run.json", spec);
    const fs::path forces = dir / "forces.csv";
    for (const std::string cmd : {"predict", "optimize"}) {
        const Result r = run(cmd + " " + source("data/demo_dryrun.csv") + " --spec " + spec_path + " --out " +
                             forces.string() + (cmd == "optimize" ? " --program " + source("data/demo_program.nc") : ""));
        require_one_error_line(r, spec_path + ":6:");
        CHECK(r.output.find("material.Ktc_N_mm2: the number 1e400 is out of range") != std::string::npos);
        CHECK(r.output.find("number overflow") == std::string::npos);
        CHECK_FALSE(fs::exists(forces));
    }
    const std::string tool = write("tool.json", R"({"shape": "flat", "diameter_mm": -1E+400, "flutes": 2})");
    const Result t = run("calibrate --tool " + tool + " --test " + source("data/demo_dryrun.csv") +
                         ":10000:1200:3:8:slot --out " + (dir / "material.json").string());
    require_one_error_line(t, tool + ":1:34: diameter_mm: the number -1E+400 is out of range");
    const std::string map = write("map.json", "{\"x\": \"x\",\n \"sample_period_ms\": 1e400}");
    require_one_error_line(run("inspect " + source("data/demo_dryrun.csv") + " --map " + map),
                           map + ":2:22: sample_period_ms: the number 1e400 is out of range");
}

TEST_CASE("predict refuses a run whose estimated work passes a limit, in one line and before computing", "[cli][bounds]") {
    // The demo: 14.9 s of motion at up to 10002 rpm, about 4.2e5 angle steps at 2 deg; its stock is
    // 105 x 90 mm at 0.1 mm, 9.45e5 cells.
    const fs::path dir = scratch("predict_bounds");
    const fs::path forces = dir / "forces.csv";
    const std::string predict = "predict " + source("data/demo_dryrun.csv") + " --spec " + source("data/demo_run.json") +
                                " --device cpu --out " + forces.string();
    const Result rows = run(predict + " --max-force-rows 100000");
    require_one_error_line(rows, "force_rows: the log's 14.87 s turn the spindle");
    CHECK(rows.output.find("force rows, above the limit of 1e+05 (--max-force-rows)") != std::string::npos);
    CHECK_FALSE(fs::exists(forces));
    const Result cells = run(predict + " --max-stock-cells 500000");
    require_one_error_line(cells, "stock_cells: resolution.grid_mm gives the stock box 9.45e+05 dexel cells");
    CHECK_FALSE(fs::exists(forces));
    const Result memory = run(predict + " --max-job-memory-mb 50");
    require_one_error_line(memory, "(--max-job-memory-mb)");
    CHECK_FALSE(fs::exists(forces));
}
