// Internal: one ingest stage and the messages that flow between stages (docs/ingest.md).
//
// A stage is one concern with a name. It declares the kinds of message it accepts and the kinds
// it emits; the chain (chain.hpp) binds each emitted kind to the next stage downstream that
// accepts it, so a kind a stage does not handle never passes through it, and a stage can be
// inserted or removed by name as long as every kind still has a producer and a consumer.
#pragma once

#include "pipeline.hpp"

#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

namespace cutload::motion_io::detail {

// Kinds of message, as a bit set.
enum class Flow : std::uint16_t {
    Readings = 1u << 0,    // reader records, any channel, file order, unchecked
    Checked = 1u << 1,     // records that passed validation
    Sessions = 1u << 2,    // session boundaries (begin, end with its summary)
    Positions = 1u << 3,   // 3-D position readings, time-ordered within a session
    Feed = 1u << 4,        // feed readings, time-ordered within a session
    Spindle = 1u << 5,     // spindle speed readings, time-ordered within a session
    Blocks = 1u << 6,      // block readings, time-ordered within a session
    Ticks = 1u << 7,       // positions timed at the CNC tick they show
    Knots = 1u << 8,       // ticks with a velocity
    Grid = 1u << 9,        // uniform grid samples
};
inline constexpr std::size_t kFlowKinds = 10;
using Flows = std::uint16_t;
constexpr Flows operator|(Flow a, Flow b) { return static_cast<Flows>(static_cast<Flows>(a) | static_cast<Flows>(b)); }
constexpr Flows operator|(Flows a, Flow b) { return static_cast<Flows>(a | static_cast<Flows>(b)); }
constexpr bool has(Flows set, Flow k) { return (set & static_cast<Flows>(k)) != 0; }
constexpr std::size_t flow_index(Flow k) { return static_cast<std::size_t>(std::countr_zero(static_cast<unsigned>(k))); }
const char* flow_name(Flow k);

// The kind a time-ordered session record travels as.
constexpr Flow session_flow(Chan ch) {
    return ch == Chan::Feed ? Flow::Feed : ch == Chan::Spindle ? Flow::Spindle : (ch == Chan::Block || ch == Chan::Tool) ? Flow::Blocks : Flow::Positions;
}

// A position reading put at the time of the CNC tick it shows.
struct Tick {
    double t_s = 0;
    double p_mm[3] = {0, 0, 0};
    double rot_deg[3] = {0, 0, 0};   // A, B, C (0 where the log has none)
    double period_s = 0;             // the CNC period the tick was timed with (0: own time stamp)
    bool replaces_previous = false;  // same time stamp as the previous tick and no CNC grid to
                                     // separate them: its position replaces the previous one's
};

// A tick with the velocity of the motion through it.
struct Knot {
    double t_s = 0;
    double p_mm[3] = {0, 0, 0};
    double v_mm_s[3] = {0, 0, 0};
    double rot_deg[3] = {0, 0, 0};
    double rot_vel_deg_s[3] = {0, 0, 0};
};

struct GridSample {
    double t_s = 0;
    double p_mm[3] = {0, 0, 0};
    double v_mm_s[3] = {0, 0, 0};
    double rot_deg[3] = {0, 0, 0};
    double rot_vel_deg_s[3] = {0, 0, 0};
    std::uint8_t rotary = 0;   // bit k: the log has rotary axis k (A, B, C)
    double spindle_rpm = 0;
    double spindle_angle_deg = 0;
    std::int32_t block = -1;
    std::int32_t tool = -1;   // tool in the spindle (-1: the log has no tool channel)
};

// Where the grid goes (MotionModel builder, CSV writer, live consumer, or nothing for inspect).
class GridSink {
public:
    virtual ~GridSink() = default;
    virtual void begin_session() {}
    virtual void sample(const GridSample& s) = 0;
};

// Travels downstream with the end of a session; each stage fills in what it knows.
struct SessionSummary {
    std::size_t position_reads = 0;   // survey: position readings in the session
    std::size_t first_line = 0;       // survey: line of its first position reading
    double first_t_s = 0, last_t_s = 0;
    double period_s = 0;              // clock: CNC update period found (0: none)
};

class Stage {
public:
    explicit Stage(std::string name) : name_(std::move(name)) {}
    virtual ~Stage() = default;
    Stage(const Stage&) = delete;
    Stage& operator=(const Stage&) = delete;

    const std::string& name() const { return name_; }
    virtual Flows accepts() const = 0;
    virtual Flows emits() const = 0;

    // One handler per kind; each is called only for kinds the stage accepts.
    virtual void record(const Record&) {}
    virtual void begin_session() { emit_begin_session(); }
    virtual void end_session(SessionSummary& s) { emit_end_session(s); }
    virtual void tick(const Tick&) {}
    virtual void knot(const Knot&) {}
    // Grid samples come in time order, a few at a time (those of one segment between knots).
    virtual void grid(std::span<GridSample> batch) { emit(batch); }
    // End of the reader's stream (stages before the sequence stage, which turns it into the end
    // of the last session).
    virtual void finish() { emit_finish(); }
    // Adds what this stage counted to the report.
    virtual void report(IngestReport&) const {}

protected:
    void emit(Flow kind, const Record& r) { route(kind).record(r); }
    void emit(const Tick& t) { route(Flow::Ticks).tick(t); }
    void emit(const Knot& k) { route(Flow::Knots).knot(k); }
    void emit(std::span<GridSample> batch) { route(Flow::Grid).grid(batch); }
    void emit_begin_session() { route(Flow::Sessions).begin_session(); }
    void emit_end_session(SessionSummary& s) { route(Flow::Sessions).end_session(s); }
    void emit_finish();

private:
    friend class StageChain;
    Stage& route(Flow kind) { return *routes_[flow_index(kind)]; }
    std::string name_;
    std::array<Stage*, kFlowKinds> routes_{};   // set by the chain for every kind emitted
};

}  // namespace cutload::motion_io::detail
