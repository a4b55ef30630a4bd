// Issue 19, reproducer class 2, as a user meets it: `cutload predict` on a log with glitched rows
// (spindle 1e10 or 5e6 rpm in 3 rows, positions of 1e308 in 6 rows or one) gives the clean log's
// forces and flags, says how many readings it dropped, and never writes NaN or infinity; NaN in a
// field is one error line naming line and column. The log is synthesized (seeded generator, the
// seed's sampling pattern): a slot cut through a 10 mm wide stock.
#include "cli/run_cli.hpp"

#include "motion_io/synth.hpp"
#include "textio/csv.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using namespace cutload::clitest;

namespace {

void write(const fs::path& p, const std::string& text) {
    std::ofstream out(p, std::ios::binary);
    out << text;
    REQUIRE(out);
}

std::string read_all(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

// Rows of a CSV file, as text fields by column name.
std::vector<std::map<std::string, std::string>> read_csv(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    REQUIRE(in);
    cutload::textio::CsvReader csv(in, p.string());
    REQUIRE(csv.next());
    std::vector<std::string> names;
    for (std::size_t i = 0; i < csv.size(); ++i) names.emplace_back(csv[i]);
    std::vector<std::map<std::string, std::string>> rows;
    while (csv.next()) {
        auto& row = rows.emplace_back();
        for (std::size_t i = 0; i < names.size(); ++i) row[names[i]] = std::string(csv[i]);
    }
    return rows;
}

// A slot along +X at 1200 mm/min, 2 mm deep, full width of an 8 mm tool; machine = stock coordinates.
std::vector<std::string> slot_rows(std::string& header) {
    cutload::motion_io::DryRunSpec spec;
    spec.start_mm[0] = -6, spec.start_mm[1] = 5, spec.start_mm[2] = -2;
    spec.program.push_back({"N10", false, {54, 5, -2}, 1200});
    spec.program.push_back({"N20", true, {54, 5, 10}, 0});
    spec.machine.spindle_ramp_s = 0.1;
    spec.seed = 1919;
    std::ostringstream out;
    cutload::motion_io::synthesize_dry_run(spec, out);
    std::istringstream in(out.str());
    std::getline(in, header);
    std::vector<std::string> rows;
    for (std::string line; std::getline(in, line);) rows.push_back(line);
    return rows;
}

const char* kSpec = R"({"tool": {"shape": "flat", "diameter_mm": 8, "flutes": 2, "helix_deg": 30,
    "flute_length_mm": 20, "stickout_mm": 30},
  "material": {"name": "A7075", "Ktc_N_mm2": 767, "Krc_N_mm2": 169, "Kac_N_mm2": 222, "Kte_N_mm": 27.7,
    "Kre_N_mm": 26.6, "Kae_N_mm": 0.7},
  "stock": {"box_mm": {"min": [0, 0, -10], "max": [100, 10, 0]}},
  "limits": {"force_N": 2000}})";

// Column k of a row replaced.
std::string with_field(const std::string& row, std::size_t k, const std::string& value) {
    std::vector<std::string> f;
    std::size_t start = 0;
    for (std::size_t comma; (comma = row.find(',', start)) != std::string::npos; start = comma + 1)
        f.push_back(row.substr(start, comma - start));
    f.push_back(row.substr(start));
    REQUIRE(k < f.size());
    f[k] = value;
    std::string s;
    for (std::size_t i = 0; i < f.size(); ++i) s += (i ? "," : "") + f[i];
    return s;
}

struct Run {
    Result result;
    std::vector<std::map<std::string, std::string>> forces, blocks;
    std::string forces_text, blocks_text;
};

// Writes the slot log with `value` in column `col` of the given rows and predicts it.
Run predict_slot(const std::string& name, std::size_t col, const std::vector<std::size_t>& rows, const std::string& value) {
    const fs::path dir = scratch("glitch_" + name);
    std::string header;
    std::vector<std::string> lines = slot_rows(header);
    for (const std::size_t r : rows) lines.at(r) = with_field(lines.at(r), col, value);
    std::string log = header + "\n";
    for (const auto& l : lines) log += l + "\n";
    write(dir / "log.csv", log);
    write(dir / "spec.json", kSpec);
    Run run;
    run.result = cutload::clitest::run("predict " + (dir / "log.csv").string() + " --spec " + (dir / "spec.json").string() +
                                       " --device cpu --out " + (dir / "forces.csv").string() + " --blocks " +
                                       (dir / "blocks.csv").string());
    if (run.result.exit_code == 0) {
        run.forces = read_csv(dir / "forces.csv");
        run.blocks = read_csv(dir / "blocks.csv");
        run.forces_text = read_all(dir / "forces.csv");
        run.blocks_text = read_all(dir / "blocks.csv");
    } else {
        CHECK_FALSE(fs::exists(dir / "forces.csv"));   // nothing half-written
    }
    return run;
}

bool has_non_finite(std::string text) {
    std::transform(text.begin(), text.end(), text.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return text.find("nan") != std::string::npos || text.find("inf") != std::string::npos;
}

const std::map<std::string, std::string>& block(const Run& r, const std::string& name) {
    for (const auto& b : r.blocks)
        if (b.at("block") == name) return b;
    FAIL("no block " << name);
    throw std::logic_error("unreachable");
}

// The glitched run against the clean one: the same forces, flags and row count, and said out loud.
void check_like_clean(const Run& clean, const Run& g, std::size_t dropped) {
    INFO(g.result.output);
    REQUIRE(g.result.exit_code == 0);
    CHECK(g.result.output.find("cutload: warning: glitch_dropped: ") != std::string::npos);
    CHECK(g.result.output.find("(" + std::to_string(dropped) + " time") != std::string::npos);
    CHECK_FALSE(has_non_finite(g.forces_text));
    CHECK_FALSE(has_non_finite(g.blocks_text));
    const double rows = double(g.forces.size()), clean_rows = double(clean.forces.size());
    CHECK(std::fabs(rows - clean_rows) <= 0.01 * clean_rows);
    const auto &b = block(g, "N10"), &c = block(clean, "N10");
    const double peak = std::stod(b.at("peak_force_N")), clean_peak = std::stod(c.at("peak_force_N"));
    CHECK(peak == Approx(clean_peak).epsilon(0.01));
    CHECK(std::stod(b.at("mean_force_N")) == Approx(std::stod(c.at("mean_force_N"))).epsilon(0.01));
    CHECK(b.at("flags") == c.at("flags"));
}

std::string lines_with(const std::string& text, const std::string& what) {
    std::istringstream in(text);
    std::string out;
    for (std::string line; std::getline(in, line);)
        if (line.find(what) != std::string::npos) out += line + "\n";
    return out;
}

constexpr std::size_t kSpindleCol = 1, kXCol = 5;

const Run& clean_run() {
    static const Run run = predict_slot("clean", 0, {}, "");
    return run;
}

}  // namespace

TEST_CASE("issue 19: predict on a log with spindle 1e10 or 5e6 rpm in 3 rows gives the clean forces", "[cli][glitch]") {
    const Run& clean = clean_run();
    INFO(clean.result.output);
    REQUIRE(clean.result.exit_code == 0);
    REQUIRE(std::stod(block(clean, "N10").at("peak_force_N")) > 100);   // the slot cuts
    CHECK(clean.result.output.find("glitch_dropped") == std::string::npos);
    for (const std::string value : {"1e10", "1e9", "5e6"}) {
        const Run g = predict_slot("spindle", kSpindleCol, {120, 127, 134}, value);
        check_like_clean(clean, g, 3);
        // The sampling check judges by the kept readings, never by the glitch's speed.
        CHECK(lines_with(g.result.output, "sampling_coarse") == lines_with(clean.result.output, "sampling_coarse"));
    }
}

TEST_CASE("issue 19: predict on a log with positions of 1e308 in 6 rows or in one gives the clean forces", "[cli][glitch]") {
    const Run& clean = clean_run();
    REQUIRE(clean.result.exit_code == 0);
    check_like_clean(clean, predict_slot("pos6", kXCol, {100, 111, 122, 133, 144, 155}, "1e308"), 6);
    check_like_clean(clean, predict_slot("pos1", kXCol, {120}, "1e308"), 1);
}

TEST_CASE("issue 19: NaN or infinity in a log field is one error line naming line and column", "[cli][glitch]") {
    for (const std::string value : {"nan", "-inf"}) {
        const Run r = predict_slot("nan", kXCol, {120}, value);
        INFO(r.result.output);
        CHECK(r.result.exit_code == 2);
        CHECK(r.result.output.rfind("cutload: error: ", 0) == 0);
        CHECK(r.result.output.find('\n') == r.result.output.size() - 1);
        CHECK(r.result.output.find("log.csv:122:") != std::string::npos);
        CHECK(r.result.output.find("'" + value + "' is not a finite number") != std::string::npos);
    }
}
