// cutload replay LOG [--listen HOST:PORT] [--speed X] [--loop] [--format csv|shdr|auto] [--map FILE]
//                    [--units mm|in] [--feed-units U] [--heartbeat-ms N] [--max-pause-s S] [--exit-at-end]
// Plays a recorded log as an MTConnect SHDR adapter (live/replay.hpp, docs/live.md). SIGINT /
// SIGTERM stop it.
#include "commands.hpp"
#include "live/live.hpp"
#include "live/replay.hpp"

#include <fmt/format.h>

#include <csignal>
#include <ctime>
#include <memory>
#include <pthread.h>

namespace cutload::cli {
namespace {

struct ReplayArgs {
    live::ReplayOptions opt;
    app::LogFormat format;
    std::string listen = "127.0.0.1:7878";
    long heartbeat_ms = 10000;
    double max_pause_s = -1;
    bool exit_at_end = false;
};

void run_replay(ReplayArgs& a) {
    try {
        const live::HostPort hp = live::parse_host_port(a.listen);
        a.opt.host = hp.host;
        a.opt.port = hp.port;
    } catch (const live::SourceError& e) {
        throw UsageError(std::string("--listen: ") + e.what());
    }
    a.opt.read = reader_options(a.format, a.opt.read.step_ms);
    a.opt.heartbeat = std::chrono::milliseconds(a.heartbeat_ms);
    if (a.max_pause_s >= 0) a.opt.max_pause_s = a.max_pause_s;

    // Signals go to this thread only (sigtimedwait), never to the replay thread.
    const sigset_t set = block_stop_signals();

    std::unique_ptr<live::ReplayAdapter> made;
    try {
        made = std::make_unique<live::ReplayAdapter>(a.opt);   // validates the whole log before it listens
    } catch (const std::invalid_argument& e) {
        throw UsageError(e.what());
    }
    live::ReplayAdapter& adapter = *made;
    const motion_io::Format format = adapter.log_format();
    fmt::print("cutload: replaying {} ({}, {} lines, {:.3f} s at speed {} = {:.3f} s{}) as an SHDR adapter on {}:{}\n",
               a.opt.log, format == motion_io::Format::Csv ? "csv" : "shdr", adapter.log_lines(),
               adapter.log_duration_s(), a.opt.speed, adapter.log_duration_s() / a.opt.speed,
               a.opt.loop ? ", looped" : "", a.opt.host, adapter.port());
    fmt::print("cutload: playback starts when the first client connects; Ctrl-C stops\n");
    std::fflush(stdout);

    bool announced_end = false;
    while (true) {
        timespec tick{0, 100'000'000};
        const int sig = sigtimedwait(&set, nullptr, &tick);
        if (sig == SIGINT || sig == SIGTERM) {
            fmt::print("cutload: {} received, stopping\n", sig == SIGINT ? "SIGINT" : "SIGTERM");
            break;
        }
        const live::ReplayStats s = adapter.stats();
        if (s.finished && !announced_end) {
            announced_end = true;
            fmt::print("cutload: end of log: {} lines sent, {} client{} served{}\n", s.lines_sent, s.clients_accepted,
                       s.clients_accepted == 1 ? "" : "s", a.exit_at_end ? "" : "; still serving (Ctrl-C stops)");
            std::fflush(stdout);
            if (a.exit_at_end) break;
        }
    }
    adapter.stop();
    const live::ReplayStats s = adapter.stats();
    if (s.clients_dropped > 0)
        fmt::print("cutload: {} client{} dropped for falling more than {} MiB behind\n", s.clients_dropped,
                   s.clients_dropped == 1 ? "" : "s", a.opt.max_client_backlog_bytes >> 20);
    std::fflush(stdout);
}

void add_replay(CLI::App& app) {
    auto a = std::make_shared<ReplayArgs>();
    auto* sub = app.add_subcommand(
        "replay", "Play a recorded log (SHDR or CSV) as an MTConnect SHDR adapter, time stamps shifted to now");
    sub->add_option("LOG", a->opt.log, "Recorded log (SHDR adapter output, or a CSV log)")->required();
    sub->add_option("--listen", a->listen, "HOST:PORT to serve on (port 0: any free port)")->capture_default_str();
    sub->add_option("--speed", a->opt.speed, "Play X times as fast as recorded (stamps keep the log's intervals)")
        ->check(CLI::Range(0.001, 10000.0))
        ->capture_default_str();
    sub->add_flag("--loop", a->opt.loop, "Start again at the end (stamps keep increasing)");
    sub->add_option("--heartbeat-ms", a->heartbeat_ms, "Heartbeat announced in '* PONG <ms>'")
        ->check(CLI::Range(1L, 600000L))
        ->capture_default_str();
    sub->add_option("--max-pause-s", a->max_pause_s, "Shorten silences in the log to this many seconds (default: keep)")
        ->check(CLI::Range(0.0, 86400.0));
    sub->add_flag("--exit-at-end", a->exit_at_end, "Exit after the last line instead of serving on");
    add_log_options(*sub, a->format);
    sub->get_option("--map")->description("CSV logs: the keys and units to write, an SHDR key map (docs/live.md)");
    sub->callback([a] { run_replay(*a); });
}

const bool registered = register_command("replay", &add_replay);

}  // namespace
}  // namespace cutload::cli
