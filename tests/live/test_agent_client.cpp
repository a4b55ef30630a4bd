// The MTConnect agent client against the test agent (agent_fixture.hpp) on loopback: following
// nextSequence, OUT_OF_RANGE and the gap, agent restarts, an agent that goes away and comes back;
// and the documents of a real agent (the Okuma demo's Devices.xml).
#include "live/agent_client.hpp"
#include "agent_fixture.hpp"
#include "live_fixtures.hpp"
#include "motion_io/readings.hpp"

#include <catch2/catch.hpp>

#include <fstream>
#include <sstream>

using namespace cutload;
using namespace cutload::live;
using namespace cutload::live::test;

namespace {

// The demo log's readings as agent observations: data item ids differ from their names, so the
// client must key them by the probe's names.
std::vector<AgentFixture::Item> demo_items() {
    return {{"p1pos", "path_pos", "SAMPLE", "PATH_POSITION", "MILLIMETER_3D"},
            {"p1feed", "path_feedrate", "SAMPLE", "PATH_FEEDRATE", "MILLIMETER/SECOND"},
            {"s1speed", "spindle_speed", "SAMPLE", "ROTARY_VELOCITY", "REVOLUTION/MINUTE"},
            {"p1block", "block", "EVENT", "BLOCK", ""}};
}

struct Obs {
    std::string id, value;
    std::int64_t stamp_ns;
};

std::vector<Obs> demo_observations() {
    std::vector<Obs> out;
    const std::int64_t base = 1'767'225'600'000'000'000;   // 2026-01-01T00:00:00Z
    for (const DemoReading& r : demo_readings()) {
        const std::int64_t ns = base + std::llround(r.t_s * 1e9);
        switch (r.kind) {
            case DemoReading::Pos: out.push_back({"p1pos", fmt::format("{} {} {}", r.v[0], r.v[1], r.v[2]), ns}); break;
            case DemoReading::Feed: out.push_back({"p1feed", fmt::format("{}", r.v[0] / 60), ns}); break;
            case DemoReading::Spindle: out.push_back({"s1speed", fmt::format("{}", r.v[0]), ns}); break;
            case DemoReading::Block: out.push_back({"p1block", r.block, ns}); break;
        }
    }
    return out;
}

const std::map<std::string, std::string> kKeyOf{
    {"p1pos", "path_pos"}, {"p1feed", "path_feedrate"}, {"s1speed", "spindle_speed"}, {"p1block", "block"}};

// Publishes obs[from, to) in bursts of `burst` every `every`, on its own thread.
class Publisher {
public:
    Publisher(AgentFixture& agent, const std::vector<Obs>& obs, std::size_t from, std::size_t to, std::size_t burst,
              std::chrono::milliseconds every)
        : thread_([&agent, &obs, from, to, burst, every] {
              for (std::size_t i = from; i < to; ++i) {
                  agent.publish(obs[i].id, obs[i].stamp_ns, obs[i].value);
                  if ((i - from + 1) % burst == 0) std::this_thread::sleep_for(every);
              }
          }) {}
    ~Publisher() { join(); }
    void join() {
        if (thread_.joinable()) thread_.join();
    }

private:
    std::thread thread_;
};

AgentOptions options_for(const AgentFixture& agent, AgentOptions::Mode mode) {
    AgentOptions o;
    o.base_url = agent.url();
    o.device = "mill";
    o.mode = mode;
    o.count = 50;   // many documents for the client to follow
    o.interval = 2ms;
    o.heartbeat = 200ms;
    o.poll_interval = 10ms;
    o.request_timeout = 2000ms;
    o.backoff.initial = 50ms;
    o.backoff.max = 200ms;
    return o;
}

// Every observation after the initial snapshot, checked against what was published: the same
// values under the probe's names, sequences one after another.
void check_follows(const Collected& c, std::size_t snapshot, const std::vector<Obs>& obs, std::size_t from,
                   std::size_t to, std::uint64_t first_sequence) {
    REQUIRE(c.observations.size() == snapshot + (to - from));
    for (std::size_t i = from; i < to; ++i) {
        const Observation& o = c.observations[snapshot + i - from];
        INFO("observation " << i);
        REQUIRE(o.sequence == first_sequence + (i - from));
        REQUIRE(o.key == kKeyOf.at(obs[i].id));
        REQUIRE(o.value == obs[i].value);
        REQUIRE(o.stamp_ns == obs[i].stamp_ns);
    }
}

}  // namespace

TEST_CASE("the agent client follows nextSequence through every document, polled and streamed", "[agent]") {
    const auto mode = GENERATE(AgentOptions::Mode::Poll, AgentOptions::Mode::Stream);
    INFO((mode == AgentOptions::Mode::Poll ? "poll" : "stream"));
    const std::vector<Obs> obs = demo_observations();
    AgentFixture agent(demo_items(), "mill", 100000);
    // Some state before the client comes: it arrives as the /current snapshot.
    for (std::size_t i = 0; i < 8; ++i) agent.publish(obs[i].id, obs[i].stamp_ns, obs[i].value);
    AgentSource src(options_for(agent, mode));
    Collected c;
    REQUIRE(collect(src, c, [](const Collected& x) { return x.count(EventKind::Connected) == 1; }, 5s));
    REQUIRE(collect(src, c, [](const Collected& x) { return x.observations.size() >= 4; }, 5s));
    const std::size_t snapshot = c.observations.size();
    CHECK(snapshot == 4);   // the latest value of each of the four items
    Publisher pub(agent, obs, 8, obs.size(), 200, 5ms);
    REQUIRE(collect(src, c, [&](const Collected& x) { return x.observations.size() >= snapshot + obs.size() - 8; }, 30s));
    pub.join();
    collect(src, c, [](const Collected&) { return false; }, 100ms);   // nothing more may come
    check_follows(c, snapshot, obs, 8, obs.size(), 9);
    CHECK(c.count(EventKind::Gap) == 0);
    CHECK(c.count(EventKind::Warning) == 0);
    CHECK(src.next_sequence() == agent.next_sequence());
    CHECK(agent.requests("probe") == 1);
    if (mode == AgentOptions::Mode::Poll) CHECK(agent.requests("sample") > (obs.size() - 8) / 50);
    else CHECK(agent.requests("stream") == 1);   // one long response carried it all
    // Units for the key map come from the probe.
    const auto items = src.data_items();
    const auto feed = std::find_if(items.begin(), items.end(), [](const DataItemInfo& d) { return d.key() == "path_feedrate"; });
    REQUIRE(feed != items.end());
    CHECK(feed->units == "MILLIMETER/SECOND");
}

TEST_CASE("after OUT_OF_RANGE the client marks the lost sequences and resynchronises from /current", "[agent]") {
    const auto mode = GENERATE(AgentOptions::Mode::Poll, AgentOptions::Mode::Stream);
    INFO((mode == AgentOptions::Mode::Poll ? "poll" : "stream"));
    const std::vector<Obs> obs = demo_observations();
    AgentFixture agent(demo_items(), "mill", 100000);
    AgentSource src(options_for(agent, mode));
    Collected c;
    REQUIRE(collect(src, c, [](const Collected& x) { return x.count(EventKind::Connected) == 1; }, 5s));
    Publisher(agent, obs, 0, 1000, 100, 2ms).join();
    REQUIRE(collect(src, c, [](const Collected& x) { return x.observations.size() >= 1000; }, 10s));
    REQUIRE(src.next_sequence() == 1001);
    // The client's next request waits while 1000 more arrive and the first 1500 are overrun.
    agent.hold_samples(true);
    for (int i = 0; i < 200 && agent.held_requests() == 0; ++i) std::this_thread::sleep_for(5ms);
    REQUIRE(agent.held_requests() == 1);
    Publisher(agent, obs, 1000, 2000, 1000, 0ms).join();
    agent.discard_through(1500);
    const std::int64_t last_stamp = c.observations.back().stamp_ns;
    agent.hold_samples(false);
    REQUIRE(collect(src, c, [](const Collected& x) { return x.count(EventKind::Gap) == 1; }, 10s));
    const SourceEvent& gap = *c.first(EventKind::Gap);
    INFO(gap.message);
    CHECK(gap.lost_from_sequence == 1001);
    CHECK(gap.lost_to_sequence == 2001);   // all that /current's nextSequence says was missed
    CHECK(gap.last_stamp_ns == last_stamp);
    // Then the snapshot (latest values) and everything published after it, in order.
    const std::size_t before = c.observations.size();
    REQUIRE(collect(src, c, [&](const Collected& x) { return x.observations.size() >= before + 4; }, 5s));
    for (std::size_t i = before; i < before + 4; ++i) CHECK(c.observations[i].sequence <= 2000);
    Publisher(agent, obs, 2000, 3000, 100, 2ms).join();
    REQUIRE(collect(src, c, [&](const Collected& x) { return x.observations.size() >= before + 4 + 1000; }, 10s));
    for (std::size_t i = 0; i < 1000; ++i) {
        const Observation& o = c.observations[before + 4 + i];
        REQUIRE(o.sequence == 2001 + i);
        REQUIRE(o.value == obs[2000 + i].value);
    }
    CHECK(c.count(EventKind::Restarted) == 0);
}

TEST_CASE("an agent restart (new instanceId) is reported, probed again and followed from the new sequences", "[agent]") {
    const auto mode = GENERATE(AgentOptions::Mode::Poll, AgentOptions::Mode::Stream);
    INFO((mode == AgentOptions::Mode::Poll ? "poll" : "stream"));
    const std::vector<Obs> obs = demo_observations();
    AgentFixture agent(demo_items(), "mill", 100000);
    AgentSource src(options_for(agent, mode));
    Collected c;
    REQUIRE(collect(src, c, [](const Collected& x) { return x.count(EventKind::Connected) == 1; }, 5s));
    const std::uint64_t old_instance = src.instance_id();
    Publisher(agent, obs, 0, 500, 100, 2ms).join();
    REQUIRE(collect(src, c, [](const Collected& x) { return x.observations.size() >= 500; }, 10s));
    agent.hold_samples(true);
    for (int i = 0; i < 200 && agent.held_requests() == 0; ++i) std::this_thread::sleep_for(5ms);
    agent.restart();
    // The new process numbers from 1 again; 1000 observations make the old `from` (501) valid.
    Publisher(agent, obs, 500, 1500, 1000, 0ms).join();
    agent.hold_samples(false);
    REQUIRE(collect(src, c, [](const Collected& x) { return x.count(EventKind::Restarted) == 1; }, 10s));
    REQUIRE(collect(src, c, [&](const Collected& x) { return x.observations.size() >= 500 + 4; }, 10s));
    CHECK(src.instance_id() == agent.instance_id());
    CHECK(src.instance_id() != old_instance);
    CHECK(agent.requests("probe") == 2);
    CHECK(c.count(EventKind::Gap) == 1);
    const std::size_t before = 504;   // the new instance's snapshot: the latest of the four items
    CHECK(c.observations[500].sequence >= 997);
    Publisher(agent, obs, 1500, 1600, 100, 0ms).join();
    REQUIRE(collect(src, c, [&](const Collected& x) { return x.observations.size() >= before + 100; }, 10s));
    for (std::size_t i = 0; i < 100; ++i) REQUIRE(c.observations[before + i].sequence == 1001 + i);
}

TEST_CASE("an agent that goes away and comes back is resumed at the same sequence without a gap", "[agent]") {
    const std::vector<Obs> obs = demo_observations();
    AgentFixture agent(demo_items(), "mill", 100000);
    AgentSource src(options_for(agent, AgentOptions::Mode::Stream));
    Collected c;
    REQUIRE(collect(src, c, [](const Collected& x) { return x.count(EventKind::Connected) == 1; }, 5s));
    Publisher(agent, obs, 0, 300, 100, 2ms).join();
    REQUIRE(collect(src, c, [](const Collected& x) { return x.observations.size() >= 300; }, 10s));
    const int port = agent.port();
    agent.stop_listening();
    REQUIRE(collect(src, c, [](const Collected& x) { return x.count(EventKind::ConnectFailed) >= 2; }, 10s));
    // One Disconnected, or two when a kept-alive connection to the stopping server still answered.
    CHECK(c.count(EventKind::Disconnected) >= 1);
    // Published while unreachable: still in the agent's buffer.
    Publisher(agent, obs, 300, 600, 300, 0ms).join();
    agent.start_listening(port);
    REQUIRE(collect(src, c, [](const Collected& x) { return x.observations.size() >= 600; }, 10s));
    collect(src, c, [](const Collected&) { return false; }, 100ms);
    for (const Timed& t : c.events) UNSCOPED_INFO(to_string(t.event.kind) << ": " << t.event.message);
    REQUIRE(c.observations.size() == 600);
    for (std::size_t i = 0; i < 600; ++i) REQUIRE(c.observations[i].sequence == 1 + i);
    CHECK(c.count(EventKind::Gap) == 0);
    CHECK(c.count(EventKind::Restarted) == 0);
    const auto last_connected = std::find_if(c.events.rbegin(), c.events.rend(),
                                             [](const Timed& t) { return t.event.kind == EventKind::Connected; });
    REQUIRE(last_connected != c.events.rend());
    CHECK(last_connected->event.message.find("resuming at sequence 301") != std::string::npos);
}

TEST_CASE("streams documents: observations sorted by sequence, conditions left out, errors of every schema read", "[agent]") {
    const std::string streams = R"(<?xml version="1.0" encoding="UTF-8"?>
<m:MTConnectStreams xmlns:m="urn:mtconnect.org:MTConnectStreams:1.8">
  <m:Header creationTime="2022-04-22T04:06:21Z" instanceId="1649989201" bufferSize="131072" nextSequence="5741581"
            firstSequence="5610509" lastSequence="5741580"/>
  <m:Streams>
    <m:DeviceStream name="Agent" uuid="a"><m:ComponentStream componentId="a1" component="Agent"><m:Events>
      <m:Availability dataItemId="agent_avail" sequence="5741549" timestamp="2022-04-22T04:06:21Z">AVAILABLE</m:Availability>
    </m:Events></m:ComponentStream></m:DeviceStream>
    <m:DeviceStream name="LinuxCNC" uuid="000">
      <m:ComponentStream componentId="path1" component="Path">
        <m:Events>
          <m:Block dataItemId="blk" sequence="5741555" timestamp="2022-04-22T04:06:21.5Z">N140 G01 X1</m:Block>
          <m:VariableDataSet name="vars" sequence="5741556" timestamp="2022-04-22T04:06:21Z" dataItemId="v1" count="2">
            <m:Entry key="X100">66</m:Entry><m:Entry key="X101">ABC</m:Entry></m:VariableDataSet>
        </m:Events>
        <m:Condition><m:Normal dataItemId="cond" sequence="5741557" timestamp="2022-04-22T04:06:21Z" type="SYSTEM"/></m:Condition>
      </m:ComponentStream>
      <m:ComponentStream componentId="c" component="Rotary">
        <m:Samples>
          <m:RotaryVelocity sequence="5741553" timestamp="2022-04-22T04:06:21.25Z" dataItemId="c1">
            UNAVAILABLE
          </m:RotaryVelocity>
          <m:PathPosition sequence="0" timestamp="2022-04-22T04:06:21Z" dataItemId="pp">1 2 3</m:PathPosition>
        </m:Samples>
      </m:ComponentStream>
    </m:DeviceStream>
  </m:Streams>
</m:MTConnectStreams>)";
    const StreamsDocument d = parse_streams(streams, {{"c1", "S1speed"}}, "LinuxCNC");
    CHECK_FALSE(d.is_error);
    CHECK(d.instance_id == 1649989201);
    CHECK(d.first_sequence == 5610509);
    CHECK(d.next_sequence == 5741581);
    REQUIRE(d.observations.size() == 3);
    CHECK(d.observations[0].sequence == 5741553);
    CHECK(d.observations[0].key == "S1speed");   // the probe's name for dataItemId c1
    CHECK(d.observations[0].value == "UNAVAILABLE");
    CHECK(d.observations[0].stamp_ns == 1650600381'250000000);
    CHECK(d.observations[1].key == "blk");       // no probe entry, no name attribute: its id
    CHECK(d.observations[1].value == "N140 G01 X1");
    CHECK(d.observations[2].key == "vars");
    CHECK(d.observations[2].value == "X100=66 X101=ABC");
    REQUIRE(d.warnings.size() == 1);              // sequence 0
    const std::string legacy = R"(<MTConnectError xmlns="urn:mtconnect.org:MTConnectError:1.3"><Header instanceId="7"/>
        <Errors><Error errorCode="OUT_OF_RANGE">'from' must be greater than 12</Error></Errors></MTConnectError>)";
    const StreamsDocument e = parse_streams(legacy, {}, "LinuxCNC");
    CHECK(e.is_error);
    CHECK(e.has_error("OUT_OF_RANGE"));
    CHECK(e.errors[0].message == "'from' must be greater than 12");
    const std::string v2 = R"(<MTConnectError><Header instanceId="7"/><Errors><OutOfRange errorCode="OUT_OF_RANGE">
        <ErrorMessage>'from' must be less than 9</ErrorMessage></OutOfRange></Errors></MTConnectError>)";
    CHECK(parse_streams(v2, {}, "x").errors.at(0).message == "'from' must be less than 9");
    CHECK_THROWS_WITH(parse_streams("<html>oops</html>", {}, "x"), Catch::Contains("expected an MTConnectStreams"));
    CHECK_THROWS_WITH(parse_streams("<MTConnectStreams><Header", {}, "x"), Catch::Contains("not valid XML"));
}

TEST_CASE("the Okuma demo's Devices.xml: names and units of its data items, the device chosen by name or uuid", "[agent][shared]") {
    std::ifstream in(std::string(CUTLOAD_SHARED_DIR) + "/data/real/okuma_multus_shdr/Devices.xml");
    REQUIRE(in);
    std::stringstream ss;
    ss << in.rdbuf();
    // The demo agent serves two machines: without a name the choice is refused, naming both.
    CHECK_THROWS_WITH(parse_probe(ss.str(), ""), Catch::Contains("several devices (OKUMA, Mazak)"));
    const ProbeDocument p = parse_probe(ss.str(), "OKUMA");
    CHECK(p.device_name == "OKUMA");
    CHECK(p.device_uuid == "OKUMA.123456");
    CHECK(p.instance_id == 1);
    const auto find = [&](const std::string& key) {
        const auto it = std::find_if(p.items.begin(), p.items.end(), [&](const DataItemInfo& d) { return d.key() == key; });
        REQUIRE(it != p.items.end());
        return *it;
    };
    const DataItemInfo feed = find("p1Fact");
    CHECK(feed.category == "SAMPLE");
    CHECK(feed.type == "PATH_FEEDRATE");
    CHECK(feed.units == "MILLIMETER/SECOND");
    CHECK(feed.native_units == "MILLIMETER/MINUTE");   // what the adapter's SHDR values are in
    CHECK(find("avail").id == "Lavail");
    CHECK(find("p1LPathPos").type == "PATH_POSITION");
    // Every key of cutload's default SHDR key map that this log uses is a data item here.
    for (const char* key : {"X1actw", "YI1actw", "Z1actw", "S6speed", "p1BlockNumber"}) CHECK(find(key).id.size() > 0);
    CHECK(parse_probe(ss.str(), "OKUMA.123456").device_name == "OKUMA");
    CHECK_THROWS_WITH(parse_probe(ss.str(), "HAAS"), Catch::Contains("no device 'HAAS'") && Catch::Contains("OKUMA, Mazak"));
}
