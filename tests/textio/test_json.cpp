// Hand-written JSON (run specs, tools, channel maps) read through one helper: a number beyond a
// double (1e400) names file, line, column and key instead of the library's bare "number overflow
// parsing '1e400'"; syntax errors and nesting limits name their place; text is decoded as shops
// write it (issue 19).
#include "textio/json.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>

using namespace cutload::textio;
using Catch::Matchers::Contains;
using Catch::Matchers::StartsWith;

namespace {

// The JsonError `text` raises, or a failed check when it parses.
JsonError error_of(const std::string& text, const std::string& source = "spec.json") {
    try {
        (void)parse_json(text, source);
    } catch (const JsonError& e) {
        return e;
    }
    FAIL("parsed without an error: " << text);
    throw std::logic_error("unreachable");
}

std::filesystem::path scratch_file(const std::string& name) {
    return std::filesystem::temp_directory_path() / ("cutload_json_test_" + std::to_string(::getpid()) + "_" + name);
}

}  // namespace

TEST_CASE("json: a number beyond a double names file, line, column and key path", "[json]") {
    const std::string spec = "{\n"
                             "  \"tool\": {\"shape\": \"flat\", \"diameter_mm\": 8},\n"
                             "  \"material\": {\"name\": \"A7075\",\n"
                             "               \"Ktc_N_mm2\": 1e400}\n"
                             "}\n";
    const JsonError e = error_of(spec);
    CHECK(e.key() == "material.Ktc_N_mm2");
    CHECK(e.line() == 4);
    CHECK(e.column() == 29);   // the first character of 1e400
    CHECK_THAT(e.what(), StartsWith("spec.json:4:29: material.Ktc_N_mm2: the number 1e400 is out of range"));
    CHECK_THAT(e.what(), !Contains("json.exception"));
}

TEST_CASE("json: the key path follows arrays and negative overflow", "[json]") {
    const JsonError in_array = error_of(R"({"stock": {"box_mm": {"min": [0, 0, 0], "max": [10, -1e400, 5]}}})");
    CHECK(in_array.key() == "stock.box_mm.max[1]");
    CHECK_THAT(in_array.what(), Contains("the number -1e400 is out of range"));
    const JsonError top = error_of("1E+999");
    CHECK(top.key().empty());
    CHECK_THAT(top.what(), StartsWith("spec.json:1:1: the number 1E+999 is out of range"));
    // Underflow is no error: 1e-400 is 0 to a double, as close as it can be.
    CHECK(parse_json(R"({"a": 1e-400})", "x").at("a").get<double>() == 0.0);
}

TEST_CASE("json: a syntax error names its place and says not valid JSON", "[json]") {
    const JsonError e = error_of("{\n  \"tool\": {\"shape\": \"flat\",,}\n}");
    CHECK(e.line() == 2);
    CHECK(e.key() == "tool");
    CHECK_THAT(e.what(), StartsWith("spec.json:2:"));
    CHECK_THAT(e.what(), Contains("not valid JSON: syntax error"));
    CHECK_THAT(e.what(), !Contains("[json.exception"));
    CHECK_THAT(error_of("").what(), Contains("not valid JSON"));
    CHECK_THAT(error_of("{} {}").what(), Contains("not valid JSON"));   // one document only
}

TEST_CASE("json: nesting deeper than the limit is refused, at the limit it is read", "[json]") {
    const std::string at_limit = std::string(kMaxJsonDepth, '[') + std::string(kMaxJsonDepth, ']');
    CHECK(parse_json(at_limit, "x").is_array());
    const std::string deep = std::string(kMaxJsonDepth + 1, '[') + std::string(kMaxJsonDepth + 1, ']');
    CHECK_THAT(error_of(deep).what(), Contains("nested deeper than 64 levels"));
    // A hostile depth costs nothing: refused at level 65, not after building a million levels.
    CHECK_THAT(error_of(std::string(1000000, '[')).what(), Contains("nested deeper"));
}

TEST_CASE("json: the document read equals the JSON library's own parse", "[json]") {
    const std::string text = R"({"tool": {"shape": "ball", "diameter_mm": 6.0, "flutes": 4, "holder": null,
        "list": [1, -2, 3.5e2, true, false, null, "x", [], {}], "big": 18446744073709551615, "neg": -9223372036854775808},
        "dup": 1, "dup": 2, "name": "Fr\u00e4sen"})";
    CHECK(parse_json(text, "x") == nlohmann::json::parse(text));
}

TEST_CASE("json: text is decoded as shops write it, NUL is refused with its place", "[json]") {
    // A material named in a Windows-1252 editor: the byte 0xE4 is an ä.
    const nlohmann::json j = parse_json("{\"name\": \"Stahl geh\xE4rtet\"}", "spec.json");
    CHECK(j.at("name").get<std::string>() == "Stahl gehärtet");
    CHECK_NOTHROW(j.dump());   // valid UTF-8 for every answer that echoes it
    try {
        (void)parse_json(std::string("{\"a\":\n 1\0}", 10), "spec.json");
        FAIL("a NUL byte was read");
    } catch (const TextError& e) {
        CHECK_THAT(e.what(), StartsWith("spec.json:2:3:"));
        CHECK_THAT(e.what(), Contains("NUL"));
    }
}

TEST_CASE("json: a file is read whole, a missing or oversized one is one error naming it", "[json]") {
    const auto path = scratch_file("spec.json");
    std::ofstream(path) << R"({"grid_mm": 1e400})";
    try {
        (void)read_json_file(path.string(), "run spec");
        FAIL("read");
    } catch (const JsonError& e) {
        CHECK_THAT(e.what(), StartsWith(path.string() + ":1:13: grid_mm: the number 1e400 is out of range"));
    }
    CHECK_THROWS_WITH(read_json_file((path.string() + ".missing"), "run spec"),
                      path.string() + ".missing: cannot open the run spec");
    {
        std::ofstream big(path, std::ios::binary);
        big << '[';
        const std::string chunk(1 << 20, ' ');
        for (std::size_t i = 0; i <= kMaxJsonFileBytes >> 20; ++i) big << chunk;
        big << ']';
    }
    CHECK_THROWS_WITH(read_json_file(path.string(), "tool file"), Contains("larger than 16 MiB"));
    std::filesystem::remove(path);
}
