#include "commands.hpp"
#include "app/inputs.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <pthread.h>
#include <unistd.h>
#include <cstdio>
#include <iostream>
#include <vector>

namespace cutload::cli {
namespace {
struct Entry {
    const char* name;
    AddCommandFn add;
};
std::vector<Entry>& registry() {
    static std::vector<Entry> r;
    return r;
}
}  // namespace

bool register_command(const char* name, AddCommandFn add) {
    registry().push_back({name, add});
    return true;
}

sigset_t block_stop_signals() {
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGINT);
    sigaddset(&set, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &set, nullptr);
    std::signal(SIGPIPE, SIG_IGN);
    return set;
}

void check_output_path(const std::string& path, const char* option) {
    namespace fs = std::filesystem;
    const fs::path target(path);
    std::error_code ec;
    if (fs::is_directory(target, ec))
        throw UsageError(std::string(option) + " " + path + ": is a folder, expected a file name");
    const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
    if (!fs::is_directory(dir, ec))
        throw UsageError(std::string(option) + " " + path + ": folder " + dir.string() + " does not exist");
    if (::access(dir.c_str(), W_OK) != 0)
        throw UsageError(std::string(option) + " " + path + ": cannot write in " + dir.string() + " (" +
                         std::strerror(errno) + ")");
}

void add_log_options(CLI::App& sub, app::LogFormat& format) {
    static const std::map<std::string, std::string> formats{{"auto", "auto"}, {"csv", "csv"}, {"shdr", "shdr"}};
    sub.add_option("--format", format.format, "Log format: csv, shdr or auto (default: from the file's content)")
        ->transform(CLI::CheckedTransformer(formats, CLI::ignore_case))
        ->option_text("csv|shdr|auto");
    // The reader checks the map file itself so that a bad path gets the one-line error format.
    sub.add_option("--map", format.map_file,
                   "Channel map: a JSON file, or a bundled preset (" + fmt::format("{}", fmt::join(motion_io::map_presets(), ", ")) +
                       "), naming the CSV columns or SHDR keys of each channel (docs/formats.md)");
    sub.add_option_function<std::string>(
           "--units", [&format](const std::string& u) { format.length_unit = u; },
           "Length unit of positions and feed when the log does not declare one")
        ->check(CLI::IsMember({"mm", "in"}));
    sub.add_option_function<std::string>(
        "--feed-units", [&format](const std::string& u) { format.feed_unit = u; },
        "Unit of the feed channel, overriding the log's declaration (mm/min, mm/s, in/min, in/s)");
}

motion_io::ReadOptions reader_options(const app::LogFormat& format, double step_ms) {
    try {
        return app::read_options(format, step_ms);
    } catch (const app::InputError& e) {
        throw UsageError("--" + std::string(e.what()));
    }
}

force_model::Device choose_device(const std::string& name) {
    const app::DeviceChoice choice = app::choose_device(name);
    if (!choice.note.empty()) std::fprintf(stderr, "cutload: note: %s\n", choice.note.c_str());
    return choice.device;
}

}  // namespace cutload::cli

int main(int argc, char** argv) {
    using namespace cutload;
    CLI::App app{"cutload: predict milling forces from CNC dry-run motion logs"};
    app.require_subcommand(1);
    app.set_version_flag("--version", "cutload 0.1.0");
    auto& entries = cli::registry();
    std::sort(entries.begin(), entries.end(),
              [](const auto& a, const auto& b) { return std::string(a.name) < b.name; });
    for (const auto& e : entries) e.add(app);
    // CLI11 would only say "A subcommand is required"; name the word that is not a command.
    if (argc > 1 && argv[1][0] != '-' &&
        std::none_of(entries.begin(), entries.end(), [&](const auto& e) { return std::string(e.name) == argv[1]; })) {
        std::string names;
        for (const auto& e : entries) names += std::string(names.empty() ? "" : ", ") + e.name;
        std::fprintf(stderr, "cutload: error: unknown command '%s' (commands: %s)\n", argv[1], names.c_str());
        return 2;
    }
    try {
        app.parse(argc, argv);
    } catch (const CLI::Success& e) {
        return app.exit(e);   // --help, --help-all, --version (CLI11 derives them from Success)
    } catch (const CLI::ParseError& e) {
        // One line in the same format as every other error, so scripts can rely on it.
        std::fprintf(stderr, "cutload: error: %s (see cutload --help)\n", e.what());
        return 2;
    } catch (const cli::UsageError& e) {
        std::fprintf(stderr, "cutload: error: %s\n", e.what());
        return e.code();
    } catch (const app::InputError& e) {
        std::fprintf(stderr, "cutload: error: %s\n", e.what());
        return 2;
    } catch (const motion_io::IngestError& e) {
        std::fprintf(stderr, "cutload: error: %s\n", e.what());
        return 2;
    } catch (const force_model::SpecError& e) {
        std::fprintf(stderr, "cutload: error: %s\n", e.what());
        return 2;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "cutload: error: %s\n", e.what());
        return 1;
    }
    return 0;
}
