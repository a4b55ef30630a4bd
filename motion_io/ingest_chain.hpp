// Ingest for a source that delivers readings as they happen (a live machine, a replay): the
// readings are pushed one by one through the same chain of stages a log file goes through
// (docs/ingest.md, "Pushing readings"), and the uniform grid comes out as soon as each sample
// is final. Pushing a log's readings gives exactly what ingest() gives for the file.
#pragma once

#include "motion_io/motion_io.hpp"
#include "motion_io/readings.hpp"

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

namespace cutload::motion_io {

struct ChainOptions {
    double step_ms = 1.0;          // grid step, 0.01 to 1000 ms
    bool event_driven = true;      // values sent on change (SHDR adapter, MTConnect agent);
                                   // false: polled at the client's rate (a CSV export)
    std::string source = "live";   // names the source in warnings and errors ("live:LINE: ...")
    // Polled sources: readings the CNC clock times at once. Lower (e.g. 64) for less latency;
    // see docs/ingest.md. Event-driven sources give the same grid at any value.
    std::size_t clock_batch_readings = 1024;
    // Readings up to this much older than the newest are put back in time order (a larger jump
    // back starts a session). Each reading waits this long for stragglers, so it is the chain's
    // least latency: 1 s for files (ingest()'s value), less for a live source that sends in order.
    double reorder_horizon_s = 1.0;
};

// Receives the grid. Samples are in time order within a session; a session starts after a jump
// back in time, a silence of over a minute or a flush().
class MotionConsumer {
public:
    virtual ~MotionConsumer() = default;
    virtual void begin_session() {}
    virtual void sample(const MotionState& s) = 0;
};

class IngestChain {
public:
    // Throws IngestError for a step outside 0.01..1000 ms.
    IngestChain(const ChainOptions& opt, MotionConsumer& out);
    ~IngestChain();
    IngestChain(const IngestChain&) = delete;
    IngestChain& operator=(const IngestChain&) = delete;

    // One reading in canonical units (s, mm, mm/min, rpm; LogReading), in time order or up to
    // 1 s out of it; `line` says where it came from in warnings (e.g. an observation's
    // sequence number). Glitches are dropped with a warning. Throws IngestError for a session
    // whose time never advances.
    void push(const LogReading& r);
    // One axis on its own (a source with X, Y and Z items instead of a path position): axis 0, 1
    // or 2, mm. Axes stamped alike make one position once all three are known.
    void push_axis(int axis, double t_s, double value_mm, std::size_t line);
    // Ends the current session: every sample still held comes out. Call it at the end of the
    // stream and when the source reports lost data (never interpolate across a gap). Readings
    // pushed afterwards start a new session.
    void flush();

    // Counts and warnings so far (channels, sessions, update period, glitches, ...).
    IngestReport report() const;
    // Names of the blocks MotionState::block indexes.
    const std::vector<std::string>& block_names() const;
    // The stages in order, e.g. "validate", "sequence", ..., "blocks".
    std::vector<std::string> stage_names() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace cutload::motion_io
