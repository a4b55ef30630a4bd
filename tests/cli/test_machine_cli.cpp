// `cutload predict --machine`: a log with rotary axes through a machine definition, as a user runs
// it; without one the rotary axes are said to be ignored, and a pose the engine cannot take is one
// line and a non-zero exit.
#include "cli/run_cli.hpp"
#include "kernels/opencl_runtime.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <regex>
#include <sstream>

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

// A side cut along the part's +X at 20 mm/s (ae 1 mm on the demo stock's y = 0 wall, 3 mm deep),
// commanded through the AC machine with the C table at c_deg (0 or 90): the machine axes are
// p_M = p_C + R_z(-c) (p_W - p_C) about the C line at (-350, -275), readings every 4 ms.
std::string side_cut_log(double c_deg) {
    const double c = c_deg * 3.14159265358979323846 / 180;
    std::string csv = "t,x,y,z,a,c,spindle,block\n";
    for (int k = 0; k <= 300; ++k) {
        const double t = 0.004 * k;
        const double xw = 195 + 20 * t, yw = -303, zw = -323;   // the demo stock is x 200..305, y -300..-210
        const double dx = xw + 350, dy = yw + 275;
        csv += fmt::format("{:.4f},{:.4f},{:.4f},{:.4f},0,{:.3f},10000,N10\n", t, -350 + std::cos(c) * dx + std::sin(c) * dy,
                           -275 - std::sin(c) * dx + std::cos(c) * dy, zw, c_deg);
    }
    return csv;
}

struct ForcesCsv {
    std::vector<std::string> header;
    std::vector<std::vector<std::string>> rows;
    std::size_t col(const std::string& name) const {
        const auto it = std::find(header.begin(), header.end(), name);
        REQUIRE(it != header.end());
        return std::size_t(it - header.begin());
    }
};

std::vector<std::string> split(const std::string& line) {
    std::vector<std::string> out;
    std::size_t start = 0;
    for (std::size_t comma; (comma = line.find(',', start)) != std::string::npos; start = comma + 1)
        out.push_back(line.substr(start, comma - start));
    out.push_back(line.substr(start));
    return out;
}

ForcesCsv read_forces(const fs::path& path) {
    std::ifstream in(path);
    ForcesCsv f;
    std::string line;
    REQUIRE(std::getline(in, line));
    f.header = split(line);
    while (std::getline(in, line)) f.rows.push_back(split(line));
    return f;
}

}  // namespace

TEST_CASE("predict --machine: FORCES.csv carries the forces in machine axes too, turned with the table (T3)",
          "[cli][five_axis]") {
    const fs::path dir = clitest::scratch("machine_axes_cli");
    const std::string spec = clitest::source("data/demo_run.json");
    const std::string machine = clitest::source("data/machines/ac_table_table.json");
    std::ofstream(dir / "c0.csv") << side_cut_log(0);
    std::ofstream(dir / "c90.csv") << side_cut_log(90);
    auto predict = [&](const std::string& log, const std::string& out, const std::string& extra) {
        const clitest::Result r = clitest::run("predict " + (dir / log).string() + " --spec " + spec +
                                               " --device cpu -q --out " + (dir / out).string() + extra);
        INFO(r.output);
        REQUIRE(r.exit_code == 0);
    };
    predict("c0.csv", "plain.csv", "");
    predict("c0.csv", "rest.csv", " --machine " + machine);
    predict("c90.csv", "turned.csv", " --machine " + machine);
    predict("c90.csv", "turned.bin", " --machine " + machine);

    const std::string base = "t_s,spindle_angle_deg,block,tool,fx_N,fy_N,fz_N,torque_Nm,power_kW,chip_mm,bending_MPa,"
                             "radial_engagement_mm,axial_engagement_mm,removed_mm3,holder_contact";
    const ForcesCsv plain = read_forces(dir / "plain.csv"), rest = read_forces(dir / "rest.csv"),
                    turned = read_forces(dir / "turned.csv");
    // Without --machine the columns are as they always were.
    CHECK(fmt::format("{}", fmt::join(plain.header, ",")) == base);
    CHECK(fmt::format("{}", fmt::join(turned.header, ",")) ==
          base + ",fx_machine_N,fy_machine_N,fz_machine_N,tool_axis_x,tool_axis_y,tool_axis_z");

    // At rest (C = 0) machine axes are workpiece axes: the same digits.
    REQUIRE(rest.rows.size() > 1000);
    for (const auto& r : rest.rows) {
        REQUIRE(r.size() == 21);
        REQUIRE(r[15] == r[4]);
        REQUIRE(r[16] == r[5]);
        REQUIRE(r[17] == r[6]);
    }
    // A C table turns about the tool's own axis: it stands on the part's +Z in every row.
    for (const ForcesCsv* f : {&rest, &turned})
        for (const auto& r : f->rows) {
            REQUIRE(std::stod(r[f->col("tool_axis_x")]) == Approx(0).margin(1e-6));
            REQUIRE(std::stod(r[f->col("tool_axis_y")]) == Approx(0).margin(1e-6));
            REQUIRE(std::stod(r[f->col("tool_axis_z")]) == 1);
        }
    // Turned 90 deg: (Fx, Fy, Fz) in workpiece axes are (Fy, -Fx, Fz) in machine axes
    // (tests/app/test_workpiece_motion.cpp derives the sense).
    const std::size_t fx = turned.col("fx_N"), fy = turned.col("fy_N"), fz = turned.col("fz_N"),
                      mx = turned.col("fx_machine_N"), my = turned.col("fy_machine_N"), mz = turned.col("fz_machine_N");
    double largest_N = 0;
    for (const auto& r : turned.rows) {
        INFO("t = " << r[0]);
        REQUIRE(std::stod(r[mx]) == Approx(std::stod(r[fy])).margin(1e-9));
        REQUIRE(std::stod(r[my]) == Approx(-std::stod(r[fx])).margin(1e-9));
        REQUIRE(std::stod(r[mz]) == Approx(std::stod(r[fz])).margin(1e-9));
        largest_N = std::max(largest_N, std::abs(std::stod(r[fx])));
    }
    CHECK(largest_N > 50);   // it cuts
    // FORCES.bin carries the same columns (cutload compare reads it; its size says they are there).
    CHECK(fs::file_size(dir / "turned.bin") > 0);
    std::ifstream bin(dir / "turned.bin", std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(bin)), {});
    CHECK(bytes.find("\"fz_machine_N\"") != std::string::npos);
}

TEST_CASE("predict --machine: rotary axes become the tool's motion, a tool turning while tilted near the stock is "
          "refused in one line",
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

    // Tilted 15 deg with the C table turning, far from the demo stock: the tool never reaches it,
    // so the turn does not matter and nothing is cut.
    const clitest::Result far = predict("tilted.csv", " --machine " + machine);
    INFO(far.output);
    CHECK(far.exit_code == 0);
    CHECK_THAT(far.output, Catch::Contains(" 0 cutting"));
    const std::string forces_before = [&] {
        std::ifstream in(dir / "forces.csv", std::ios::binary);
        return std::string(std::istreambuf_iterator<char>(in), {});
    }();
    // The same log on a stock around the tool: a tilted tool turning where it can cut.
    std::string near_spec = [&] {
        std::ifstream in(spec, std::ios::binary);
        return std::string(std::istreambuf_iterator<char>(in), {});
    }();
    const auto replace = [&](const std::string& from, const std::string& to) {
        const std::size_t at = near_spec.find(from);
        REQUIRE(at != std::string::npos);
        near_spec.replace(at, from.size(), to);
    };
    replace(R"("min": [0, 0, 0], "max": [105, 90, 30])", R"("min": [-400, -400, -600], "max": [0, 0, -200])");
    replace(R"("offset_mm": [-200, 300, 350])", R"("offset_mm": [0, 0, 0])");
    replace(R"("grid_mm": 0.1)", R"("grid_mm": 2)");
    std::ofstream(dir / "near.json") << near_spec;
    // With a program it does not run (demo3's ring groove) the turning tool's log is refused by the
    // mapping, in one line, before any row: the earlier FORCES.csv is untouched and no temporary
    // file is left. (Its own program is compared: tests/app/test_turning_tool.cpp.)
    const clitest::Result with_program = clitest::run(
        "predict " + (dir / "tilted.csv").string() + " --spec " + (dir / "near.json").string() + " --device cpu -q --out " +
        (dir / "forces.csv").string() + " --machine " + machine + " --program " + clitest::source("data/demo3_program.nc"));
    INFO(with_program.output);
    CHECK(with_program.exit_code != 0);
    CHECK_THAT(with_program.output, Catch::Contains("demo3_program.nc: only") &&
                                        Catch::Contains("not this log's program, or the wrong work offset"));
    CHECK(std::count(with_program.output.begin(), with_program.output.end(), '\n') == 1);
    {
        std::ifstream in(dir / "forces.csv", std::ios::binary);
        CHECK(std::string(std::istreambuf_iterator<char>(in), {}) == forces_before);
    }
    std::size_t files = 0;
    for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++files;
    CHECK(files == 4);   // level.csv, tilted.csv, near.json, forces.csv
    // Alone, the tilted tool turning inside the stock is predicted on the multi-direction stock.
    const clitest::Result tilted = clitest::run("predict " + (dir / "tilted.csv").string() + " --spec " +
                                                (dir / "near.json").string() + " --device cpu --out " +
                                                (dir / "forces.csv").string() + " --machine " + machine);
    INFO(tilted.output);
    CHECK(tilted.exit_code == 0);
    CHECK_THAT(tilted.output, Catch::Contains("multi-direction stock"));
    // Again from the stock that run leaves: the same path finds its material gone and cuts less.
    {
        const auto run_saving = [&](const std::string& extra) {
            return clitest::run("predict " + (dir / "tilted.csv").string() + " --spec " + (dir / "near.json").string() +
                                " --device cpu --out " + (dir / "again.csv").string() + " --machine " + machine + extra);
        };
        const clitest::Result first = run_saving(" --save-stock " + (dir / "after.stock").string());
        const clitest::Result again = run_saving(" --start-stock " + (dir / "after.stock").string());
        INFO(first.output << again.output);
        CHECK(first.exit_code == 0);
        CHECK(again.exit_code == 0);
        CHECK_THAT(again.output, Catch::Contains("multi-direction stock"));
        const auto cutting = [](const std::string& out) {
            std::smatch m;
            return std::regex_search(out, m, std::regex(R"((\d+) cutting)")) ? std::stol(m[1]) : -1L;
        };
        CHECK(cutting(first.output) > 0);
        CHECK(cutting(again.output) < cutting(first.output));
        fs::remove(dir / "after.stock");
        fs::remove(dir / "again.csv");
    }
    // On the OpenCL kernels, with the stock in host memory (PoCL) and on a GPU's path (the stock
    // written to the device once, read back at the end: CUTLOAD_OPENCL_DISCRETE=1), the same bytes.
    try {
        kernels::OpenClRuntime::instance();
        auto on_opencl = [&](const std::string& name) {
            const clitest::Result r = clitest::run("predict " + (dir / "tilted.csv").string() + " --spec " +
                                                   (dir / "near.json").string() + " --device opencl --out " +
                                                   (dir / (name + ".csv")).string() + " --save-stock " +
                                                   (dir / (name + ".stock")).string() + " --machine " + machine);
            INFO(r.output);
            CHECK(r.exit_code == 0);
            CHECK_THAT(r.output, Catch::Contains("opencl: ") && Catch::Contains("multi-direction stock"));
        };
        on_opencl("host");
        {
            const clitest::Env discrete("CUTLOAD_OPENCL_DISCRETE", "1");
            on_opencl("discrete");
        }
        const auto slurp = [](const fs::path& p) {
            std::ifstream in(p, std::ios::binary);
            return std::string(std::istreambuf_iterator<char>(in), {});
        };
        CHECK(slurp(dir / "host.csv").size() > 10000);
        CHECK(slurp(dir / "discrete.csv") == slurp(dir / "host.csv"));
        CHECK(slurp(dir / "discrete.stock") == slurp(dir / "host.stock"));
    } catch (const kernels::OpenClError& e) {
        WARN("no OpenCL device: " << e.what());
    }

    const clitest::Result bad = predict("level.csv", " --machine " + spec);
    INFO(bad.output);
    CHECK(bad.exit_code != 0);
    CHECK_THAT(bad.output, Catch::Contains("demo_run.json"));

    // A log without the c column the AC machine's C axis reads: one line naming the axis and the
    // column, as the service's upload says it (docs/api.md, "Five-axis machines").
    {
        std::string no_c;
        std::istringstream in(turning_table_log(0));
        for (std::string line; std::getline(in, line);) no_c += line.substr(0, line.rfind(',', line.rfind(',') - 1)) + line.substr(line.rfind(',')) + "\n";
        REQUIRE(no_c.substr(0, no_c.find('\n')) == "t,x,y,z,a,spindle");
        std::ofstream(dir / "no_c.csv") << no_c;
    }
    const clitest::Result no_c = predict("no_c.csv", " --machine " + machine);
    INFO(no_c.output);
    CHECK(no_c.exit_code != 0);
    CHECK_THAT(no_c.output, Catch::Contains("machine: machine ") &&
                                Catch::Contains("rotary axis C needs column 'c' in the log, which has none"));
    CHECK(std::count(no_c.output.begin(), no_c.output.end(), '\n') == 1);
}
