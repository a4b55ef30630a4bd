// The small input pieces both front ends need in the same form: how to read a log, which device
// the engine runs on, and a tool or material checked on its own. The CLI fills them from options,
// the service from multipart parts and stored JSON; bad values are errors naming the key.
#pragma once

#include "force_model/force_model.hpp"
#include "motion_io/motion_io.hpp"

#include <nlohmann/json_fwd.hpp>

#include <future>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

namespace cutload::app {

// A bad input value: what() is "<key>: <why>"; front ends prefix their own spelling ("part ",
// "--") or map it to their error format.
class InputError : public std::invalid_argument {
public:
    InputError(std::string key, const std::string& why);
    const std::string& key() const { return key_; }

private:
    std::string key_;
};

// How a log is to be read, as a front end receives it.
struct LogFormat {
    std::string format = "auto";              // auto | csv | shdr
    std::string map_file;                     // channel map: a JSON file or a bundled preset name; empty: built-in
    std::optional<std::string> length_unit;   // mm | in, when the log does not declare one
    std::optional<std::string> feed_unit;     // overrides the log's feed unit (checked by the reader)
};

// The reader's options; InputError naming `format` or `units` for a value it does not know.
motion_io::ReadOptions read_options(const LogFormat& f, double step_ms = motion_io::ReadOptions{}.step_ms);

// The engine's device for "opencl", "cpu" or "auto" (OpenCL when a device is usable; else the CPU
// path, and `note` says why). InputError naming `device` for another name.
struct DeviceChoice {
    force_model::Device device = force_model::Device::Cpu;
    std::string note;   // empty unless auto fell back to the CPU
};
DeviceChoice choose_device(std::string_view name);
// choose_device in the background, the chosen OpenCL device also made ready (platform opened, the
// engine's programs built), so that a front end can open it while the log is read: PoCL's platform
// takes about 0.15 s to open (it loads LLVM), as long as reading a 10 s log. For "opencl" a device
// that fails to open is left for the engine to report, as without this. The last copy of the
// future waits for the work when it is destroyed: no thread outlives it.
std::shared_future<DeviceChoice> prepare_device(std::string name);
// For a front end that runs prediction after prediction in one process (the service and its
// workers): the heap memory a finished prediction frees stays for the next one instead of being
// faulted in again (force_model::keep_freed_heap_for_next_prediction). Once, from main, before
// any thread starts; false when the allocator refused.
bool prepare_for_repeated_runs();

// A complete, valid run spec: replace one part (tool, material, limits) to have the engine check
// that part alone, with its own error naming the key.
nlohmann::json probe_spec();

// The run spec's tool object; SpecError naming the key (tool.diameter_mm, ...).
force_model::ToolSpec parse_tool(const nlohmann::json& tool);
// A JSON file holding the tool object, or a whole run spec whose `tool` is taken; SpecError
// starting with the path (unreadable file, bad JSON, bad tool).
force_model::ToolSpec load_tool(const std::string& path);

// The run spec's material object; SpecError naming the key (material.Ktc_N_mm2, ...).
force_model::Material parse_material(const nlohmann::json& material);

}  // namespace cutload::app
