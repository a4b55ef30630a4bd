// A run with a tool table through the service: the stored blocks and their flags name their tools,
// a tool the table lacks is flagged unknown_tool (and raises no run-limits alert), and a bad table
// is a 400 naming the entry's key.
#include "harness.hpp"

#include <map>

using namespace cutload::test;

namespace {

// A slot at 1200 mm/min, 2 mm deep: N10 cut by T1 (D8), N20 by T2 (D6), N30 by T7 (not in the
// table); every 2 ms, a tool column as a controller writes it.
std::string tool_log_csv() {
    std::ostringstream o;
    o << "t,x,y,z,feed,spindle,tool,block\n";
    const double v_mm_s = 1200 / 60.0;
    for (int i = 0; i < 1500; ++i) {
        const double t = i * 0.002;
        const int part = i / 500;
        o << t << ',' << -6.0 + v_mm_s * t << ",5,-2,1200,10000," << (part == 0 ? 1 : part == 1 ? 2 : 7) << ",N"
          << (part + 1) * 10 << '\n';
    }
    return o.str();
}

json tool_table_spec() {
    json spec = slot_spec();
    json t1 = tool_json(), t2 = tool_json();
    t1["number"] = 1;
    t2["number"] = 2;
    t2["diameter_mm"] = 6;
    t2["limits"] = {{"force_N", 5}};   // T2's own limit: trips; the run's (none) does not for T1
    spec.erase("tool");
    spec["tools"] = {t1, t2};
    return spec;
}

}  // namespace

TEST_CASE("runs: a tool table names each block's tool, flags name theirs, an unknown tool is flagged") {
    TestServer ts;
    auto c = ts.client(ts.write_key);
    auto r = upload(c, tool_log_csv(), tool_table_spec(), {{"name", "tools", "", ""}});
    REQUIRE(r->status == 202);
    const auto id = body(r)["id"].get<std::int64_t>();
    const json run = wait_finished(c, id);
    REQUIRE(run["state"] == "done");
    REQUIRE(run["inputs"]["spec"]["tools"].size() == 2);
    CHECK_FALSE(run["inputs"]["spec"].contains("tool"));

    const json blocks = body(c.Get(("/api/v1/runs/" + std::to_string(id) + "/blocks").c_str()));
    std::map<std::string, json> by_name;
    for (const auto& b : blocks["items"]) by_name[b["block"]] = b;
    REQUIRE(by_name.size() == 3);
    CHECK(by_name["N10"]["tool"] == 1);
    CHECK(by_name["N20"]["tool"] == 2);
    CHECK(by_name["N30"]["tool"] == 7);
    CHECK(by_name["N10"]["peak_force_N"].get<double>() > 10);
    CHECK(by_name["N20"]["peak_force_N"].get<double>() > 10);
    CHECK(by_name["N30"]["peak_force_N"] == 0);
    CHECK(by_name["N10"]["flags"].empty());
    auto flag = [](const json& b, const std::string& name) {
        for (const auto& f : b["flags"])
            if (f["flag"] == name) return f;
        return json();
    };
    CHECK(flag(by_name["N20"], "force_limit")["tool"] == 2);
    const json unknown = flag(by_name["N30"], "unknown_tool");
    REQUIRE(unknown.is_object());
    CHECK(unknown["tool"] == 7);
    CHECK(unknown["value"] == 7);

    // The run-limits alert is about N20's force limit only.
    const json alerts = body(c.Get(("/api/v1/alerts?run_id=" + std::to_string(id)).c_str()));
    REQUIRE(alerts["items"].size() == 1);
    const json& listed = alerts["items"][0]["blocks"];
    REQUIRE(listed.size() == 1);
    CHECK(listed[0]["block"] == "N20");
    CHECK(listed[0]["tool"] == 2);
}

TEST_CASE("runs: a bad tool table is a 400 naming the entry and key") {
    TestServer ts;
    auto c = ts.client(ts.write_key);
    json spec = tool_table_spec();
    spec["tools"][1]["number"] = 1;
    require_error(upload(c, tool_log_csv(), spec), 400, "bad_spec", "tools[1].number: T1 is already tools[0]");
    spec = tool_table_spec();
    spec["tools"][0]["flutes"] = 0;
    require_error(upload(c, tool_log_csv(), spec), 400, "bad_spec", "tools[0].flutes");
}

TEST_CASE("runs: a tool table naming library tools by tool_id gives the blocks of the same table inline") {
    TestServer ts;
    auto c = ts.admin();
    const json inline_spec = tool_table_spec();
    // The two tools of the inline table, stored in the library; T2's force limit is the library
    // tool's own here, so it reaches the table entry as that tool's limit.
    auto store = [&](const char* name, json tool, json limits) {
        tool.erase("number");
        tool.erase("limits");
        const json item{{"name", name}, {"tool", tool}, {"limits", limits}};
        auto r = c.Post("/api/v1/tools", item.dump(), "application/json");
        REQUIRE(r->status == 201);
        return body(r)["id"].get<std::int64_t>();
    };
    const std::int64_t d8 = store("D8 3-flute", inline_spec["tools"][0], json::object());
    const std::int64_t d6 = store("D6 slotting", inline_spec["tools"][1], {{"force_N", 5}, {"rapid_feed_mm_min", 15000}});
    json by_id = inline_spec;
    by_id["tools"] = {{{"number", 1}, {"tool_id", d8}}, {{"number", 2}, {"tool_id", d6}}};

    auto blocks_of = [&](const json& spec) {
        auto r = upload(c, tool_log_csv(), spec);
        REQUIRE(r->status == 202);
        const auto id = body(r)["id"].get<std::int64_t>();
        const json run = wait_finished(c, id);
        REQUIRE(run["state"] == "done");
        json blocks = body(c.Get(("/api/v1/runs/" + std::to_string(id) + "/blocks").c_str()))["items"];
        return std::make_pair(run["inputs"]["spec"], blocks);
    };
    const auto [spec_inline, blocks_inline] = blocks_of(inline_spec);
    const auto [spec_by_id, blocks_by_id] = blocks_of(by_id);
    // The stored spec is the resolved table, the same as written inline (the library's rapid feed
    // is the machine's and stays out of a tool's limits).
    CHECK(spec_by_id["tools"] == spec_inline["tools"]);
    REQUIRE(blocks_inline.size() == 3);
    REQUIRE(blocks_by_id.size() == blocks_inline.size());
    for (std::size_t b = 0; b < blocks_inline.size(); ++b) {
        INFO("block " << blocks_inline[b]["block"]);
        CHECK(blocks_by_id[b] == blocks_inline[b]);
    }
    CHECK(blocks_by_id[1]["peak_force_N"].get<double>() > 10);   // T2 cut, and tripped its library limit
    CHECK(blocks_by_id[1]["flags"].size() >= 1);

    // An entry's own limits win over the library tool's.
    json own = by_id;
    own["tools"][1]["limits"] = {{"force_N", 0}};
    const auto [spec_own, blocks_own] = blocks_of(own);
    CHECK(spec_own["tools"][1]["limits"]["force_N"] == 0);

    json unknown = by_id;
    unknown["tools"][1]["tool_id"] = 999;
    require_error(upload(c, tool_log_csv(), unknown), 404, "not_found", "tools[1].tool_id: no library tool has id 999");
    json both = by_id;
    both["tools"][0]["shape"] = "flat";
    require_error(upload(c, tool_log_csv(), both), 400, "bad_spec",
                  "tools[0].tool_id: give either the tool's fields or tool_id, not both (the entry has 'shape')");
    json text = by_id;
    text["tools"][0]["tool_id"] = "3";
    require_error(upload(c, tool_log_csv(), text), 400, "bad_spec", "tools[0].tool_id: must be an integer id");
}
