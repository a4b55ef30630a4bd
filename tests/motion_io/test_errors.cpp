// Every class of bad input is an IngestError that names the file, the line and the column or key.
#include "test_helpers.hpp"

#include <catch2/catch.hpp>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;

namespace {

std::string error_of(const std::string& name, const std::string& content, ReadOptions opt = {}, bool create = true) {
    TempFile f(name, content, create);
    try {
        ingest(f.path(), opt);
    } catch (const IngestError& e) {
        return e.what();
    }
    return "no error";
}

}  // namespace

TEST_CASE("errors: non-numeric and NaN values name file, line and column", "[errors]") {
    const std::string e1 = error_of("bad_number.csv", "t,x,y,z\n0,1,2,3\n0.01,1.1,abc,3\n");
    CHECK_THAT(e1, Catch::Contains("bad_number.csv:3") && Catch::Contains("'y'") && Catch::Contains("'abc' is not a number"));
    const std::string e2 = error_of("nan.csv", "t,x,y,z\n0,1,2,3\n0.01,nan,2,3\n");
    CHECK_THAT(e2, Catch::Contains("nan.csv:3") && Catch::Contains("'x'") && Catch::Contains("not a finite number"));
}

TEST_CASE("errors: missing required columns and unknown units", "[errors]") {
    CHECK_THAT(error_of("missing.csv", "t,x,y\n0,1,2\n"),
               Catch::Contains("missing.csv:1") && Catch::Contains("missing required column 'z'"));
    CHECK_THAT(error_of("notime.csv", "x,y,z\n0,1,2\n"), Catch::Contains("notime.csv:1") && Catch::Contains("'t'"));
    CHECK_THAT(error_of("unit.csv", "t,x [furlong],y,z\n0,1,2,3\n"),
               Catch::Contains("unit.csv:1") && Catch::Contains("x [furlong]") && Catch::Contains("unknown length unit"));
    ReadOptions opt;
    opt.feed_unit = "mm/fortnight";
    CHECK_THAT(error_of("feedunit.csv", "t,x,y,z,feed\n0,1,2,3,4\n", opt), Catch::Contains("unknown time unit"));
}

TEST_CASE("errors: time that never advances, wrong field count, empty file", "[errors]") {
    CHECK_THAT(error_of("stuck.csv", "t,x,y,z\n5,1,2,3\n5,1.1,2,3\n5,1.2,2,3\n"),
               Catch::Contains("stuck.csv:2") && Catch::Contains("time never advances"));
    CHECK_THAT(error_of("fields.csv", "t,x,y,z\n0,1,2,3\n0.01,1,2\n"),
               Catch::Contains("fields.csv:3") && Catch::Contains("expected 4 fields"));
    CHECK_THAT(error_of("empty.csv", ""), Catch::Contains("empty.csv") && Catch::Contains("empty file"));
    CHECK_THAT(error_of("nofile.csv", "", ReadOptions{Format::Csv}, false),
               Catch::Contains("nofile.csv") && Catch::Contains("cannot open"));
}

TEST_CASE("errors: SHDR values and map files name the key", "[errors]") {
    const std::string shdr = "2022-08-08T13:51:34.7167146Z|p1LPathPos|1 2 3\n"
                             "2022-08-08T13:51:35.0000000Z|p1LPathPos|1 two 3\n";
    CHECK_THAT(error_of("bad.shdr", shdr), Catch::Contains("bad.shdr:2") && Catch::Contains("key 'p1LPathPos'"));
    CHECK_THAT(error_of("stamp.shdr", "2022-08-08T13:51:34Z|path_pos|1 2 3\nyesterday|path_pos|2 2 3\n", ReadOptions{Format::Shdr}),
               Catch::Contains("stamp.shdr:2") && Catch::Contains("ISO 8601"));
    CHECK_THAT(error_of("nopos.shdr", "2022-08-08T13:51:34Z|S1speed|100\n"),
               Catch::Contains("nopos.shdr") && Catch::Contains("no position data"));
    TempFile map("bad_map.json", R"({"spindel": "S1speed"})");
    ReadOptions opt;
    opt.map_file = map.path();
    CHECK_THAT(error_of("mapped.shdr", shdr, opt), Catch::Contains("bad_map.json") && Catch::Contains("'spindel'"));
}

TEST_CASE("warnings: out-of-range values and gaps are counted, not fatal", "[errors]") {
    std::string s = "t,x,y,z,spindle\n";
    for (int i = 0; i < 40; ++i) s += std::to_string(0.01 * i) + "," + std::to_string(0.1 * i) + ",0,0,500000\n";
    s += "2.0,4.0,0,0,500000\n";   // 1.6 s without a reading
    TempFile f("warn.csv", s);
    ReadOptions opt;
    opt.step_ms = 10;
    IngestReport report;
    ingest(f.path(), opt, &report);
    std::map<std::string, std::size_t> counts;
    for (const auto& w : report.warnings) counts[w.code] = w.count;
    CHECK(counts["out_of_range"] == 41);
    CHECK(counts["gap"] == 1);
}
