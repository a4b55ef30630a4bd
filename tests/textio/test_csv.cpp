// RFC 4180 CSV both ways: the writer's output read back by the reader, the RFC's own cases, the
// export dialects (';' and tab, comments, blanks), and every error naming its line and column.
#include "textio/csv.hpp"

#include <catch2/catch.hpp>

#include <random>
#include <sstream>

using namespace cutload::textio;

namespace {

std::vector<std::vector<std::string>> read_all(const std::string& text, CsvOptions opt = {}) {
    std::istringstream in(text);
    CsvReader r(in, "t.csv", opt);
    std::vector<std::vector<std::string>> rows;
    while (r.next()) {
        rows.emplace_back();
        for (std::size_t i = 0; i < r.size(); ++i) rows.back().emplace_back(r[i]);
    }
    return rows;
}

std::string error_of(const std::string& text, CsvOptions opt = {}) {
    try {
        read_all(text, opt);
    } catch (const TextError& e) {
        return e.what();
    }
    return "no error";
}

// Seeded random fields over an alphabet that holds everything that forces quoting.
std::string random_field(std::mt19937_64& rng) {
    static const std::vector<std::string> pieces{"a", "Z", "7", ".", ",", ";", "\t", "\"", "\n", "\r", " ", "N10",
                                                 "\xC3\xA4", "\xE2\x82\xAC", "#", "'", "\"\"", "x y"};
    std::uniform_int_distribution<std::size_t> len(0, 6), pick(0, pieces.size() - 1);
    std::string f;
    for (std::size_t n = len(rng); n > 0; --n) f += pieces[pick(rng)];
    return f;
}

}  // namespace

TEST_CASE("csv: what the writer quotes the reader reads back unchanged, for comma, semicolon and tab", "[csv]") {
    for (const char delim : {',', ';', '\t'}) {
        std::mt19937_64 rng(20240611 + static_cast<unsigned>(delim));
        std::vector<std::vector<std::string>> rows(300);
        std::string text;
        for (auto& row : rows) {
            const std::size_t n = 1 + rng() % 6;
            for (std::size_t i = 0; i < n; ++i) {
                row.push_back(random_field(rng));
                if (i) text += delim;
                append_field(text, row.back(), delim);
            }
            text += (rng() % 2) ? "\r\n" : "\n";
        }
        CsvOptions opt;
        opt.delimiter = delim;
        opt.skip_blank_lines = false;   // a row of one empty field is a record here
        const auto back = read_all(text, opt);
        REQUIRE(back.size() == rows.size());
        for (std::size_t k = 0; k < rows.size(); ++k) {
            auto expected = rows[k];
            // A CR before a line break inside a quoted field is the line end (read as LF).
            for (auto& f : expected)
                for (std::size_t p; (p = f.find("\r\n")) != std::string::npos;) f.replace(p, 2, "\n");
            INFO("delimiter " << int(delim) << ", row " << k);
            CHECK(back[k] == expected);
        }
    }
}

TEST_CASE("csv: quoting happens exactly when a field needs it", "[csv]") {
    CHECK(csv_field("N10") == "N10");
    CHECK(csv_field("") == "");
    CHECK(csv_field("Fräsen N10") == "Fräsen N10");
    CHECK(csv_field("a,b") == "\"a,b\"");
    CHECK(csv_field("say \"hi\"") == "\"say \"\"hi\"\"\"");
    CHECK(csv_field("two\nlines") == "\"two\nlines\"");
    CHECK(csv_field(" lead") == "\" lead\"");
    CHECK(csv_field("a;b") == "a;b");
    CHECK(csv_field("a;b", ';') == "\"a;b\"");
    CHECK(csv_field("12\" vise") == "\"12\"\" vise\"");
    CHECK_FALSE(needs_quotes("1.98E+02"));
}

TEST_CASE("csv: the RFC 4180 cases, trimming and unquoted quotes", "[csv]") {
    const auto rows = read_all("a,\"b,c\",\"d\"\"e\",\"f\ng\"\n"
                               "  x  , \"y\" ,12\" vise,\n"
                               "\"\",last\n");
    REQUIRE(rows.size() == 3);
    CHECK(rows[0] == std::vector<std::string>{"a", "b,c", "d\"e", "f\ng"});
    CHECK(rows[1] == std::vector<std::string>{"x", "y", "12\" vise", ""});
    CHECK(rows[2] == std::vector<std::string>{"", "last"});
    CsvOptions raw;
    raw.trim = false;
    CHECK(read_all("  x  ,y\n", raw)[0] == std::vector<std::string>{"  x  ", "y"});
}

TEST_CASE("csv: comments, blank lines, byte order mark and the last line without a line end", "[csv]") {
    CsvOptions opt;
    opt.comment = '#';
    const auto rows = read_all("\xEF\xBB\xBFt,x\n# a \"quoted\" note\n\n   \n1,2", opt);
    REQUIRE(rows.size() == 2);
    CHECK(rows[0] == std::vector<std::string>{"t", "x"});
    CHECK(rows[1] == std::vector<std::string>{"1", "2"});
}

TEST_CASE("csv: delimiter detection counts outside quotes and prefers tab, then semicolon", "[csv]") {
    CHECK(detect_delimiter("t,x,y") == ',');
    CHECK(detect_delimiter("t;x;y") == ';');
    CHECK(detect_delimiter("t\tx;y") == '\t');
    CHECK(detect_delimiter("t,\"a;b\",y") == ',');
    CHECK(detect_delimiter("0,5;1,25") == ';');
    CsvOptions opt;
    opt.delimiter = 0;
    std::istringstream in("Zeit [s];Fx\n0,5;1,25\nt,x\n");
    CsvReader r(in, "d.csv", opt);
    REQUIRE(r.next());
    CHECK(r.delimiter() == ';');
    CHECK(r.size() == 2);
    r.set_delimiter(';');   // fixed from here on, whatever the next line holds
    REQUIRE(r.next());
    CHECK(std::string(r[1]) == "1,25");
    REQUIRE(r.next());
    CHECK(r.size() == 1);
}

TEST_CASE("csv: fields know their line and character column", "[csv]") {
    std::istringstream in("h1,h2,h3\n\"m\nn\",Fräsen,\xB0" "C x\n");
    CsvReader r(in, "c.csv");
    REQUIRE(r.next());
    CHECK(r.column_of(2) == 7);
    REQUIRE(r.next());
    CHECK(r.line() == 2);
    CHECK(r.line_of(1) == 3);
    CHECK(r.column_of(1) == 4);
    CHECK(r.column_of(2) == 11);   // after "n",Fräsen, : ä is one character
    CHECK(std::string(r[2]) == "\xC2\xB0" "C x");   // Latin-1 0xB0 decoded
    try {
        r.fail(2, "bad");
        FAIL("fail() returned");
    } catch (const TextError& e) {
        CHECK(std::string(e.what()) == "c.csv:3:11: bad");
    }
}

TEST_CASE("csv: errors name the line and column", "[csv]") {
    CHECK(error_of("a,b\n1,\"open\n2,3\n") == "t.csv:2:3: quoted field never closed: the file ends inside it");
    CHECK(error_of("a,\"b\"c,d\n") == "t.csv:1:6: text after the closing quote of a field (a quote inside a quoted field is written \"\")");
    CHECK(error_of("ok\nx,\x81y\n") == "t.csv:2:3: byte 0x81 is not a character (not UTF-8, and undefined in Windows-1252)");
    CHECK(error_of(std::string("ok\nab\0c\n", 8)) == "t.csv:2:3: a NUL byte (0x00): binary data, not text");
}

TEST_CASE("csv: memory is bounded: an overlong field, record or line is an error naming it", "[csv]") {
    CsvOptions opt;
    opt.max_field_bytes = 100;
    opt.max_record_bytes = 1000;
    const std::string big(150, 'x');
    CHECK(error_of("a,b\n1," + big + "\n", opt) == "t.csv:2:3: field longer than 100 bytes (a quote never closed?)");
    CHECK(error_of("a,b\n1,\"" + big + "\"\n", opt) == "t.csv:2:3: quoted field longer than 100 bytes (a quote never closed?)");
    // An unclosed quote over many short lines stops at the field limit, at the line it opened.
    std::string lines = "a,b\n1,\"open\n";
    for (int i = 0; i < 100; ++i) lines += "row,row\n";
    CHECK(error_of(lines, opt) == "t.csv:2:3: quoted field longer than 100 bytes (a quote never closed?)");
    // A line without a line break (a binary file) stops at the record limit.
    std::string field_ok;
    for (int i = 0; i < 40; ++i) field_ok += std::string(50, 'y') + ",";
    CHECK_THAT(error_of("a\n" + field_ok + "\n", opt), Catch::StartsWith("t.csv:2: line longer than 1000 bytes"));
}
