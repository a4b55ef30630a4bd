// The public SHDR pieces (motion_io/shdr.hpp): time stamps, the line tokenizer, the key map.
#include "motion_io/shdr.hpp"
#include "test_helpers.hpp"

#include <catch2/catch.hpp>

#include <random>

using namespace cutload::motion_io;

TEST_CASE("ISO time stamps parse to the seconds a calendar gives and format back exactly", "[shdr]") {
    // Reference seconds from Python's calendar.timegm (an independent civil-date implementation).
    const auto t = parse_iso_time("2022-08-08T13:51:34.7167146Z");
    REQUIRE(t);
    CHECK(t->sec == 1659966694);
    CHECK(t->frac == Approx(0.7167146).epsilon(1e-15));
    CHECK(t->nanos() == 1659966694716714600);
    CHECK(format_iso_time(t->nanos()) == "2022-08-08T13:51:34.7167146Z");
    CHECK(parse_iso_time("2024-02-29T23:59:59Z")->sec == 1709251199);
    CHECK(parse_iso_time("1969-12-31T23:59:59Z")->sec == -1);
    CHECK(format_iso_time(0) == "1970-01-01T00:00:00.000Z");
    CHECK(format_iso_time(-1) == "1969-12-31T23:59:59.999999999Z");
    CHECK(format_iso_time(1709251199'120000000) == "2024-02-29T23:59:59.120Z");
    // Accepted variants: a space for the T, no Z, an @duration suffix; rejected: no separator.
    CHECK(parse_iso_time("2022-08-08 13:51:34.5")->nanos() == 1659966694'500000000);
    CHECK(parse_iso_time("2022-08-08T13:51:34.5Z@100.0")->nanos() == 1659966694'500000000);
    CHECK_FALSE(parse_iso_time("2022-08-08T13:51:34,5Z"));
    CHECK_FALSE(parse_iso_time("13:51:34"));
}

TEST_CASE("format_iso_time and parse_iso_time are inverse over two centuries to the nanosecond", "[shdr]") {
    std::mt19937_64 rng(20240229);
    // 1900-01-01 .. 2100-01-01 in ns.
    std::uniform_int_distribution<std::int64_t> ns(-2208988800LL * 1'000'000'000, 4102444800LL * 1'000'000'000);
    for (int i = 0; i < 20000; ++i) {
        const std::int64_t v = ns(rng);
        const auto back = parse_iso_time(format_iso_time(v));
        REQUIRE(back);
        REQUIRE(back->nanos() == v);
    }
}

TEST_CASE("the line tokenizer classifies an adapter's lines as the file reader skips them", "[shdr]") {
    ShdrLineTokenizer tok;
    CHECK(tok.next("2022-08-08T13:51:34.7167146Z|X1actw|1039.897|Z1actw|269.0133\r") == ShdrLineKind::Data);
    REQUIRE(tok.fields().size() == 5);
    CHECK(tok.fields()[4] == "269.0133");   // the '\r' is gone
    CHECK_FALSE(tok.odd_fields());
    CHECK(tok.next("2022-08-08T13:51:34.7167146Z|X1actw|1039.897|Z1actw") == ShdrLineKind::Data);
    CHECK(tok.odd_fields());
    CHECK(tok.next("2022-08-08T13:51:34.7167146Z|system|NORMAL||||") == ShdrLineKind::Condition);
    CHECK(tok.next("2022-08-08T13:51:34.7167146Z|Zload_cond|UNAVAILABLE||||") == ShdrLineKind::Condition);
    // UNAVAILABLE with a value in the code field is a data line of 7 fields, not a condition.
    CHECK(tok.next("2022-08-08T13:51:34.7167146Z|a|UNAVAILABLE|b|1|c|2") == ShdrLineKind::Data);
    CHECK(tok.next("2022-08-08T13:51:34.7237196Z|@REMOVE_ALL_ASSETS@|CuttingTool") == ShdrLineKind::Asset);
    CHECK(tok.next("* PONG 10000") == ShdrLineKind::Command);
    CHECK(tok.next("") == ShdrLineKind::Blank);
    CHECK(tok.next("garbage") == ShdrLineKind::Short);
    CHECK(tok.next("2022-08-08T13:43:36.0810790Z|@ASSET@|123456.2201|CuttingTool|--multiline--ABCD") == ShdrLineKind::Asset);
    CHECK(tok.in_multiline());
    CHECK(tok.multiline_terminator() == "--multiline--ABCD");
    // Inside the body even a line that looks like data is body.
    CHECK(tok.next("2022-08-08T13:51:34Z|X1actw|1") == ShdrLineKind::Body);
    CHECK(tok.fields().empty());
    CHECK(tok.next("--multiline--ABCD") == ShdrLineKind::Body);
    CHECK_FALSE(tok.in_multiline());
    CHECK(tok.next("2022-08-08T13:51:34Z|X1actw|1") == ShdrLineKind::Data);
    CHECK(tok.next("2022-08-08T13:51:34Z|table|--multiline--0F") == ShdrLineKind::Multiline);
    tok.reset();   // a dropped connection: the body never closes
    CHECK(tok.next("2022-08-08T13:51:34Z|X1actw|2") == ShdrLineKind::Data);
}

TEST_CASE("a key map file replaces the channels it names, and unit factors follow map and options", "[shdr]") {
    const ShdrKeyMap d = default_shdr_key_map();
    CHECK(d.position.front() == "path_pos");
    const ShdrUnitFactors df = shdr_unit_factors(d);
    CHECK(df.feed_mm_min == 60.0);   // MTConnect PATH_FEEDRATE is mm/s
    CHECK(df.length_mm == 1.0);
    test::TempFile map("shdr_line_map.json", R"({"position": [], "x": "Xabs", "feed": ["Fact"],
        "units": {"length": "in", "feed": "in/min", "spindle": "rev/s"}})");
    const ShdrKeyMap m = load_shdr_key_map(map.path());
    CHECK(m.position.empty());
    CHECK(m.x == std::vector<std::string>{"Xabs"});
    CHECK(m.y == d.y);
    const ShdrUnitFactors f = shdr_unit_factors(m);
    CHECK(f.length_mm == 25.4);
    CHECK(f.feed_mm_min == Approx(25.4));
    CHECK(f.spindle_rpm == 60.0);
    ReadOptions opt;
    opt.length_unit = "mm";   // --units alone: feed in <length>/s
    CHECK(shdr_unit_factors(m, opt).feed_mm_min == 60.0);
    test::TempFile bad("shdr_line_bad_map.json", R"({"feeds": ["x"]})");
    CHECK_THROWS_WITH(load_shdr_key_map(bad.path()), Catch::Contains("unknown key 'feeds'"));
}
