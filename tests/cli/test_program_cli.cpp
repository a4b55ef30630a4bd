// `cutload predict --program` and `cutload optimize` as a user runs them: output files with
// the comparison columns, consistent with each other, and one-line errors for bad programs.
#include "cli/run_cli.hpp"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace fs = std::filesystem;
using namespace cutload::clitest;

namespace {

void write(const fs::path& p, const std::string& text) {
    std::ofstream out(p, std::ios::binary);
    out << text;
    REQUIRE(out);
}

std::string read(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    REQUIRE(in);
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

// A CSV file as rows of named fields (no quoted commas in what these tests read).
std::vector<std::map<std::string, std::string>> read_csv(const fs::path& p) {
    std::istringstream in(read(p));
    std::string line;
    std::getline(in, line);
    std::vector<std::string> names;
    for (std::stringstream hs(line); std::getline(hs, line, ',');) names.push_back(line);
    std::vector<std::map<std::string, std::string>> rows;
    while (std::getline(in, line)) {
        std::map<std::string, std::string> row;
        std::stringstream ls(line);
        std::string field;
        for (std::size_t i = 0; i < names.size(); ++i) {
            field.clear();
            std::getline(ls, field, ',');
            row[names[i]] = field;
        }
        rows.push_back(row);
    }
    return rows;
}

// A straight slot along +X at 1200 mm/min, 10000 rpm, logged every 2 ms, with its program.
void write_slot(const fs::path& dir) {
    std::ostringstream log;
    log << "t,x,y,z,feed,spindle\n";
    for (int i = 0; i < 500; ++i) {
        const double t = i * 0.002;
        log << t << ',' << -6.0 + 20.0 * t << ",5,-2,1200,10000\n";
    }
    write(dir / "slot.csv", log.str());
    write(dir / "slot.nc", "%\nO0007 (SLOT)\nN10 G90 G21 G17 G01 X4. Y5. Z-2. F1200 S10000 M03\nN20 X14.\nM30\n%\n");
    write(dir / "slot.json", R"({"tool": {"shape": "flat", "diameter_mm": 8, "flutes": 2, "helix_deg": 30,
        "flute_length_mm": 20, "stickout_mm": 30},
      "material": {"name": "A7050", "Ktc_N_mm2": 800, "Krc_N_mm2": 300, "Kac_N_mm2": 100, "Kte_N_mm": 20,
        "Kre_N_mm": 20, "Kae_N_mm": 5},
      "stock": {"box_mm": {"min": [0, 0, -10], "max": [100, 10, 0]}},
      "limits": {"force_N": 400}})");
}

}  // namespace

TEST_CASE("predict --program adds the comparison columns to BLOCKS.csv, consistent with --compare", "[cli][program]") {
    const fs::path dir = scratch("program_predict");
    const Result r = run("predict " + source("data/demo_dryrun.csv") + " --spec " + source("data/demo_run.json") +
                         " --device cpu -q --out " + (dir / "forces.csv").string() + " --blocks " +
                         (dir / "blocks.csv").string() + " --program " + source("data/demo_program.nc") + " --compare " +
                         (dir / "compare.csv").string() + " --commanded-out " + (dir / "commanded.csv").string());
    INFO(r.output);
    REQUIRE(r.exit_code == 0);
    REQUIRE(r.output.find("mapping agrees with the log's blocks") != std::string::npos);

    const auto blocks = read_csv(dir / "blocks.csv");
    const auto compare = read_csv(dir / "compare.csv");
    std::map<std::string, std::map<std::string, std::string>> by_name;
    for (const auto& c : compare) by_name[c.at("block")] = c;
    std::size_t checked = 0;
    for (const auto& b : blocks) {
        INFO(b.at("block"));
        const auto it = by_name.find(b.at("block"));
        REQUIRE(it != by_name.end());
        const double actual_N = std::stod(b.at("peak_force_N")), commanded_N = std::stod(b.at("commanded_peak_force_N"));
        CHECK(commanded_N == Approx(std::stod(it->second.at("commanded_peak_force_N"))).margin(0.002));
        CHECK(actual_N == Approx(std::stod(it->second.at("actual_peak_force_N"))).margin(0.002));
        CHECK(std::stod(b.at("force_difference_N")) == Approx(actual_N - commanded_N).margin(0.003));
        CHECK(std::stod(b.at("max_deviation_mm")) == Approx(std::stod(it->second.at("max_deviation_mm"))).margin(1e-4));
        if (actual_N > 100) ++checked;
    }
    CHECK(checked > 30);
    // The commanded forces: their own FORCES.csv, shorter in time (no acceleration).
    const auto forces = read_csv(dir / "forces.csv"), commanded = read_csv(dir / "commanded.csv");
    REQUIRE(commanded.size() > 1000);
    CHECK(std::stod(commanded.back().at("t_s")) < std::stod(forces.back().at("t_s")));
}

TEST_CASE("optimize writes a program that differs only in F words and meets the target", "[cli][program]") {
    const fs::path dir = scratch("program_optimize");
    write_slot(dir);
    const Result r = run("optimize " + (dir / "slot.csv").string() + " --spec " + (dir / "slot.json").string() +
                         " --program " + (dir / "slot.nc").string() + " --target 0.8 --max-feed 20000 --device cpu -q" +
                         " --out " + (dir / "opt.nc").string() + " --report " + (dir / "feeds.csv").string());
    INFO(r.output);
    REQUIRE(r.exit_code == 0);
    const auto feeds = read_csv(dir / "feeds.csv");
    REQUIRE(feeds.size() == 2);
    for (const auto& f : feeds) {
        CHECK(f.at("binding") == "force");
        CHECK(std::stod(f.at("recommended_feed_mm_min")) > 1200);
        CHECK(std::stod(f.at("ratio_after")) <= 0.8 + 1e-9);
        CHECK(std::stod(f.at("ratio_after")) >= 0.8 * 0.95);
    }
    const std::string before = read(dir / "slot.nc"), after = read(dir / "opt.nc");
    CHECK(after != before);
    // Remove every F word: the rest is byte-identical.
    auto without_f = [](const std::string& s) {
        std::string out;
        for (std::size_t i = 0; i < s.size(); ++i) {
            if (s[i] == 'F') {
                for (++i; i < s.size() && (std::isdigit(static_cast<unsigned char>(s[i])) || s[i] == '.'); ++i) {}
                if (i < s.size() && s[i] == ' ' && !out.empty() && out.back() == ' ') continue;
                --i;
                continue;
            }
            out += s[i];
        }
        return out;
    };
    CHECK(without_f(after) == without_f(before));
}

TEST_CASE("a bad program is a one-line error naming file, line and word", "[cli][program]") {
    const fs::path dir = scratch("program_bad");
    write_slot(dir);
    write(dir / "g41.nc", "%\nN10 G01 X1. F100\nN20 G41 X2.\n%\n");
    Result r = run("predict " + (dir / "slot.csv").string() + " --spec " + (dir / "slot.json").string() + " --out " +
                   (dir / "f.csv").string() + " --program " + (dir / "g41.nc").string());
    INFO(r.output);
    CHECK(r.exit_code != 0);
    CHECK(r.output.rfind("cutload: error: ", 0) == 0);
    CHECK(r.output.find("g41.nc:3") != std::string::npos);
    CHECK(r.output.find("G41") != std::string::npos);
    CHECK_FALSE(fs::exists(dir / "f.csv"));

    // A program the log does not run: refused, naming how little of the log lies on it.
    write(dir / "far.nc", "%\nN10 G90 G00 Y300.\nN20 G01 X504. F1200 S10000 M03\n%\n");
    r = run("predict " + (dir / "slot.csv").string() + " --spec " + (dir / "slot.json").string() + " --out " +
            (dir / "f.csv").string() + " --program " + (dir / "far.nc").string());
    INFO(r.output);
    CHECK(r.exit_code == 2);
    CHECK(r.output.find("far.nc: only") != std::string::npos);
    CHECK(r.output.find("not this log's program") != std::string::npos);
    CHECK_FALSE(fs::exists(dir / "f.csv"));

    // The comparison outputs need a program.
    r = run("predict " + (dir / "slot.csv").string() + " --spec " + (dir / "slot.json").string() + " --out " +
            (dir / "f.csv").string() + " --compare " + (dir / "c.csv").string());
    INFO(r.output);
    CHECK(r.exit_code == 2);
    CHECK(r.output.find("--compare and --commanded-out need --program") != std::string::npos);
    CHECK_FALSE(fs::exists(dir / "c.csv"));
}

TEST_CASE("issue 19: a typo in a program is one line naming file, line and word, at once", "[cli][program][bounds]") {
    // The demo program with N40 moving Y to 1000000 mm. On main before this change this ran for
    // 15.5 s, took 2.1 GB and exited 0; now it is refused while the program is read.
    const fs::path dir = scratch("program_typo");
    std::string text = read(source("data/demo_program.nc"));
    const auto at = text.find("N40 X64.5 F6000");
    REQUIRE(at != std::string::npos);
    text.replace(at, std::string("N40 X64.5 F6000").size(), "N40 X64.5 Y1000000. F6000");
    write(dir / "typo.nc", text);
    const auto t0 = std::chrono::steady_clock::now();
    const Result r = run("predict " + source("data/demo_dryrun.csv") + " --spec " + source("data/demo_run.json") + " --device cpu -q --out " +
                         (dir / "f.csv").string() + " --program " + (dir / "typo.nc").string());
    const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    INFO(r.output);
    CHECK(r.exit_code == 2);
    CHECK(r.output == "cutload: error: " + (dir / "typo.nc").string() +
                          ":7: word 'Y1000000.': 1e+06 mm is outside the physical range +-100000 mm\n");
    CHECK(wall_s < 10);   // reading stops at the typo (generous: a shared 2-core machine)
    CHECK_FALSE(fs::exists(dir / "f.csv"));
}

TEST_CASE("program options: units, arc centres, tolerance, block skip and the match reach the reader", "[cli][program]") {
    const fs::path dir = scratch("program_units");
    write_slot(dir);
    // The slot as a 3-decimal inch post writes it, with no G20.
    write(dir / "inch.nc", "%\nO0008 (SLOT, INCH)\nN10 G90 G17 G01 X0.157 Y0.197 Z-0.079 F47.2 S10000 M03\nN20 X0.551\nM30\n%\n");
    const std::string base = "predict " + (dir / "slot.csv").string() + " --spec " + (dir / "slot.json").string() + " --device cpu -q --out " +
                             (dir / "f.csv").string() + " --program " + (dir / "inch.nc").string();
    Result r = run(base + " --program-units in --arc-centers absolute --arc-tolerance-mm 0.05 --min-match 0.9 --block-skip");
    INFO(r.output);
    CHECK(r.exit_code == 0);
    CHECK(r.output.find("matched 100.0% of samples") != std::string::npos);
    // Read as mm, the program lies off the log: refused, naming the fractions.
    r = run(base);
    INFO(r.output);
    CHECK(r.exit_code == 2);
    CHECK(r.output.find("inch.nc: only") != std::string::npos);
    CHECK(r.output.find("% not counted") != std::string::npos);
    // Option values are checked by the option parser.
    for (const std::string bad : {" --program-units cm", " --arc-centers relative", " --min-match 2", " --rapid-feed 1e-9"}) {
        r = run(base + bad);
        INFO(bad << ": " << r.output);
        CHECK(r.exit_code != 0);
        CHECK(r.output.rfind("cutload: error: ", 0) == 0);
    }
}

TEST_CASE("demo2 with its tool table: every block predicted with its tool, none unknown", "[cli][program][tools]") {
    const fs::path dir = scratch("demo2_tools");
    // The bundled spec at a coarser resolution (the tools' assignment does not depend on it; the
    // suite stays fast): 4 degree steps, 0.2 mm grid and elements.
    nlohmann::json spec = nlohmann::json::parse(read(source("data/demo2_run.json")));
    REQUIRE(spec.contains("tools"));
    REQUIRE_FALSE(spec.contains("tool"));
    spec["resolution"] = {{"angle_step_deg", 4}, {"axial_step_mm", 0.2}, {"grid_mm", 0.2}};
    write(dir / "demo2_run.json", spec.dump());
    const Result r = run("predict " + source("data/demo2_dryrun.csv") + " --spec " + (dir / "demo2_run.json").string() +
                         " --device cpu -q --out " + (dir / "forces.csv").string() + " --blocks " + (dir / "blocks.csv").string());
    INFO(r.output);
    REQUIRE(r.exit_code == 0);
    CHECK(r.output.find("unknown_tool") == std::string::npos);
    CHECK(r.output.find("one tool for every block") == std::string::npos);

    // Every block names its tool; each tool cuts in the blocks the program runs it in (the log's
    // block column), and every tool cuts somewhere.
    const auto blocks = read_csv(dir / "blocks.csv");
    REQUIRE(blocks.size() > 70);
    std::map<std::string, double> peak_by_tool;
    for (const auto& b : blocks) {
        INFO(b.at("block"));
        REQUIRE_FALSE(b.at("tool").empty());
        CHECK(b.at("flags").find("unknown_tool") == std::string::npos);
        peak_by_tool[b.at("tool")] = std::max(peak_by_tool[b.at("tool")], std::stod(b.at("peak_force_N")));
    }
    REQUIRE(peak_by_tool.size() == 3);
    for (const auto& [tool, peak] : peak_by_tool) {
        INFO("T" << tool);
        CHECK(peak > 20);
    }
    // demo2_program.nc: the face mill T1 through N140, the end mill T2 from N150 to N720, the drill T3 after.
    auto tool_of = [&](const std::string& name) {
        for (const auto& b : blocks)
            if (b.at("block") == name) return b.at("tool");
        return std::string("(missing)");
    };
    CHECK(tool_of("N60") == "1");
    CHECK(tool_of("N450") == "2");
    CHECK(tool_of("N770") == "3");

    // FORCES.csv's rows carry the tool too.
    const auto forces = read_csv(dir / "forces.csv");
    std::map<std::string, std::size_t> rows_by_tool;
    for (const auto& f : forces) ++rows_by_tool[f.at("tool")];
    CHECK(rows_by_tool.size() == 3);
    CHECK(rows_by_tool.count("") == 0);
}
