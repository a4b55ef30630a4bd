// The text layer as a user meets it: block names holding quotes, commas and Latin-1 bytes
// round-trip through `cutload resample` and predict's FORCES.csv / BLOCKS.csv; a byte that is not
// text is one error line naming file, line and column; coarse data is said on every predict; the
// log's own commanded positions give the commanded prediction (--commanded-from-log).
#include "cli/run_cli.hpp"

#include "textio/csv.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
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

// A CSV file read by textio's reader: the header, then rows of named fields.
std::vector<std::map<std::string, std::string>> read_csv(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    REQUIRE(in);
    cutload::textio::CsvReader csv(in, p.string());
    REQUIRE(csv.next());
    std::vector<std::string> names;
    for (std::size_t i = 0; i < csv.size(); ++i) names.emplace_back(csv[i]);
    std::vector<std::map<std::string, std::string>> rows;
    while (csv.next()) {
        REQUIRE(csv.size() == names.size());
        auto& row = rows.emplace_back();
        for (std::size_t i = 0; i < names.size(); ++i) row[names[i]] = std::string(csv[i]);
    }
    return rows;
}

// Block names as a shop writes them: quotes, commas, and an ä as one Latin-1 byte (0xE4).
const std::string kRoughLatin1 = "Fr\xE4sen \"N10\", grob";
const std::string kRough = "Fräsen \"N10\", grob";
const std::string kFinish = "N20, fein";

// A straight slot along +X at 1200 mm/min (20 mm/s), 10000 rpm, logged every `period_s`; the
// commanded position leads the actual one by 10 ms (0.2 mm at 20 mm/s).
void write_slot(const fs::path& dir, double period_s = 0.002) {
    std::string log = "t,x,y,z,x_cmd,y_cmd,z_cmd,feed,spindle,block\n";
    const int rows = static_cast<int>(std::lround(1.0 / period_s));
    for (int i = 0; i < rows; ++i) {
        const double t = i * period_s;
        char buf[160];
        std::snprintf(buf, sizeof buf, "%.4f,%.4f,5.0000,-2.0000,%.4f,5.0000,-2.0000,1200,10000,", t, -6.0 + 20.0 * t,
                      -6.0 + 20.0 * (t + 0.010));
        log += buf;
        cutload::textio::append_field(log, i < rows / 2 ? kRoughLatin1 : kFinish);
        log += '\n';
    }
    write(dir / "slot.csv", log);
    write(dir / "slot.json", R"({"tool": {"shape": "flat", "diameter_mm": 8, "flutes": 2, "helix_deg": 30,
        "flute_length_mm": 20, "stickout_mm": 30},
      "material": {"name": "A7050", "Ktc_N_mm2": 800, "Krc_N_mm2": 300, "Kac_N_mm2": 100, "Kte_N_mm": 20,
        "Kre_N_mm": 20, "Kae_N_mm": 5},
      "stock": {"box_mm": {"min": [0, 0, -10], "max": [100, 10, 0]}},
      "limits": {"force_N": 400}})");
}

std::set<std::string> column_values(const std::vector<std::map<std::string, std::string>>& rows, const std::string& col) {
    std::set<std::string> s;
    for (const auto& r : rows)
        if (!r.at(col).empty()) s.insert(r.at(col));
    return s;
}

}  // namespace

TEST_CASE("block names with quotes, commas and Latin-1 round-trip through resample, FORCES.csv and BLOCKS.csv", "[cli][text]") {
    const fs::path dir = scratch("text_roundtrip");
    write_slot(dir);
    Result r = run("resample " + (dir / "slot.csv").string() + " --step-ms 1 --out " + (dir / "motion.csv").string());
    INFO(r.output);
    REQUIRE(r.exit_code == 0);
    CHECK(column_values(read_csv(dir / "motion.csv"), "block") == std::set<std::string>{kRough, kFinish});

    r = run("predict " + (dir / "slot.csv").string() + " --spec " + (dir / "slot.json").string() + " --device cpu --out " +
            (dir / "forces.csv").string() + " --blocks " + (dir / "blocks.csv").string());
    INFO(r.output);
    REQUIRE(r.exit_code == 0);
    CHECK(column_values(read_csv(dir / "forces.csv"), "block") == std::set<std::string>{kRough, kFinish});
    const auto blocks = read_csv(dir / "blocks.csv");
    CHECK(column_values(blocks, "block") == std::set<std::string>{kRough, kFinish});
    for (const auto& b : blocks) CHECK(std::stod(b.at("peak_force_N")) > 0);
    // Printed as UTF-8 too.
    CHECK(r.output.find("Fr\xE4sen") == std::string::npos);
}

TEST_CASE("a byte that is not text is one error line naming file, line and column", "[cli][text]") {
    const fs::path dir = scratch("text_bad_byte");
    write(dir / "bad.csv", "t,x,y,z,block\n0,1,2,3,N10\n0.01,1.1,2,3,N\x81" "20\n");
    const Result r = run("inspect " + (dir / "bad.csv").string());
    INFO(r.output);
    CHECK(r.exit_code != 0);
    CHECK(r.output == "cutload: error: " + (dir / "bad.csv").string() +
                          ":3:15: byte 0x81 is not a character (not UTF-8, and undefined in Windows-1252)\n");
    // A digit group inside a number, the same way.
    write(dir / "grouped.csv", "t,x,y,z\n0,1\xA0" "234.5,2,3\n");
    const Result g = run("inspect " + (dir / "grouped.csv").string());
    INFO(g.output);
    CHECK(g.exit_code != 0);
    CHECK(g.output.find("grouped.csv:2:3: column 'x': '1\xC2\xA0" "234.5' is not a number: a no-break space inside it") !=
          std::string::npos);
}

TEST_CASE("predict says coarse data out loud: sampling longer than a tooth period", "[cli][text]") {
    const fs::path dir = scratch("text_coarse");
    write_slot(dir, 0.010);   // 10 ms rows; 10000 rpm, 2 teeth: a tooth every 3 ms
    const Result r = run("predict " + (dir / "slot.csv").string() + " --spec " + (dir / "slot.json").string() +
                         " --device cpu --out " + (dir / "forces.csv").string());
    INFO(r.output);
    REQUIRE(r.exit_code == 0);
    CHECK(r.output.find("cutload: warning: sampling_coarse: positions are sampled every 10 ms, longer than a tooth period "
                        "(3 ms at 10000 rpm with 2 teeth") != std::string::npos);
    CHECK(r.output.find("data: COARSE (sampling_coarse)") != std::string::npos);
    // At 2 ms rows nothing is said.
    write_slot(dir, 0.002);
    const Result fine = run("predict " + (dir / "slot.csv").string() + " --spec " + (dir / "slot.json").string() +
                            " --device cpu --out " + (dir / "forces.csv").string());
    CHECK(fine.exit_code == 0);
    CHECK(fine.output.find("warning") == std::string::npos);
    CHECK(fine.output.find("COARSE") == std::string::npos);
}

TEST_CASE("predict --commanded-from-log predicts the log's commanded path and compares it block by block", "[cli][text]") {
    const fs::path dir = scratch("text_commanded");
    write_slot(dir);
    const Result r = run("predict " + (dir / "slot.csv").string() + " --spec " + (dir / "slot.json").string() +
                         " --device cpu --out " + (dir / "forces.csv").string() + " --commanded-from-log --compare " +
                         (dir / "compare.csv").string() + " --commanded-out " + (dir / "commanded.csv").string() +
                         " --blocks " + (dir / "blocks.csv").string());
    INFO(r.output);
    REQUIRE(r.exit_code == 0);
    const auto rows = read_csv(dir / "compare.csv");
    REQUIRE(rows.size() == 2);
    for (const auto& row : rows) {
        INFO(row.at("block"));
        // The commanded path runs 10 ms ahead on the same line: 0.2 mm at 20 mm/s, except where
        // the log starts and stops (the commanded motion ends 10 ms early).
        CHECK(std::stod(row.at("mean_deviation_mm")) == Approx(0.2).margin(0.02));
        CHECK(std::stod(row.at("programmed_feed_mm_min")) == Approx(1200).epsilon(0.02));
        // The same steady slot: the same force either way.
        CHECK(std::stod(row.at("actual_peak_force_N")) == Approx(std::stod(row.at("commanded_peak_force_N"))).epsilon(0.05));
    }
    CHECK(column_values(rows, "block") == std::set<std::string>{kRough, kFinish});
    CHECK(fs::exists(dir / "commanded.csv"));
    CHECK(read_csv(dir / "blocks.csv").front().count("commanded_peak_force_N") == 1);

    // Refused clearly: with --program, and for a log without commanded positions.
    Result both = run("predict " + (dir / "slot.csv").string() + " --spec " + (dir / "slot.json").string() + " --out " +
                      (dir / "f.csv").string() + " --commanded-from-log --program " + (dir / "slot.json").string());
    CHECK(both.exit_code == 2);
    CHECK(both.output.find("choose one") != std::string::npos);
    write(dir / "plain.csv", "t,x,y,z\n0,1,2,3\n0.01,1.1,2,3\n0.02,1.2,2,3\n");
    Result plain = run("predict " + (dir / "plain.csv").string() + " --spec " + (dir / "slot.json").string() + " --out " +
                       (dir / "f.csv").string() + " --commanded-from-log");
    CHECK(plain.exit_code == 2);
    CHECK(plain.output.find("no commanded positions") != std::string::npos);
}

TEST_CASE("the real UMich export: inspect through its preset names the quantization", "[cli][text][shared]") {
    const Result r = run("inspect " + std::string(CUTLOAD_SHARED_DIR) + "/data/real/umich_cnc_mill/experiment_05.csv --map umich_cnc_mill");
    INFO(r.output);
    REQUIRE(r.exit_code == 0);
    CHECK(r.output.find("position_quantized: positions are written in steps of 1 mm") != std::string::npos);
    CHECK(r.output.find("position step 1 mm") != std::string::npos);
    CHECK(r.output.find("commanded     the log also holds commanded positions") != std::string::npos);
}
