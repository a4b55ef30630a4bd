// Routes are declared once with typed parameters and the wrapper holds every request to its
// declaration; the store is reached only through db/'s repositories, so server/ holds no SQL.
#include "harness.hpp"
#include "server/core.hpp"
#include "server/route.hpp"

#include <regex>
#include <set>

using namespace cutload::test;
using cutload::server::Param;
using cutload::server::ParamIn;
using cutload::server::ParamType;

namespace {

std::vector<cutload::server::RouteSpec> declared_routes() {
    cutload::server::Core core{cutload::server::ServerOptions{}};
    cutload::server::add_all_routes(core);
    return core.routes;
}

// Values the declaration refuses, each with what the 400 must say.
std::vector<std::pair<std::string, std::string>> refused_values(const Param& p) {
    std::vector<std::pair<std::string, std::string>> v;
    switch (p.type) {
        case ParamType::Integer:
            v.emplace_back("12x", "is not an integer");
            if (p.minimum) v.emplace_back(std::to_string(static_cast<long long>(*p.minimum) - 1), "is outside");
            if (p.maximum) v.emplace_back(std::to_string(static_cast<long long>(*p.maximum) + 1), "is outside");
            break;
        case ParamType::Number: v.emplace_back("1.5s", "is not a number"); break;
        case ParamType::Boolean: v.emplace_back("maybe", "is not true or false"); break;
        case ParamType::String:
            if (!p.allowed.empty() || !p.pattern.empty()) v.emplace_back("no-such-value", "'no-such-value' is not");
            break;
    }
    return v;
}

}  // namespace

TEST_CASE("routes: every declared query parameter refuses a bad value with 400 naming it") {
    TestServer ts;
    auto c = ts.admin();
    std::size_t checked = 0;
    for (const auto& r : declared_routes()) {
        if (r.method != "GET") continue;   // only GET routes take query parameters
        const std::string path = std::regex_replace(r.path, std::regex(R"(\{id\})"), "1");
        for (const Param& p : r.params) {
            if (p.in != ParamIn::Query) continue;
            for (const auto& [value, says] : refused_values(p)) {
                const std::string url = path + "?" + p.name + "=" + value;
                INFO(url);
                require_error(c.Get(url.c_str()), 400, "bad_request", "query parameter " + p.name + ": ");
                require_error(c.Get(url.c_str()), 400, "bad_request", says);
                ++checked;
            }
        }
    }
    REQUIRE(checked > 40);
    // A path id is checked as declared too; text that is no id is no such resource.
    require_error(c.Get("/api/v1/runs/0"), 400, "bad_request", "path parameter id: 0 is below 1");
    require_error(c.Get("/api/v1/runs/99999999999999999999"), 400, "bad_request", "path parameter id");
    require_error(c.Get("/api/v1/runs/abc"), 404, "not_found");
    // Defaults apply when a parameter is not given: a page of the default size.
    REQUIRE(body(c.Get("/api/v1/runs"))["items"].is_array());
}

namespace {

// The string literals of C++ source, adjacent ones joined ("SELECT a " "FROM b" is one), comments
// and character literals skipped.
std::vector<std::string> string_literals(const std::string& src) {
    std::vector<std::string> out;
    bool joinable = false;   // only whitespace since the last literal ended
    std::size_t i = 0;
    auto add = [&](std::string lit) {
        if (joinable && !out.empty())
            out.back() += lit;
        else
            out.push_back(std::move(lit));
        joinable = true;
    };
    while (i < src.size()) {
        const char ch = src[i];
        if (src.compare(i, 2, "//") == 0) {
            i = src.find('\n', i);
            if (i == std::string::npos) break;
        } else if (src.compare(i, 2, "/*") == 0) {
            i = src.find("*/", i + 2);
            if (i == std::string::npos) break;
            i += 2;
        } else if (ch == 'R' && i + 1 < src.size() && src[i + 1] == '"' &&
                   (i == 0 || !std::isalnum(static_cast<unsigned char>(src[i - 1])))) {
            const std::size_t open = src.find('(', i + 2);
            const std::string close = ")" + src.substr(i + 2, open - i - 2) + "\"";
            const std::size_t end = src.find(close, open);
            add(src.substr(open + 1, end - open - 1));
            i = end + close.size();
            continue;
        } else if (ch == '"') {
            std::string lit;
            for (++i; i < src.size() && src[i] != '"'; ++i) {
                if (src[i] == '\\') ++i;
                lit += src[i];
            }
            ++i;
            add(std::move(lit));
            continue;
        } else if (ch == '\'' && (i == 0 || !std::isalnum(static_cast<unsigned char>(src[i - 1])))) {
            for (++i; i < src.size() && src[i] != '\''; ++i)
                if (src[i] == '\\') ++i;
            ++i;
            joinable = false;
            continue;
        } else if (!std::isspace(static_cast<unsigned char>(ch))) {
            joinable = false;
        }
        ++i;
    }
    return out;
}

// SQL as it would appear in a query string; prose in messages does not match.
bool looks_like_sql(const std::string& lit) {
    static const std::vector<std::regex> sql{
        std::regex(R"(\bselect\b[\s\S]*\bfrom\b)", std::regex::icase),
        std::regex(R"(\binsert\s+(or\s+\w+\s+)?into\b)", std::regex::icase),
        std::regex(R"(\bupdate\s+\S+\s+set\b)", std::regex::icase),
        std::regex(R"(\bdelete\s+from\b)", std::regex::icase),
        std::regex(R"(\b(create|alter|drop)\s+(table|index|view|trigger)\b)", std::regex::icase),
        std::regex(R"(\bpragma\b)", std::regex::icase),
        std::regex(R"(^\s*(begin(\s+\w+)?|commit|rollback(\s+to\s+\w+)?|savepoint\s+\w+|release\s+\w+)\s*;?\s*$)",
                   std::regex::icase),
        std::regex(R"((=|<|>|\bin\s*\()\s*\?\d*)"),   // placeholders
    };
    for (const auto& re : sql)
        if (std::regex_search(lit, re)) return true;
    return false;
}

std::string read_all(const fs::path& p) {
    std::ifstream in(p);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

}  // namespace

TEST_CASE("routes: server/ holds no SQL and db's public headers no SQLite") {
    // The scanner itself: it finds SQL in the shapes the store used to be written in, and passes
    // the prose of messages.
    const std::string planted = R"cpp(
        auto a = c.prepare("SELECT id, name FROM runs WHERE id = ?");   // "INSERT INTO x" in a comment
        auto b = fmt::format("UPDATE {} SET state = 'queued' "
                             "WHERE id = ?1", table);
        c.exec("BEGIN IMMEDIATE");
        /* "DELETE FROM runs" */ const char* d = R"SQL(
          CREATE TABLE t (id INTEGER PRIMARY KEY);
        )SQL";
        const char* e = "PRAGMA user_version";
        const char ch = '"';
        const char* f = "delete from alerts where run_id = ?";
    )cpp";
    std::size_t found = 0;
    for (const auto& lit : string_literals(planted)) found += looks_like_sql(lit) ? 1 : 0;
    REQUIRE(found == 6);
    for (const char* prose : {"run 3 is running: cancel it first (POST /api/v1/runs/3/cancel)",
                              "select the channels with channels=a,b", "give either tool or tool_id, not both",
                              "query parameter limit: 0 is outside 1..1000", "the job is begun", "commit message"})
        REQUIRE_FALSE(looks_like_sql(prose));

    const fs::path root = CUTLOAD_SOURCE_DIR;
    std::size_t files = 0, literals = 0;
    for (const auto& e : fs::directory_iterator(root / "server")) {
        const auto ext = e.path().extension();
        if (ext != ".cpp" && ext != ".hpp") continue;
        ++files;
        const std::string src = read_all(e.path());
        for (const auto& lit : string_literals(src)) {
            ++literals;
            INFO(e.path().filename().string() << ": \"" << lit << "\"");
            REQUIRE_FALSE(looks_like_sql(lit));
        }
        INFO(e.path().filename().string());
        REQUIRE(src.find("sqlite") == std::string::npos);
        REQUIRE(src.find("db::Connection") == std::string::npos);
    }
    REQUIRE(files > 20);
    REQUIRE(literals > 500);

    // db's public headers: no backend types, no SQL.
    std::smatch m;
    const std::string cmake = read_all(root / "db" / "CMakeLists.txt");
    REQUIRE(std::regex_search(cmake, m, std::regex(R"(PUBLIC_HEADERS([^\n]+))")));
    std::stringstream list(m[1].str());
    std::size_t headers = 0;
    for (std::string h; list >> h; ++headers) {
        const std::string src = read_all(root / "db" / h);
        INFO(h);
        REQUIRE(!src.empty());
        std::string code;   // without comments, which may name the backend
        for (std::size_t i = 0; i < src.size(); ++i) {
            if (src.compare(i, 2, "//") == 0) i = src.find('\n', i);
            if (i == std::string::npos) break;
            code += src[i];
        }
        for (const char* word : {"sqlite", "SQLite", "Stmt", "Connection"}) REQUIRE(code.find(word) == std::string::npos);
        for (const auto& lit : string_literals(src)) REQUIRE_FALSE(looks_like_sql(lit));
    }
    REQUIRE(headers >= 7);
}
