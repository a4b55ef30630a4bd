// The SHDR client on real loopback sockets: lines in order, heartbeat, dead connections,
// reconnection with backoff and the gap it reports, malformed input.
#include "live/replay.hpp"
#include "live/shdr_client.hpp"
#include "live_fixtures.hpp"

#include <catch2/catch.hpp>
#include <fmt/format.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

using namespace cutload;
using namespace cutload::live;
using namespace cutload::live::test;

namespace {

ReplayOptions replay_of(const std::string& log, double speed, int port = 0) {
    ReplayOptions o;
    o.log = log;
    o.port = port;
    o.speed = speed;
    return o;
}

double seconds(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double>(b - a).count(); }

}  // namespace

TEST_CASE("the SHDR client receives every line of a replayed log in order", "[shdr]") {
    // The demo log as the replay sends it, written out here to compare with.
    const std::string shdr = temp_path("lines.txt");
    std::FILE* f = std::fopen(shdr.c_str(), "wb");
    REQUIRE(f);
    const std::size_t n = write_csv_as_shdr(source_path("data/demo_dryrun.csv"), {}, f);
    std::fclose(f);
    ReplayAdapter adapter(replay_of(shdr, 50.0));
    REQUIRE(adapter.log_lines() == n);
    ShdrOptions o;
    o.port = adapter.port();
    ShdrClient client(o);
    CollectedLines got;
    REQUIRE(collect_lines(client, got, [&](const CollectedLines& x) { return x.lines.size() >= n; }, 20s));
    REQUIRE(got.lines.size() == n);
    std::ifstream in(shdr);
    std::string line;
    std::optional<std::int64_t> offset;
    for (std::size_t i = 0; i < n; ++i) {
        REQUIRE(std::getline(in, line));
        const auto bar = line.find('|');
        const auto got_bar = got.lines[i].find('|');
        REQUIRE(got.lines[i].substr(got_bar) == line.substr(bar));
        const std::int64_t shift = motion_io::parse_iso_time(got.lines[i].substr(0, got_bar))->nanos() -
                                   motion_io::parse_iso_time(line.substr(0, bar))->nanos();
        if (!offset) offset = shift;
        REQUIRE(shift == *offset);
    }
    REQUIRE(got.events.size() == 1);
    CHECK(got.events[0].event.kind == EventKind::Connected);
    std::filesystem::remove(shdr);
}

TEST_CASE("the heartbeat is agreed by PING/PONG and keeps a quiet connection alive", "[shdr]") {
    const std::string log = temp_path("hb.txt");
    std::ofstream(log) << "2022-08-08T10:00:00.000Z|Xact|1\n";
    ReplayOptions ro = replay_of(log, 1.0);
    ro.heartbeat = 250ms;
    ReplayAdapter adapter(ro);
    ShdrOptions o;
    o.port = adapter.port();
    ShdrClient client(o);
    CollectedLines got;
    // 1.5 s with a single line: only the heartbeat keeps the connection (dead after 500 ms).
    collect_lines(client, got, [](const CollectedLines&) { return false; }, 1500ms);
    REQUIRE(client.heartbeat());
    CHECK(client.heartbeat()->count() == 250);
    CHECK(client.connected());
    CHECK(got.lines.size() == 1);
    REQUIRE(got.events.size() == 1);
    CHECK(got.events[0].event.kind == EventKind::Connected);
    // One PING on connecting, then one every 250 ms: about 7 in 1.5 s.
    CHECK(client.pings_sent() >= 5);
    CHECK(client.pings_sent() <= 8);
    CHECK(adapter.stats().pings_answered >= client.pongs_received());
    CHECK(client.pongs_received() >= client.pings_sent() - 2);
    std::filesystem::remove(log);
}

TEST_CASE("a connection with nothing received for twice the heartbeat is dead and dropped", "[shdr]") {
    // Answers the first PING with a 100 ms heartbeat, then never says anything again.
    ScriptedAdapter silent([](int fd, const std::atomic<bool>& stop) {
        std::string line;
        if (!read_line(fd, line, stop) || line != "* PING") return;
        send_text(fd, "* PONG 100\n2022-08-08T10:00:00.000Z|Xact|1\n");
        while (read_line(fd, line, stop)) {
        }
    });
    ShdrOptions o;
    o.port = silent.port();
    o.backoff.initial = 10s;   // no second attempt within the test
    ShdrClient client(o);
    CollectedLines got;
    REQUIRE(collect_lines(client, got, [](const CollectedLines& x) {
        return !x.events.empty() && x.events.back().event.kind == EventKind::Disconnected;
    }, 5s));
    REQUIRE(got.events.size() == 2);
    const double dead_after = seconds(got.events[0].seen, got.events[1].seen);
    INFO(got.events[1].event.message);
    CHECK(dead_after >= 0.19);
    CHECK(dead_after < 1.0);
    CHECK(got.events[1].event.message.find("twice the 100 ms heartbeat") != std::string::npos);
    CHECK(got.events[1].event.retry_in == 10s);
    CHECK(got.lines == std::vector<std::string>{"2022-08-08T10:00:00.000Z|Xact|1"});
}

TEST_CASE("an adapter killed mid-stream and restarted: reconnection with backoff, the gap reported", "[shdr]") {
    const std::string csv = source_path("data/demo_dryrun.csv");
    ReplayOptions ro = replay_of(csv, 1.0);
    ro.loop = true;
    auto adapter = std::make_unique<ReplayAdapter>(ro);
    const int port = adapter->port();
    ShdrOptions o;
    o.port = port;
    o.backoff.initial = 50ms;
    o.backoff.max = 200ms;
    ShdrSource src(o);
    Collected c;
    REQUIRE(collect(src, c, [](const Collected& x) { return x.observations.size() >= 100; }, 10s));
    const auto killed = Clock::now();
    adapter.reset();   // the adapter process dies: its sockets close
    REQUIRE(collect(src, c, [](const Collected& x) { return x.count(EventKind::ConnectFailed) >= 4; }, 10s));
    // What was in flight when it died has been read by now; nothing comes while it is down.
    const std::int64_t last_before = c.observations.back().stamp_ns;
    const auto restarted = Clock::now();
    adapter = std::make_unique<ReplayAdapter>(replay_of(csv, 1.0, port));
    const std::size_t before = c.observations.size();
    REQUIRE(collect(src, c, [&](const Collected& x) { return x.observations.size() >= before + 100; }, 10s));

    // Disconnected, then failed attempts with doubling delays capped at 200 ms, then the
    // connection and its gap.
    std::vector<const Timed*> ev;
    for (const Timed& t : c.events) ev.push_back(&t);
    REQUIRE(ev.size() >= 7);
    CHECK(ev[0]->event.kind == EventKind::Connected);
    CHECK(ev[1]->event.kind == EventKind::Disconnected);
    CHECK(ev[1]->event.retry_in == 50ms);
    const std::vector<std::chrono::milliseconds> expected_retry{100ms, 200ms, 200ms};
    for (std::size_t i = 0; i < expected_retry.size(); ++i) {
        INFO("attempt " << i + 1);
        REQUIRE(ev[2 + i]->event.kind == EventKind::ConnectFailed);
        CHECK(ev[2 + i]->event.retry_in == expected_retry[i]);
        // The attempt waited for the previous retry_in.
        CHECK(seconds(ev[1 + i]->seen, ev[2 + i]->seen) >=
              std::chrono::duration<double>(ev[1 + i]->event.retry_in).count() * 0.9);
    }
    const auto connected = std::find_if(ev.begin() + 2, ev.end(), [](const Timed* t) { return t->event.kind == EventKind::Connected; });
    REQUIRE(connected != ev.end());
    REQUIRE(connected + 1 != ev.end());
    const SourceEvent& gap = (*(connected + 1))->event;
    REQUIRE(gap.kind == EventKind::Gap);
    const double outage = seconds(killed, (*connected)->seen);
    INFO(gap.message);
    CHECK(gap.gap_s >= seconds(killed, restarted) - 0.05);
    CHECK(gap.gap_s <= outage + 0.1);
    CHECK(gap.last_stamp_ns == last_before);
    // Data flows again from the new adapter, stamped later than before.
    CHECK(c.observations.back().stamp_ns > last_before);
}

TEST_CASE("with no adapter listening the attempts back off exponentially up to the cap", "[shdr]") {
    int port = 0;
    {
        // A port that was free a moment ago and is closed now.
        ScriptedAdapter probe([](int, const std::atomic<bool>&) {});
        port = probe.port();
    }
    ShdrOptions o;
    o.port = port;
    o.backoff.initial = 20ms;
    o.backoff.max = 160ms;
    ShdrClient client(o);
    CollectedLines got;
    REQUIRE(collect_lines(client, got, [](const CollectedLines& x) { return x.events.size() >= 6; }, 10s));
    const std::vector<long> expected{20, 40, 80, 160, 160, 160};
    for (std::size_t i = 0; i < expected.size(); ++i) {
        INFO(got.events[i].event.message);
        REQUIRE(got.events[i].event.kind == EventKind::ConnectFailed);
        CHECK(got.events[i].event.retry_in.count() == expected[i]);
    }
    CHECK_FALSE(client.connected());
}

TEST_CASE("data lines become observations, conditions, assets and protocol lines are skipped, bad lines warn", "[shdr]") {
    ScriptedAdapter adapter([](int fd, const std::atomic<bool>& stop) {
        std::string line;
        read_line(fd, line, stop);   // the PING
        send_text(fd, "* PONG 5000\r\n"
                      "* shdrVersion: 2\n"
                      "2022-08-08T13:51:34.7167146Z|X1actw|1039.897|p1LPathPos|1039.897 0 269.0133\r\n"
                      "2022-08-08T13:51:34.7167146Z|system|NORMAL||||\n"
                      "2022-08-08T13:43:36.0810790Z|@ASSET@|123456.2201|CuttingTool|--multiline--ABCD\n"
                      "<CuttingTool toolId=\"123456\">|not|data|</CuttingTool>\n"
                      "--multiline--ABCD\n"
                      "\n"
                      "garbage\n"
                      "08/08/2022 13:51|X1actw|1\n"
                      "2022-08-08T13:51:35.0000000Z|S6speed|UNAVAILABLE|X1actw|1040.5|Z1actw\n"
                      "2022-08-08T13:51:35.2500000Z|X1actw|1041.");
        send_text(fd, "5\n");   // a line split across two reads
        while (read_line(fd, line, stop)) {
        }
    });
    ShdrOptions o;
    o.port = adapter.port();
    ShdrSource src(o);
    Collected c;
    REQUIRE(collect(src, c, [](const Collected& x) { return x.observations.size() >= 5; }, 5s));
    collect(src, c, [](const Collected&) { return false; }, 200ms);
    REQUIRE(c.observations.size() == 5);
    CHECK(c.observations[0].key == "X1actw");
    CHECK(c.observations[0].stamp_ns == 1659966694716714600);
    CHECK(c.observations[1].value == "1039.897 0 269.0133");
    CHECK(c.observations[2].key == "S6speed");
    CHECK(c.observations[2].value == "UNAVAILABLE");   // kept: the consumer holds the last value
    CHECK(c.observations[3].value == "1040.5");
    CHECK(c.observations[4].value == "1041.5");
    CHECK(c.observations[4].stamp_ns == 1659966695250000000);
    // garbage (short), the bad stamp, the key without a value.
    CHECK(c.count(EventKind::Warning) == 3);
    REQUIRE(src.client().heartbeat());
    CHECK(src.client().heartbeat()->count() == 5000);
}

TEST_CASE("a line longer than the limit is skipped with a warning and the stream goes on", "[shdr]") {
    ScriptedAdapter adapter([](int fd, const std::atomic<bool>& stop) {
        std::string line;
        read_line(fd, line, stop);
        send_text(fd, "2022-08-08T13:51:34Z|a|1\n2022-08-08T13:51:34Z|b|" + std::string(5000, 'x') + "\n2022-08-08T13:51:35Z|c|3\n");
        while (read_line(fd, line, stop)) {
        }
    });
    ShdrOptions o;
    o.port = adapter.port();
    o.max_line_bytes = 1000;
    ShdrSource src(o);
    Collected c;
    REQUIRE(collect(src, c, [](const Collected& x) { return x.observations.size() >= 2; }, 5s));
    CHECK(c.observations[0].key == "a");
    CHECK(c.observations[1].key == "c");
    CHECK(c.count(EventKind::Warning) == 1);
}

TEST_CASE("source addresses are checked: shdr://host[:port], http(s)://host[:port]/device", "[shdr]") {
    CHECK(open_source("shdr://127.0.0.1")->describe() == "shdr://127.0.0.1:7878");
    CHECK(open_source("shdr://[::1]:7000/")->describe() == "shdr://::1:7000");
    CHECK(open_source("http://127.0.0.1:1/OKUMA")->describe() == "http://127.0.0.1:1/OKUMA");
    CHECK_THROWS_WITH(open_source("shdr://host:99999"), Catch::Contains("not a port"));
    CHECK_THROWS_WITH(open_source("ftp://host"), Catch::Contains("expected shdr://"));
    CHECK(parse_host_port("10.0.0.5:7878").port == 7878);
    CHECK_THROWS_WITH(parse_host_port("10.0.0.5"), Catch::Contains("no port"));
}

TEST_CASE("a stream of garbage gives 20 warnings and one saying the rest are not reported", "[shdr]") {
    ScriptedAdapter adapter([](int fd, const std::atomic<bool>& stop) {
        std::string line;
        read_line(fd, line, stop);
        std::string junk;
        for (int i = 0; i < 50; ++i) junk += "no pipes here " + std::to_string(i) + "\n";
        send_text(fd, junk + "2022-08-08T13:51:35Z|c|3\n");
        while (read_line(fd, line, stop)) {
        }
    });
    ShdrOptions o;
    o.port = adapter.port();
    ShdrSource src(o);
    Collected c;
    REQUIRE(collect(src, c, [](const Collected& x) { return !x.observations.empty(); }, 5s));
    collect(src, c, [](const Collected&) { return false; }, 100ms);
    REQUIRE(c.count(EventKind::Warning) == 21);
    CHECK(c.events.back().event.message == "more warnings on this connection are not reported");
    CHECK(c.events[1].event.message.find("no pipes here 0") != std::string::npos);
    CHECK(c.observations.size() == 1);
}
