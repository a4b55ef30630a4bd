// The built `cutload inspect` / `cutload resample` on the demo log and on a bad file.
#include "test_helpers.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <array>
#include <cstdio>
#include <filesystem>
#include <sys/wait.h>

using namespace cutload::motion_io::test;

namespace {

struct Run {
    int exit_code = -1;
    std::string out;   // stdout and stderr together
};

Run run(const std::string& args) {
    Run r;
    const std::string cmd = std::string(CUTLOAD_BINARY) + " " + args + " 2>&1";
    std::FILE* p = popen(cmd.c_str(), "r");
    REQUIRE(p != nullptr);
    std::array<char, 4096> buf{};
    std::size_t n;
    while ((n = std::fread(buf.data(), 1, buf.size(), p)) > 0) r.out.append(buf.data(), n);
    const int status = pclose(p);
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return r;
}

}  // namespace

TEST_CASE("cli: inspect --json on the demo log has the documented keys", "[cli]") {
    const Run r = run("inspect " + source_path("data/demo_dryrun.csv") + " --json");
    REQUIRE(r.exit_code == 0);
    const auto j = nlohmann::json::parse(r.out);
    CHECK(j.at("duration_s").get<double>() > 10);
    CHECK(j.at("sessions").get<int>() == 1);
    CHECK(j.at("blocks").get<int>() > 20);
    CHECK(j.at("channels").at("pos").at("samples").get<int>() > 2000);
    CHECK(j.at("channels").at("pos").at("interval_s").at("median").get<double>() == Approx(0.006).epsilon(0.05));
    CHECK(j.at("channels").at("pos").at("update_period_s").get<double>() == Approx(0.004).epsilon(0.01));
    for (const char* k : {"min", "median", "max"}) CHECK(j.at("channels").at("spindle").at("interval_s").contains(k));
    CHECK(j.at("warnings").is_array());
}

TEST_CASE("cli: resample writes the uniform CSV with the documented header", "[cli]") {
    TempFile out("resampled.csv", {}, false);
    const Run r = run("resample " + source_path("data/demo_dryrun.csv") + " --step-ms 2 --out " + out.path());
    REQUIRE(r.exit_code == 0);
    std::ifstream in(out.path());
    std::string header, first;
    std::getline(in, header);
    std::getline(in, first);
    CHECK(header == "t_s,x_mm,y_mm,z_mm,feed_mm_min,spindle_rpm,spindle_angle_deg,block");
    CHECK(first.find(",N10") != std::string::npos);
    std::size_t rows = 1;
    for (std::string line; std::getline(in, line);) ++rows;
    CHECK(rows > 7000);   // about 15 s at 2 ms
}

TEST_CASE("cli: a bad log exits non-zero with one line and writes nothing", "[cli]") {
    TempFile bad("cli_bad.csv", "t,x,y,z\n0,1,2,3\n0.01,1,2,oops\n");
    TempFile out("cli_bad_out.csv", {}, false);
    const Run r = run("resample " + bad.path() + " --step-ms 1 --out " + out.path());
    CHECK(r.exit_code != 0);
    CHECK(r.out.find("cli_bad.csv:3") != std::string::npos);
    CHECK(r.out.find("'z'") != std::string::npos);
    CHECK(std::count(r.out.begin(), r.out.end(), '\n') == 1);
    CHECK_FALSE(std::filesystem::exists(out.path()));
    for (const auto& e : std::filesystem::directory_iterator(std::filesystem::temp_directory_path()))
        CHECK(e.path().filename().string().rfind("cutload_motion_test_cli_bad_out.csv.tmp", 0) != 0);

    const Run missing = run("inspect " + bad.path() + ".does-not-exist --json");
    CHECK(missing.exit_code != 0);
    CHECK(std::count(missing.out.begin(), missing.out.end(), '\n') == 1);
}
