// Internal to motion_io: the record stream the readers push into the ingest stages.
//
//   reader (csv_reader / shdr_reader)  ->  RecordSink: the chain of stages (stages/chain.hpp:
//   validate, sequence, drop_jumps, ..., blocks)  ->  GridSink (MotionModel builder, CSV writer,
//   live consumer, or nothing for inspect)
#pragma once

#include "motion_io/motion_io.hpp"

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

namespace cutload::motion_io::detail {

// AxisA, AxisB, AxisC: single rotary items (SHDR), in degrees; the sequence stage latches them into
// the position readings (Record::rot_deg) as it merges the single linear axes.
enum class Chan : std::uint8_t { Pos, AxisX, AxisY, AxisZ, Feed, Spindle, Block, Tool, AxisA, AxisB, AxisC };
constexpr bool is_rotary_axis(Chan ch) { return ch == Chan::AxisA || ch == Chan::AxisB || ch == Chan::AxisC; }

// One reading of one channel, in canonical units (s, mm, mm/min, rpm).
struct Record {
    double t_s = 0;
    std::size_t line = 0;
    Chan ch = Chan::Pos;
    double v[3] = {0, 0, 0};
    std::int32_t block = -1;
    // Pos: the rotary axes A, B, C latched with the linear ones, in degrees (0 where the log has
    // no such axis: ReaderFacts::rotary).
    double rot_deg[3] = {0, 0, 0};
    // The reading of this channel before it was dropped as a glitch (validate, drop_jumps): the
    // silence before this one is a lost reading, not a value held (stage hold).
    bool after_glitch = false;
};

// The step positions are written to, from the text of each value (docs/formats.md, "Coarse data"):
// a value's last written digit has a place 10^e (1.98E+02: 10^0; 258.428: 10^-3, trailing zeros
// count, as the writer printed them). Per axis, consecutive moving readings written to the same
// place are counted by place; the place most of them use is the axis's step, times the common
// divisor of their differences when those take at least three distinct values (positions that
// all move in 0.005 mm steps although written to 0.001 mm; one repeated difference is just steady
// motion). Bounded memory: a few counters per place.
class PositionResolution {
public:
    void add(int axis, std::string_view text, double factor_mm);
    struct Step {
        double step_mm = 0;
        std::string example;   // one value as written at that step
    };
    std::optional<Step> step() const;   // the coarsest axis that moved; nullopt: too few moves to tell

private:
    struct Bucket {
        std::size_t pairs = 0;
        std::uint64_t gcd = 0;
        std::uint64_t deltas[3] = {0, 0, 0};   // first distinct differences seen
        std::string example;
    };
    struct Axis {
        bool have_prev = false;
        int prev_place = 0;
        std::int64_t prev_digits = 0;
        double factor_mm = 1;
        std::map<int, Bucket> buckets;
    };
    std::array<Axis, 3> axes_;
};

// What the readers learn besides the records: handed on to the report.
struct ReaderFacts {
    PositionResolution resolution;
    double spindle_max_abs_rpm = 0;     // set by the validate stage: the fastest reading it passed on
    bool commanded_positions = false;   // commanded positions besides the actual ones
    // Which rotary axes (A, B, C) the position readings carry; known before the first record.
    std::array<bool, 3> rotary{false, false, false};
    bool any_rotary() const { return rotary[0] || rotary[1] || rotary[2]; }
    // The rotary axes come as items of their own (SHDR: Chan::AxisA..AxisC), which the sequence
    // stage latches into every position reading; false: the readings carry them (CSV rows).
    bool rotary_items = false;
};

// Rotary axes count as motion of this many mm per degree where the ingest weighs them against the
// linear axes (the clock stage's velocity jumps): a point 100 mm from the axis line (design
// docs/five_axis.md, section 2.2: rho_ref = 100 mm/rad).
inline constexpr double kRotaryMmPerDeg = 100.0 * 3.14159265358979323846 / 180.0;

// A logged angle beyond this is no axis position (a counter that overflowed, a wrong column or
// key): a table turning 1000 rpm for ten hours reaches 2e8 deg when its display counts on. The
// readers refuse it at its line.
inline constexpr double kMaxAbsRotaryDeg = 1e9;

// Warnings are counted per code; the first occurrence keeps its place and wording.
class Diagnostics {
public:
    // `file` is the path as given; messages carry it as valid UTF-8 (textio::printable).
    explicit Diagnostics(const std::string& file);
    const std::string& file() const { return file_; }
    void warn(const std::string& code, std::size_t line, const std::string& what);
    [[noreturn]] void fail(std::size_t line, const std::string& what) const;
    [[noreturn]] void fail_at(std::size_t line, std::size_t column, const std::string& what) const;
    std::vector<IngestWarning> warnings() const;
    ReaderFacts& facts() { return facts_; }
    const ReaderFacts& facts() const { return facts_; }

private:
    ReaderFacts facts_;
    struct Entry {
        std::size_t count = 0;
        std::size_t first_line = 0;
        std::string first_what;
    };
    std::string file_;
    std::vector<std::string> order_;
    std::unordered_map<std::string, Entry> entries_;
};

class BlockTable {
public:
    std::int32_t intern(std::string_view name);
    const std::vector<std::string>& names() const { return names_; }

private:
    std::unordered_map<std::string, std::int32_t> ids_;
    std::vector<std::string> names_;
};

// Interval statistics in bounded memory: exact min/max, median from a log-spaced histogram
// (0.1 % resolution), so a 10-million-row log needs no sorted copy of its intervals.
class IntervalHistogram {
public:
    void add(double dt_s);
    IntervalStats stats() const;
    std::size_t count() const { return n_; }

private:
    static constexpr double kLogMin = -7.0, kLogMax = 6.0;
    static constexpr int kBinsPerDecade = 1000;
    std::vector<std::uint32_t> bins_;
    std::size_t n_ = 0;
    double min_ = 0, max_ = 0;
};

// Everything downstream of the readers receives records here.
class RecordSink {
public:
    virtual ~RecordSink() = default;
    virtual void push(const Record& r) = 0;
    virtual void finish() = 0;
};

// Plausible ranges (the readers warn `out_of_range` beyond them) and the sequence stage's tunables,
// documented in docs/ingest.md.
struct StageLimits {
    double reorder_horizon_s = 1.0;   // backward jumps up to this are reordered, larger start a session
    double session_gap_s = 60.0;      // a forward silence longer than this starts a session
    double max_abs_position_mm = 10000;
    double max_feed_mm_min = 200000;  // 200 m/min: beyond any machine tool's rapid traverse
    double max_abs_spindle_rpm = 100000;
};

// ---- readers ----
void read_csv(const std::string& path, const ReadOptions& opt, Diagnostics& diag, BlockTable& blocks,
              RecordSink& out);
void read_shdr(const std::string& path, const ReadOptions& opt, Diagnostics& diag, BlockTable& blocks,
               RecordSink& out);
Format detect_format(const std::string& path, Diagnostics& diag);

// After the stages have filled `report`: the readers' facts into it, and the position_quantized
// warning when positions are written coarser than kQuantizedStepMm.
inline constexpr double kQuantizedStepMm = 0.01;
void report_reader_facts(Diagnostics& diag, IngestReport& report);

// ---- units (factor to the canonical unit; throws std::invalid_argument on unknown) ----
double length_factor_mm(std::string_view unit);
double time_factor_s(std::string_view unit);
double feed_factor_mm_min(std::string_view unit);
double angle_factor_deg(std::string_view unit);
double speed_factor_rpm(std::string_view unit);
// Lower-case, trimmed.
std::string normalise_unit(std::string_view unit);

}  // namespace cutload::motion_io::detail
