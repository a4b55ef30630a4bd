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
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

namespace cutload::motion_io::detail {

enum class Chan : std::uint8_t { Pos, AxisX, AxisY, AxisZ, Feed, Spindle, Block };

// One reading of one channel, in canonical units (s, mm, mm/min, rpm).
struct Record {
    double t_s = 0;
    std::size_t line = 0;
    Chan ch = Chan::Pos;
    double v[3] = {0, 0, 0};
    std::int32_t block = -1;
};

// Warnings are counted per code; the first occurrence keeps its place and wording.
class Diagnostics {
public:
    explicit Diagnostics(std::string file) : file_(std::move(file)) {}
    const std::string& file() const { return file_; }
    void warn(const std::string& code, std::size_t line, const std::string& what);
    [[noreturn]] void fail(std::size_t line, const std::string& what) const;
    std::vector<IngestWarning> warnings() const;

private:
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

// ---- units (factor to the canonical unit; throws std::invalid_argument on unknown) ----
double length_factor_mm(std::string_view unit);
double time_factor_s(std::string_view unit);
double feed_factor_mm_min(std::string_view unit);
double angle_factor_deg(std::string_view unit);
double speed_factor_rpm(std::string_view unit);
// Lower-case, trimmed.
std::string normalise_unit(std::string_view unit);

}  // namespace cutload::motion_io::detail
