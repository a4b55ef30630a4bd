// `cutload replay` as a user runs it: the adapter it serves, and one-line errors for bad input.
#include "live/shdr_client.hpp"
#include "live_fixtures.hpp"

#include <catch2/catch.hpp>
#include <fmt/format.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sys/wait.h>

using namespace cutload::live;
using namespace cutload::live::test;

namespace {

struct Run {
    int exit_code = -1;
    std::string output;
};

Run run_cli(const std::string& args) {
    Run r;
    FILE* p = popen((std::string(CUTLOAD_BINARY) + " " + args + " 2>&1").c_str(), "r");
    REQUIRE(p);
    char buf[4096];
    while (std::fgets(buf, sizeof buf, p)) r.output += buf;
    const int status = pclose(p);
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return r;
}

}  // namespace

TEST_CASE("cutload replay serves the demo log to an SHDR client and exits at the end when asked", "[cli]") {
    FILE* p = popen((std::string(CUTLOAD_BINARY) + " replay " + source_path("data/demo_dryrun.csv") +
                     " --listen 127.0.0.1:0 --speed 50 --exit-at-end 2>&1").c_str(), "r");
    REQUIRE(p);
    char buf[4096];
    REQUIRE(std::fgets(buf, sizeof buf, p));
    const std::string first = buf;
    std::smatch m;
    REQUIRE(std::regex_search(first, m, std::regex(R"(\(csv, (\d+) lines, 14\.879 s at speed 50 = 0\.298 s\) as an SHDR adapter on 127\.0\.0\.1:(\d+))")));
    const std::size_t lines = std::stoul(m[1]);
    ShdrOptions o;
    o.port = std::stoi(m[2]);
    ShdrClient client(o);
    CollectedLines got;
    REQUIRE(collect_lines(client, got, [&](const CollectedLines& x) { return x.lines.size() >= lines; }, 20s));
    std::string rest;
    while (std::fgets(buf, sizeof buf, p)) rest += buf;
    const int status = pclose(p);
    CHECK(WIFEXITED(status));
    CHECK(WEXITSTATUS(status) == 0);
    CHECK(rest.find(fmt::format("end of log: {} lines sent, 1 client served", lines)) != std::string::npos);
    CHECK(got.lines.size() == lines);
}

TEST_CASE("cutload replay refuses bad input with one line and a non-zero exit", "[cli]") {
    const std::string demo = source_path("data/demo_dryrun.csv");
    struct Case {
        std::string args, says;
    };
    const std::string shdr = temp_path("cli_replay.txt");
    std::ofstream(shdr) << "2022-08-08T10:00:00Z|Xact|1\n";
    const std::vector<Case> cases{
        {"replay", "LOG is required"},
        {"replay " + demo + " --speed 0", "--speed"},
        {"replay " + demo + " --listen nohost", "--listen: 'nohost': no port"},
        {"replay " + demo + " --listen 127.0.0.1:http", "is not a port"},
        {"replay " + shdr + " --map map.json", "apply to CSV logs only"},
        {"replay " + shdr + " --units in", "apply to CSV logs only"},
        {"replay /nonexistent/log.csv", "/nonexistent/log.csv"},
    };
    for (const Case& c : cases) {
        INFO(c.args);
        const Run r = run_cli(c.args);
        INFO(r.output);
        CHECK(r.exit_code == 2);
        CHECK(r.output.find(c.says) != std::string::npos);
        CHECK(std::count(r.output.begin(), r.output.end(), '\n') == 1);
    }
    std::filesystem::remove(shdr);
}
