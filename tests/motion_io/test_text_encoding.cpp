// Text as shops write it (docs/formats.md, "Text encoding"): Latin-1 and Windows-1252 bytes in
// headers and block names decoded, bytes that are not text refused at their line and column, a
// no-break space around a number trimmed and inside one refused; the report always valid UTF-8.
#include "test_helpers.hpp"

#include "textio/csv.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <fstream>
#include <set>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;

namespace {

// A 1 s move along X at 600 mm/min, 10 ms rows; `block` and `extra` fill the last two columns.
std::string log_with(const std::string& header_extra, const std::string& block_a, const std::string& block_b,
                     const std::string& x_override = {}, int override_row = -1) {
    std::string s = "t,x,y,z,block," + header_extra + "\n";
    for (int i = 0; i <= 100; ++i) {
        const std::string x = i == override_row ? x_override : std::to_string(10.0 + 0.1 * i);
        s += std::to_string(0.01 * i) + "," + x + ",0.000,-5.000," + (i < 50 ? block_a : block_b) + ",21.5\n";
    }
    return s;
}

std::string error_of(const std::string& name, const std::string& content) {
    TempFile f(name, content);
    try {
        ingest(f.path(), ReadOptions{});
    } catch (const IngestError& e) {
        return e.what();
    }
    return "no error";
}

// "line:column:" of byte `pos` in `text` (the text before it on its line is ASCII).
std::string place_of(const std::string& text, std::size_t pos) {
    const std::size_t line = 1 + static_cast<std::size_t>(std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(pos), '\n'));
    const std::size_t start = text.rfind('\n', pos) == std::string::npos ? 0 : text.rfind('\n', pos) + 1;
    return std::to_string(line) + ":" + std::to_string(pos - start + 1) + ":";
}

bool names_block(const MotionModel& m, const std::string& name) {
    return std::find(m.block_names.begin(), m.block_names.end(), name) != m.block_names.end();
}

}  // namespace

TEST_CASE("text: a Latin-1 header and a cp1252 block name decode to what they mean", "[text][csv]") {
    // "Temperatur [°C]" with the degree sign as Latin-1 0xB0; "Fräsen N10" with ä as 0xE4, and a
    // cp1252 en dash (0x96) in the other block name.
    TempFile f("latin1.csv", log_with("Temperatur [\xB0" "C]", "Fr\xE4sen N10", "Schlichten \x96 N20"));
    IngestReport report;
    const MotionModel m = ingest(f.path(), ReadOptions{}, &report);
    CHECK(names_block(m, "Fräsen N10"));
    CHECK(names_block(m, "Schlichten – N20"));
    std::string unknown;
    for (const auto& w : report.warnings)
        if (w.code == "unknown_column") unknown = w.message;
    CHECK_THAT(unknown, Catch::Contains("'Temperatur [°C]'"));
    // The report (what the service stores and answers) is valid JSON text.
    const std::string json = report_to_json(report).dump();
    CHECK_THAT(json, Catch::Contains("Temperatur [°C]"));
}

TEST_CASE("text: the same names in UTF-8 read the same, and the resampled CSV writes UTF-8", "[text][csv]") {
    TempFile latin("names_latin1.csv", log_with("note", "Fr\xE4sen N10", "N20"));
    TempFile utf8("names_utf8.csv", log_with("note", "Fräsen N10", "N20"));
    ReadOptions opt;
    opt.step_ms = 10;
    CHECK(ingest(latin.path(), opt).block_names == ingest(utf8.path(), opt).block_names);
    TempFile out("names_resampled.csv", "", false);
    resample_to_csv(latin.path(), opt, out.path());
    std::ifstream in(out.path(), std::ios::binary);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    CHECK_THAT(text, Catch::Contains(",Fräsen N10\n"));
}

TEST_CASE("text: a byte that is not text is refused at its line and column", "[text][csv]") {
    // 0x81 is undefined in Windows-1252: refused at its line and column.
    std::string s = log_with("note", "N10", "N20");
    const std::size_t block = s.find(",N20") + 1;
    s.replace(block, 3, "N\x81" "20");
    CHECK(place_of(s, block + 1) == "52:34:");
    CHECK(error_of("undefined_byte.csv", s) ==
          std::string(TempFile("undefined_byte.csv", "", false).path()) + ":52:34: byte 0x81 is not a character (not UTF-8, "
                                                                        "and undefined in Windows-1252)");
    std::string nul = log_with("note", "N10", "N20");
    nul[nul.find("N20")] = '\0';
    CHECK_THAT(error_of("nul.csv", nul), Catch::Contains("nul.csv:" + place_of(nul, nul.find('\0'))) && Catch::Contains("NUL byte"));
}

TEST_CASE("text: a no-break space after a number is trimmed, inside one refused with line and column", "[text][csv]") {
    // 12.5 followed by a Latin-1 no-break space (0xA0) reads as 12.5.
    TempFile trailing("nbsp_after.csv", log_with("note", "N10", "N20", "12.5\xA0", 30));
    const MotionModel m = ingest(trailing.path(), ReadOptions{});
    CHECK(std::any_of(m.x_mm.begin(), m.x_mm.end(), [](double x) { return std::fabs(x - 12.5) < 1e-9; }));
    // 1 234.5 with the no-break space as a digit group: refused, never read as 1 or 1234.5.
    const std::string e = error_of("nbsp_inside.csv", log_with("note", "N10", "N20", "1\xA0" "234.5", 30));
    // Row 30 is line 32; the x field starts after "0.300000,".
    CHECK_THAT(e, Catch::Contains("nbsp_inside.csv:32:10:") && Catch::Contains("column 'x'") &&
                      Catch::Contains("no-break space inside it"));
    // The same in UTF-8 (C2 A0).
    CHECK_THAT(error_of("nbsp_utf8.csv", log_with("note", "N10", "N20", "1\xC2\xA0" "234.5", 30)),
               Catch::Contains("nbsp_utf8.csv:32:10:") && Catch::Contains("no-break space inside it"));
}

TEST_CASE("text: SHDR block names and keys decode, a bad byte names line and column", "[text][shdr]") {
    const std::string shdr =
        "2024-01-01T00:00:00.000Z|path_pos|0 0 0|block|Fr\xE4sen N10|S1speed|1000\n"
        "2024-01-01T00:00:00.100Z|path_pos|1 0 0\n"
        "2024-01-01T00:00:00.200Z|path_pos|2 0 0|block|N20 \x93" "fin\x94\n"
        "2024-01-01T00:00:00.300Z|path_pos|3 0 0\n";
    TempFile f("latin1.shdr", shdr);
    IngestReport report;
    const MotionModel m = ingest(f.path(), ReadOptions{}, &report);
    CHECK(names_block(m, "Fräsen N10"));
    CHECK(names_block(m, "N20 “fin”"));
    CHECK(report.spindle_max_rpm == 1000);
    std::string bad = shdr;
    const std::size_t at = bad.find("N20") + 1;
    bad.replace(at - 1, 3, "N\x9D" "0");
    CHECK_THAT(error_of("bad.shdr", bad), Catch::Contains("bad.shdr:" + place_of(bad, at)) && Catch::Contains("0x9D"));
    std::string grouped = shdr;
    grouped.replace(grouped.find("|2 0 0"), 6, "|2\xA0" "000 0 0");
    CHECK_THAT(error_of("grouped.shdr", grouped), Catch::Contains("grouped.shdr:3:") && Catch::Contains("path_pos"));
}

TEST_CASE("text: block names with quotes and commas round-trip through the resampled CSV", "[text][csv]") {
    // Written as RFC 4180 quotes them, read by textio's reader: the same names come back.
    const std::string a = "Schruppen \"grob\", Kontur", b = "N20, \"fein\"";
    std::string s = "t,x,y,z,block\n";
    for (int i = 0; i <= 100; ++i)
        s += std::to_string(0.01 * i) + "," + std::to_string(10.0 + 0.1 * i) + ",0,0," +
             cutload::textio::csv_field(i < 50 ? a : b) + "\n";
    TempFile f("quoted_blocks.csv", s);
    ReadOptions opt;
    opt.step_ms = 10;
    const MotionModel m = ingest(f.path(), opt);
    REQUIRE(m.block_names.size() == 2);
    CHECK(m.block_names[0] == a);
    CHECK(m.block_names[1] == b);
    TempFile out("quoted_blocks_resampled.csv", "", false);
    resample_to_csv(f.path(), opt, out.path());
    std::ifstream in(out.path(), std::ios::binary);
    cutload::textio::CsvReader csv(in, out.path());
    REQUIRE(csv.next());
    REQUIRE(csv[7] == "block");
    std::set<std::string> seen;
    while (csv.next()) seen.emplace(csv[7]);
    CHECK(seen == std::set<std::string>{a, b});
}
