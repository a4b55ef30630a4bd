// Text as shops write it, through the service (docs/formats.md, "Text encoding"): a log with a
// Latin-1 header and cp1252 block names, uploaded under a Latin-1 file name, is accepted with the
// text decoded (it used to be a 500); a byte that is not text, or a digit group inside a number,
// is a 400 naming line and column; block names with quotes and commas come back intact in the
// CSV answers; a controller export goes in through a bundled map preset, its coarse data said.
#include "harness.hpp"
#include "motion_io/controller_export.hpp"

#include "textio/csv.hpp"

#include <cmath>
#include <cstdio>
#include <set>

using namespace cutload::test;

namespace {

// slot_log_csv with its blocks renamed and a Latin-1 temperature column added.
std::string shop_log(const std::string& first_block, const std::string& second_block) {
    std::istringstream in(slot_log_csv(1.0));
    std::string line, out;
    std::getline(in, line);
    out = line + ",Temperatur [\xB0" "C]\n";
    while (std::getline(in, line)) {
        const bool first = line.substr(line.rfind(',') + 1) == "N10";
        line.resize(line.rfind(',') + 1);
        cutload::textio::append_field(line, first ? first_block : second_block);
        out += line + ",21.5\n";
    }
    return out;
}

std::set<std::string> csv_column(const std::string& text, const std::string& column) {
    std::istringstream in(text);
    cutload::textio::CsvReader csv(in, "answer");
    REQUIRE(csv.next());
    std::size_t col = csv.size();
    for (std::size_t i = 0; i < csv.size(); ++i)
        if (csv[i] == column) col = i;
    REQUIRE(col < csv.size());
    std::set<std::string> values;
    while (csv.next())
        if (!csv[col].empty()) values.emplace(csv[col]);
    return values;
}

}  // namespace

TEST_CASE("text: a Latin-1 / cp1252 log under a Latin-1 file name is accepted with its text decoded", "[text]") {
    TestServer ts([](cutload::server::ServerOptions& o) { o.max_points = 200000; });
    auto c = ts.client(ts.write_key);
    const std::string log = shop_log("Fr\xE4sen \x93N10\x94", "Schlichten, \"fein\"");
    const auto up = c.Post("/api/v1/runs", httplib::MultipartFormDataItems{{"log", log, "Fr\xE4sen.csv", "text/csv"},
                                                                          {"spec", slot_spec().dump(), "", "application/json"},
                                                                          {"name", "Los \xA7" "4", "", ""}});
    REQUIRE(up);
    INFO(up->body);
    REQUIRE(up->status == 202);
    const auto id = body(up)["id"].get<std::int64_t>();
    const json run = wait_finished(c, id);
    REQUIRE(run["state"] == "done");
    CHECK(run["inputs"]["log"]["filename"] == "Fräsen.csv");
    CHECK(run["name"] == "Los §4");
    bool saw_header = false;
    for (const auto& w : run["inputs"]["ingest"]["warnings"])
        saw_header = saw_header || w["message"].get<std::string>().find("'Temperatur [°C]'") != std::string::npos;
    CHECK(saw_header);

    const json blocks = body(c.Get(("/api/v1/runs/" + std::to_string(id) + "/blocks").c_str()));
    std::set<std::string> names;
    for (const auto& b : blocks["items"]) names.insert(b["block"].get<std::string>());
    CHECK(names == std::set<std::string>{"Fräsen “N10”", "Schlichten, \"fein\""});

    // The CSV answer quotes what must be quoted: the names come back as they are.
    const auto forces = c.Get(("/api/v1/runs/" + std::to_string(id) + "/forces?format=csv&max_points=100000").c_str());
    REQUIRE(forces);
    REQUIRE(forces->status == 200);
    CHECK(csv_column(forces->body, "block") == names);
}

TEST_CASE("text: a byte that is not text or a digit group in a number is a 400 naming line and column", "[text]") {
    TestServer ts;
    auto c = ts.client(ts.write_key);
    std::string bad = slot_log_csv(1.0);
    const std::size_t at = bad.find("N20");
    bad.replace(at, 3, "N\x81" "20");
    require_error(upload(c, bad, slot_spec()), 400, "bad_log", "byte 0x81 is not a character");
    const json e = body(upload(c, bad, slot_spec()));
    const std::string line = std::to_string(1 + std::count(bad.begin(), bad.begin() + static_cast<std::ptrdiff_t>(at), '\n'));
    const std::string column = std::to_string(at + 2 - (bad.rfind('\n', at) + 1));
    CHECK_THAT(e["error"]["message"].get<std::string>(), Catch::StartsWith("slot.csv:" + line + ":" + column + ": "));

    std::string grouped = slot_log_csv(1.0);
    const std::size_t row = grouped.find("\n0.1,");
    REQUIRE(row != std::string::npos);
    const std::size_t x = grouped.find(',', row + 1) + 1;
    grouped.replace(x, grouped.find(',', x) - x, "1\xA0" "234.5");
    const json g = body(upload(c, grouped, slot_spec()));
    CHECK_THAT(g["error"]["message"].get<std::string>(),
               Catch::Contains("slot.csv:" + std::to_string(1 + std::count(grouped.begin(), grouped.begin() + static_cast<std::ptrdiff_t>(x), '\n')) + ":") &&
                   Catch::Contains("column 'x'") && Catch::Contains("no-break space inside it"));
    // A text part that is not text: 400 naming the part.
    require_error(upload(c, slot_log_csv(1.0), slot_spec(), {{"name", std::string("a\0b", 3), "", ""}}), 400, "bad_request",
                  "part name");
}

TEST_CASE("text: a dynamometer record with a Latin-1 header column is read, the column named decoded", "[text]") {
    TestServer ts;
    auto c = ts.client(ts.write_key);
    auto up = upload(c, slot_log_csv(1.0), slot_spec());
    REQUIRE(up->status == 202);
    const auto id = std::to_string(body(up)["id"].get<int>());
    REQUIRE(wait_finished(c, std::stoll(id))["state"] == "done");
    // 10 kHz, a force that is not zero (the comparison needs something to align).
    std::string dyno = "Time;Fx;Fy;Fz;Temperatur [\xB0" "C]\ns;N;N;N;\xB0" "C\n";
    for (int i = 0; i < 10000; ++i) {
        char row[96];
        std::snprintf(row, sizeof row, "%.4f;%.3f;%.3f;%.3f;21,5\n", i * 1e-4, 50 * std::sin(i * 0.21), 30 * std::cos(i * 0.21),
                      5.0);
        dyno += row;
    }
    const auto r = c.Post(("/api/v1/runs/" + id + "/measurement").c_str(),
                          httplib::MultipartFormDataItems{{"file", dyno, "Messung \xFC" "ber Nacht.csv", ""}});
    REQUIRE(r);
    INFO(r->body);
    REQUIRE(r->status == 201);
    const json report = json::parse(r->body)["report"];
    CHECK(report["measured"]["file"] == "Messung über Nacht.csv");
    REQUIRE(report["measured"]["ignored_channels"].size() == 1);
    CHECK(report["measured"]["ignored_channels"][0] == "Temperatur [°C]");
}

TEST_CASE("text: a controller export uploaded with a bundled map preset has its coarse data in the run", "[text]") {
    TestServer ts;
    auto c = ts.client(ts.write_key);
    const auto log = cutload::motion_io::test::umich_like_export(5);
    const auto up = upload(c, log.csv, slot_spec(), {{"mapping", "umich_cnc_mill", "", ""}});
    REQUIRE(up);
    INFO(up->body);
    REQUIRE(up->status == 202);
    const json run = wait_finished(c, body(up)["id"].get<std::int64_t>());
    CHECK(run["state"] == "done");
    const json& ingest = run["inputs"]["ingest"];
    CHECK(run["inputs"]["log"]["mapping_preset"] == "umich_cnc_mill");
    CHECK(ingest["data_quality"]["coarse"] == true);
    CHECK(ingest["data_quality"]["position_step_mm"] == 1.0);
    CHECK(ingest["data_quality"]["sample_period_s"].get<double>() == Approx(0.1));
    bool named = false;
    for (const auto& w : ingest["warnings"])
        named = named || (w["code"] == "position_quantized" && w["message"].get<std::string>().find("steps of 1 mm") != std::string::npos);
    CHECK(named);
}
