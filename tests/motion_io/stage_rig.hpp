// A test bench for one ingest stage: a feeder stage in front emits what the test hands it, the
// stage under test sits in a chain as in production, and a capture stage behind it records
// everything the stage emits.
#pragma once

#include "stages/chain.hpp"
#include "stages/stage.hpp"

#include <catch2/catch.hpp>

#include <memory>
#include <string>
#include <vector>

namespace cutload::motion_io::test {

using detail::Chan;
using detail::Flow;
using detail::Flows;
using detail::Record;

// Emits the test's messages as the kinds given.
class Feeder final : public detail::Stage {
public:
    explicit Feeder(Flows kinds) : Stage("feeder"), kinds_(kinds) {}
    Flows accepts() const override { return static_cast<Flows>(Flow::Readings); }
    Flows emits() const override { return kinds_; }
    // What the chain is pushed goes on as readings or checked readings, whichever it emits.
    void record(const Record& r) override { emit(detail::has(kinds_, Flow::Readings) ? Flow::Readings : Flow::Checked, r); }
    void session_record(const Record& r) { emit(detail::session_flow(r.ch), r); }
    void begin() { emit_begin_session(); }
    void end(detail::SessionSummary& s) { emit_end_session(s); }
    void end() {
        detail::SessionSummary s;
        emit_end_session(s);
    }
    void tick(const detail::Tick& t) override { emit(t); }
    void knot(const detail::Knot& k) override { emit(k); }
    void grid(detail::GridSample s) { emit(std::span<detail::GridSample>(&s, 1)); }
    void finish() override { emit_finish(); }

private:
    Flows kinds_;
};

// Records what reaches it.
class Capture final : public detail::Stage {
public:
    explicit Capture(Flows kinds) : Stage("capture"), kinds_(kinds) {}
    Flows accepts() const override { return kinds_; }
    Flows emits() const override { return 0; }
    void record(const Record& r) override { records.push_back(r); }
    void begin_session() override { ++sessions_begun; }
    void end_session(detail::SessionSummary& s) override { summaries.push_back(s); }
    void tick(const detail::Tick& t) override { ticks.push_back(t); }
    void knot(const detail::Knot& k) override { knots.push_back(k); }
    void grid(std::span<detail::GridSample> batch) override { samples.insert(samples.end(), batch.begin(), batch.end()); }
    void finish() override { ++finished; }

    std::vector<Record> positions() const { return of(Chan::Pos); }
    std::vector<Record> of(Chan ch) const {
        std::vector<Record> out;
        for (const Record& r : records)
            if (r.ch == ch) out.push_back(r);
        return out;
    }

    std::vector<Record> records;
    std::vector<detail::Tick> ticks;
    std::vector<detail::Knot> knots;
    std::vector<detail::GridSample> samples;
    std::vector<detail::SessionSummary> summaries;
    int sessions_begun = 0, finished = 0;

private:
    Flows kinds_;
};

class NoGrid final : public detail::GridSink {
public:
    void sample(const detail::GridSample&) override {}
};

// feeder -> stage -> capture.
struct StageRig {
    StageRig(std::unique_ptr<detail::Stage> stage, Flows feed, Flows capture) : chain(sink) {
        auto f = std::make_unique<Feeder>(feed);
        auto c = std::make_unique<Capture>(capture);
        feeder = f.get();
        out = c.get();
        under_test = stage.get();
        chain.append(std::move(f));
        chain.append(std::move(stage));
        chain.append(std::move(c));
        chain.bind();
    }
    NoGrid sink;
    detail::StageChain chain;
    Feeder* feeder = nullptr;
    detail::Stage* under_test = nullptr;
    Capture* out = nullptr;
};

inline Record pos(double t_s, double x, double y = 0, double z = 0, std::size_t line = 0) {
    Record r;
    r.t_s = t_s;
    r.line = line;
    r.ch = Chan::Pos;
    r.v[0] = x, r.v[1] = y, r.v[2] = z;
    return r;
}

inline Record value(Chan ch, double t_s, double v, std::size_t line = 0) {
    Record r;
    r.t_s = t_s;
    r.line = line;
    r.ch = ch;
    r.v[0] = v;
    return r;
}

inline Record block(double t_s, std::int32_t id, std::size_t line = 0) {
    Record r;
    r.t_s = t_s;
    r.line = line;
    r.ch = Chan::Block;
    r.block = id;
    return r;
}

// The warning of a code, or an empty one.
inline IngestWarning warning_of(const detail::Diagnostics& d, const std::string& code) {
    for (const auto& w : d.warnings())
        if (w.code == code) return w;
    return {};
}

}  // namespace cutload::motion_io::test
