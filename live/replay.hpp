// The replay adapter: plays a recorded log (SHDR or CSV) as an SHDR adapter, so a live consumer
// (cutload's own sources, an MTConnect agent) sees a machine running. `cutload replay` is its
// command-line front end. See docs/live.md.
#pragma once

#include "motion_io/motion_io.hpp"
#include "motion_io/shdr.hpp"

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>

namespace cutload::live {

// The keys and units a CSV log is written under in SHDR: the first key of each channel's list in
// a map file (docs/formats.md), or without one path_pos, path_feedrate (mm/s), spindle_speed
// (rpm) and block, which cutload's SHDR reader takes with no map.
struct ShdrOutputKeys {
    std::string position;              // empty: the axes x, y, z as separate keys
    std::string x, y, z, feed, spindle, block;
    motion_io::ShdrUnitFactors units;  // canonical units per written unit
};
ShdrOutputKeys shdr_output_keys(const std::string& map_file);

// Writes every reading of a CSV log as SHDR, stamped 1970-01-01T00:00:00Z + its t (the replay
// shifts stamps anyway); readings with the same stamp share a line. `opt.map_file` chooses the
// output keys (shdr_output_keys); the other options read the CSV as `ingest` does. Throws
// IngestError as the CSV reader does, or for a block name holding '|' (SHDR cannot carry it).
// Returns the number of lines written.
std::size_t write_csv_as_shdr(const std::string& csv_path, const motion_io::ReadOptions& opt, std::FILE* out);

struct ReplayOptions {
    std::string log;
    motion_io::ReadOptions read;       // format (auto, csv, shdr); for CSV its units and output keys (map_file)
    std::string host = "127.0.0.1";
    int port = 7878;                   // 0: any free port (see port())
    double speed = 1.0;                // 10: ten times as fast as recorded
    bool loop = false;                 // start again at the end, stamps still increasing
    std::chrono::milliseconds heartbeat{10000};   // announced in '* PONG <ms>'
    std::optional<double> max_pause_s; // a longer silence in the log is shortened to this (delivery only)
    std::size_t max_client_backlog_bytes = 8u << 20;   // a client that falls further behind is dropped
};

struct ReplayStats {
    std::uint64_t lines_sent = 0;      // log lines sent (each once, whatever the number of clients)
    std::uint64_t passes_done = 0;
    std::uint64_t clients_accepted = 0, clients_dropped = 0, clients_now = 0;
    std::uint64_t pings_answered = 0;
    bool started = false, finished = false;   // finished: the last pass is out (never with loop)
};

// Serves the log on host:port: plays it from the start when the first client connects, to every
// connected client (a later client first gets the latest value of every key, as an adapter sends
// its current state to a new connection), answers '* PING' with '* PONG <heartbeat>'. Time stamps
// are the log's own shifted by one constant per pass, so the first line is stamped 'now' and the
// log's unequal intervals are kept exactly; lines are sent when their stamp falls due, the
// intervals divided by `speed` (so at speed 10 the stamps run ahead of the wall clock). After the
// last pass it keeps serving (heartbeats, the state to new clients) until stopped.
class ReplayAdapter {
public:
    // Reads the whole log once to validate it (IngestError: what, file:line) and listens
    // (std::runtime_error when the address cannot be had). Serves from a thread of its own.
    // std::invalid_argument for a bad option (speed, heartbeat, a map or units for an SHDR log).
    explicit ReplayAdapter(ReplayOptions opt);
    ~ReplayAdapter();
    ReplayAdapter(const ReplayAdapter&) = delete;
    ReplayAdapter& operator=(const ReplayAdapter&) = delete;

    int port() const;
    // Closes every connection and the listening socket; idempotent.
    void stop();
    // True once the last pass is out (false on timeout, or with loop).
    bool wait_finished(std::chrono::milliseconds timeout) const;
    ReplayStats stats() const;
    // The log as validated: lines sent per pass; the playing time of one pass at speed 1 (the
    // forward steps between the stamps of data and condition lines, max_pause_s applied); the
    // format it was read as.
    std::size_t log_lines() const;
    double log_duration_s() const;
    motion_io::Format log_format() const;

private:
    class Engine;
    std::unique_ptr<Engine> engine_;
};

}  // namespace cutload::live
