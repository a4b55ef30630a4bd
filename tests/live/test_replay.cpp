// The replay adapter: CSV logs as SHDR, pacing, time stamps, several clients, loops, bad input.
#include "live/replay.hpp"
#include "live/shdr_client.hpp"
#include "live_fixtures.hpp"
#include "motion_io/readings.hpp"

#include <catch2/catch.hpp>
#include <fmt/format.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>

using namespace cutload;
using namespace cutload::live;
using namespace cutload::live::test;

namespace {

std::string write_file(const std::string& name, const std::string& text) {
    const std::string p = temp_path(name);
    std::ofstream(p, std::ios::binary) << text;
    return p;
}

ReplayOptions loopback(const std::string& log, double speed) {
    ReplayOptions o;
    o.log = log;
    o.port = 0;
    o.speed = speed;
    return o;
}

std::unique_ptr<ShdrSource> client_of(const ReplayAdapter& a) {
    ShdrOptions o;
    o.host = "127.0.0.1";
    o.port = a.port();
    return std::make_unique<ShdrSource>(o);
}

// Checks one observation against the demo reading it must be: key, value, and time relative
// to the first reading (stamps keep the log's intervals to the nanosecond).
void check_reading(const Observation& o, std::int64_t first_ns, const DemoReading& r, double t0_s, std::size_t i) {
    INFO("reading " << i << ": " << o.key << "=" << o.value);
    REQUIRE(std::fabs((o.stamp_ns - first_ns) * 1e-9 - (r.t_s - t0_s)) < 2e-9);
    switch (r.kind) {
        case DemoReading::Spindle:
            REQUIRE(o.key == "spindle_speed");
            REQUIRE(std::stod(o.value) == r.v[0]);
            break;
        case DemoReading::Feed:
            REQUIRE(o.key == "path_feedrate");   // MTConnect's unit, mm/s
            REQUIRE(std::stod(o.value) * 60 == Approx(r.v[0]).epsilon(1e-13).margin(1e-12));
            break;
        case DemoReading::Pos: {
            REQUIRE(o.key == "path_pos");
            const auto v = numbers(o.value);
            REQUIRE(v.size() == 3);
            for (int k = 0; k < 3; ++k) REQUIRE(v[k] == r.v[k]);
            break;
        }
        case DemoReading::Block:
            REQUIRE(o.key == "block");
            REQUIRE(o.value == r.block);
            break;
    }
}

}  // namespace

TEST_CASE("a CSV log written as SHDR reads with cutload's SHDR reader and no map, channel for channel", "[replay]") {
    const std::string csv = source_path("data/demo_dryrun.csv");
    const std::string shdr = temp_path("demo_as_shdr.txt");
    std::FILE* f = std::fopen(shdr.c_str(), "wb");
    REQUIRE(f);
    const std::size_t lines = write_csv_as_shdr(csv, {}, f);
    std::fclose(f);
    const std::vector<DemoReading> expected = demo_readings();
    // Spindle, feed and position have their own stamps; the block shares the position's line.
    CHECK(lines == expected.size() / 4 * 3);

    motion_io::ReadOptions as_shdr;
    as_shdr.format = motion_io::Format::Shdr;
    const motion_io::IngestReport from_shdr = motion_io::inspect(shdr, as_shdr);
    const motion_io::IngestReport from_csv = motion_io::inspect(csv, {});
    CHECK(from_shdr.format == "shdr");
    for (const char* ch : {"pos", "feed", "spindle", "block"}) {
        INFO(ch);
        REQUIRE(from_shdr.channels.count(ch) == 1);
        CHECK(from_shdr.channels.at(ch).samples == from_csv.channels.at(ch).samples);
    }
    CHECK(from_shdr.duration_s == Approx(from_csv.duration_s).margin(1e-6));
    CHECK(from_shdr.blocks == from_csv.blocks);
    CHECK(from_shdr.feed_raw_max_mm_min == Approx(from_csv.feed_raw_max_mm_min).epsilon(1e-9));
    std::filesystem::remove(shdr);
}

TEST_CASE("a map file chooses the keys and units a CSV log is written under, and the same map reads it back", "[replay]") {
    const std::string csv = write_file("map_in.csv", "t [s],x [mm],y [mm],z [mm],feed [mm/min],spindle [rpm],block\n"
                                                     "0.004,25.400,-50.800,0.000,1524,-1200,N10\n"
                                                     "0.010,25.654,-50.800,0.000,1524,-1200,N20\n");
    const std::string map = write_file("map.json", R"({"position": [], "x": ["Xabs", "Xact"], "y": "Yabs", "z": "Zabs",
        "feed": "Fact", "spindle": "S1speed", "block": "line", "units": {"length": "in", "feed": "in/min"}})");
    motion_io::ReadOptions opt;
    opt.map_file = map;
    const std::string shdr = temp_path("map_out.txt");
    std::FILE* f = std::fopen(shdr.c_str(), "wb");
    write_csv_as_shdr(csv, opt, f);
    std::fclose(f);
    std::ifstream in(shdr);
    std::string first;
    std::getline(in, first);
    // 25.4 mm = 1 in, 1524 mm/min = 60 in/min, all readings of the row on one line (one stamp).
    CHECK(first == "1970-01-01T00:00:00.004Z|Xabs|1|Yabs|-2|Zabs|0|Fact|60|S1speed|-1200|line|N10");
    motion_io::ReadOptions back;
    back.format = motion_io::Format::Shdr;
    back.map_file = map;
    const motion_io::MotionModel m = motion_io::ingest(shdr, back);
    const motion_io::MotionModel ref = motion_io::ingest(csv, {});
    REQUIRE(m.size() > 2);
    CHECK(m.x_mm.front() == Approx(25.4));
    CHECK(m.x_mm.back() == Approx(ref.x_mm.back()));
    CHECK(m.block_names == ref.block_names);
    for (const auto& p : {csv, map, shdr}) std::filesystem::remove(p);
}

TEST_CASE("replay at 10x of the demo log takes ~1.5 s and delivers the file's samples: values and relative times", "[replay]") {
    const std::vector<DemoReading> expected = demo_readings();
    const double span_s = expected.back().t_s - expected.front().t_s;   // 14.879 s
    ReplayAdapter adapter(loopback(source_path("data/demo_dryrun.csv"), 10.0));
    CHECK(adapter.log_format() == motion_io::Format::Csv);
    CHECK(adapter.log_duration_s() == Approx(span_s).margin(1e-6));
    auto src = client_of(adapter);
    Collected c;
    const auto started = Clock::now();
    REQUIRE(collect(*src, c, [&](const Collected& x) { return x.observations.size() >= expected.size(); }, 20s));
    REQUIRE(c.observations.size() == expected.size());
    const double took_s = std::chrono::duration<double>(c.arrived.back() - c.arrived.front()).count();
    INFO("replay took " << took_s << " s for " << span_s << " s of log at 10x");
    // Paced: never faster than the stamps allow; slack above for a loaded machine.
    CHECK(took_s >= span_s / 10 * 0.98);
    CHECK(took_s <= span_s / 10 + 1.5);
    CHECK(c.count(EventKind::Connected) == 1);
    CHECK(c.count(EventKind::Warning) == 0);
    // Stamps shifted to now: the first is within a few seconds of the wall clock.
    const auto wall_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(WallClock::now().time_since_epoch()).count();
    CHECK(std::abs(c.observations.front().stamp_ns - wall_ns) < 30'000'000'000LL);
    for (std::size_t i = 0; i < expected.size(); ++i)
        check_reading(c.observations[i], c.observations.front().stamp_ns, expected[i], expected.front().t_s, i);
    // Pacing on the way: halfway through the log, about halfway through the time.
    const std::size_t mid = expected.size() / 2;
    const double mid_s = std::chrono::duration<double>(c.arrived[mid] - c.arrived.front()).count();
    CHECK(mid_s >= (expected[mid].t_s - expected.front().t_s) / 10 * 0.98 - 0.06);
    CHECK(adapter.wait_finished(2s));
    CHECK(adapter.stats().lines_sent == adapter.log_lines());
    (void)started;
}

TEST_CASE("a client joining mid-replay first gets the latest value of every key, then the same lines", "[replay]") {
    ReplayAdapter adapter(loopback(source_path("data/demo_dryrun.csv"), 20.0));
    ShdrOptions o;
    o.port = adapter.port();
    ShdrClient first(o), second(o);
    CollectedLines a, b;
    REQUIRE(collect_lines(first, a, [](const CollectedLines& x) { return x.lines.size() >= 500; }, 10s));
    REQUIRE(collect_lines(second, b, [](const CollectedLines& x) { return !x.lines.empty(); }, 5s));
    // The state line: one line holding every key, stamped like the last line sent.
    const std::string state = b.lines.front();
    for (const char* key : {"|path_pos|", "|path_feedrate|", "|spindle_speed|", "|block|"})
        CHECK(state.find(key) != std::string::npos);
    REQUIRE(adapter.wait_finished(10s));
    collect_lines(first, a, [](const CollectedLines&) { return false; }, 300ms);
    collect_lines(second, b, [](const CollectedLines&) { return false; }, 300ms);
    REQUIRE(a.lines.size() == adapter.log_lines());
    // After the state line the second client's lines are the tail of the first client's.
    const std::size_t tail = b.lines.size() - 1;
    REQUIRE(tail > 0);
    REQUIRE(tail < a.lines.size());
    for (std::size_t i = 0; i < tail; ++i) REQUIRE(b.lines[1 + i] == a.lines[a.lines.size() - tail + i]);
    CHECK(adapter.stats().clients_accepted == 2);
}

TEST_CASE("a looped replay keeps its time stamps increasing from pass to pass", "[replay]") {
    // 20 rows at an unequal 6 +- 1 ms, as the seed's client cycle.
    std::string csv = "t [ms],x,y,z\n";
    double t = 3;
    for (int i = 0; i < 20; ++i, t += 6 + (i % 3 - 1)) csv += fmt::format("{:.3f},{:.3f},0,0\n", t, i * 0.1);
    const std::string log = write_file("loop.csv", csv);
    ReplayOptions opt = loopback(log, 5.0);
    opt.loop = true;
    ReplayAdapter adapter(opt);
    auto src = client_of(adapter);
    Collected c;
    REQUIRE(collect(*src, c, [](const Collected& x) { return x.observations.size() >= 60; }, 10s));
    for (std::size_t i = 1; i < 60; ++i) REQUIRE(c.observations[i].stamp_ns > c.observations[i - 1].stamp_ns);
    // Within a pass the log's intervals; between passes at least 1 s.
    for (std::size_t i = 1; i < 20; ++i)
        CHECK(c.observations[i].stamp_ns - c.observations[i - 1].stamp_ns == c.observations[20 + i].stamp_ns -
                                                                                    c.observations[20 + i - 1].stamp_ns);
    CHECK(c.observations[20].stamp_ns - c.observations[19].stamp_ns >= 1'000'000'000);
    CHECK(c.observations[20].value == c.observations[0].value);
    CHECK(adapter.stats().passes_done >= 2);
    CHECK_FALSE(adapter.stats().finished);
    std::filesystem::remove(log);
}

TEST_CASE("a long silence in the log can be shortened for delivery while the stamps stay the log's", "[replay]") {
    const std::string log = write_file("pause.txt", "2022-08-08T10:00:00.000Z|Xact|1\n"
                                                    "2022-08-08T10:00:30.000Z|Xact|2\n"
                                                    "2022-08-08T10:00:30.250Z|Xact|3\n");
    ReplayOptions opt = loopback(log, 1.0);
    opt.max_pause_s = 0.4;   // 30 s -> 0.4 s; 0.25 s stays
    ReplayAdapter adapter(opt);
    CHECK(adapter.log_duration_s() == Approx(0.65));
    auto src = client_of(adapter);
    Collected c;
    REQUIRE(collect(*src, c, [](const Collected& x) { return x.observations.size() >= 3; }, 5s));
    CHECK(c.observations[1].stamp_ns - c.observations[0].stamp_ns == 30'000'000'000LL);
    const double took = std::chrono::duration<double>(c.arrived[2] - c.arrived[0]).count();
    CHECK(took >= 0.63);
    CHECK(took < 2.0);
    std::filesystem::remove(log);
}

TEST_CASE("bad logs and options are refused before the replay listens", "[replay]") {
    const std::string bad_stamp = write_file("bad_stamp.txt", "2022-08-08T10:00:00.000Z|Xact|1\n08/08/2022 10:00|Xact|2\n");
    CHECK_THROWS_WITH(ReplayAdapter(loopback(bad_stamp, 1)),
                      Catch::Contains("bad_stamp.txt:2") && Catch::Contains("not an ISO 8601 time stamp"));
    const std::string no_data = write_file("no_data.txt", "* shdrVersion: 2\n2022-08-08T10:00:00Z|system|NORMAL||||\n");
    CHECK_THROWS_WITH(ReplayAdapter(loopback(no_data, 1)), Catch::Contains("no data lines"));
    ReplayOptions mapped = loopback(bad_stamp, 1);
    mapped.read.map_file = "map.json";
    CHECK_THROWS_AS(ReplayAdapter(mapped), std::invalid_argument);
    CHECK_THROWS_AS(ReplayAdapter(loopback(source_path("data/demo_dryrun.csv"), 0)), std::invalid_argument);
    const std::string pipe_block = write_file("pipe_block.csv", "t,x,y,z,block\n0.1,1,2,3,N1|N2\n");
    CHECK_THROWS_WITH(ReplayAdapter(loopback(pipe_block, 1)), Catch::Contains("pipe_block.csv:2") && Catch::Contains("'|'"));
    CHECK_THROWS_AS(ReplayAdapter(loopback(temp_path("missing.csv"), 1)), motion_io::IngestError);
    // The port is taken.
    ReplayAdapter first(loopback(source_path("data/demo_dryrun.csv"), 1));
    ReplayOptions same = loopback(source_path("data/demo_dryrun.csv"), 1);
    same.port = first.port();
    same.host = "127.0.0.1";
    // SO_REUSEADDR does not let two listeners share a port.
    CHECK_THROWS_WITH(ReplayAdapter(same), Catch::Contains("cannot listen"));
    for (const auto& p : {bad_stamp, no_data, pipe_block}) std::filesystem::remove(p);
}

TEST_CASE("the Okuma adapter log replays line for line, each stamp shifted by one constant", "[replay][shared]") {
    ReplayOptions opt = loopback(okuma_log(), 2000.0);
    opt.max_pause_s = 0.5;   // the log holds a 2020 s silence between recordings
    ReplayAdapter adapter(opt);
    ShdrOptions o;
    o.port = adapter.port();
    ShdrClient client(o);
    CollectedLines got;
    REQUIRE(collect_lines(client, got, [&](const CollectedLines& x) { return x.lines.size() >= adapter.log_lines(); }, 30s));
    // The file's lines an adapter would send: no blank lines, no '*' protocol lines.
    std::ifstream in(okuma_log(), std::ios::binary);
    std::vector<std::string> file;
    std::string line;
    while (std::getline(in, line)) {
        while (!line.empty() && std::isspace(static_cast<unsigned char>(line.back()))) line.pop_back();
        if (!line.empty() && line.front() != '*') file.push_back(line);
    }
    REQUIRE(got.lines.size() == file.size());
    motion_io::ShdrLineTokenizer tok;
    std::optional<std::int64_t> offset;
    std::size_t stamped = 0;
    for (std::size_t i = 0; i < file.size(); ++i) {
        INFO("line " << i << ": " << file[i].substr(0, 80));
        const motion_io::ShdrLineKind kind = tok.next(file[i]);
        const auto bar = file[i].find('|');
        const auto stamp = bar == std::string::npos || kind == motion_io::ShdrLineKind::Body
                               ? std::nullopt : motion_io::parse_iso_time(file[i].substr(0, bar));
        if (!stamp) {
            REQUIRE(got.lines[i] == file[i]);
            continue;
        }
        const auto got_bar = got.lines[i].find('|');
        REQUIRE(got.lines[i].substr(got_bar) == file[i].substr(bar));
        const auto shifted = motion_io::parse_iso_time(got.lines[i].substr(0, got_bar));
        REQUIRE(shifted);
        if (!offset) offset = shifted->nanos() - stamp->nanos();
        REQUIRE(shifted->nanos() - stamp->nanos() == *offset);
        ++stamped;
    }
    CHECK(stamped > 10000);
}
