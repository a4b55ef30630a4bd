#include "app/inputs.hpp"

#include "textio/json.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

namespace cutload::app {

InputError::InputError(std::string key, const std::string& why)
    : std::invalid_argument(key + ": " + why), key_(std::move(key)) {}

motion_io::ReadOptions read_options(const LogFormat& f, double step_ms) {
    motion_io::ReadOptions o;
    if (f.format == "auto")
        o.format = motion_io::Format::Auto;
    else if (f.format == "csv")
        o.format = motion_io::Format::Csv;
    else if (f.format == "shdr")
        o.format = motion_io::Format::Shdr;
    else
        throw InputError("format", fmt::format("'{}' is not auto, csv or shdr", f.format));
    if (f.length_unit && *f.length_unit != "mm" && *f.length_unit != "in")
        throw InputError("units", fmt::format("'{}' is not mm or in", *f.length_unit));
    o.map_file = f.map_file;
    o.length_unit = f.length_unit;
    o.feed_unit = f.feed_unit;
    o.step_ms = step_ms;
    return o;
}

DeviceChoice choose_device(std::string_view name) {
    if (name == "cpu") return {force_model::Device::Cpu, ""};
    if (name == "opencl") return {force_model::Device::OpenCL, ""};
    if (name != "auto") throw InputError("device", fmt::format("'{}' is not opencl, cpu or auto", name));
    try {
        force_model::opencl_device_name();
        return {force_model::Device::OpenCL, ""};
    } catch (const std::runtime_error& e) {
        return {force_model::Device::Cpu, std::string(e.what()) + "; using the CPU path"};
    }
}

bool prepare_for_repeated_runs() { return force_model::keep_freed_heap_for_next_prediction(); }

std::shared_future<DeviceChoice> prepare_device(std::string name) {
    if (name == "cpu") {
        std::promise<DeviceChoice> ready;
        ready.set_value({force_model::Device::Cpu, ""});
        return ready.get_future().share();
    }
    return std::async(std::launch::async, [name = std::move(name)] {
               DeviceChoice choice = choose_device(name);
               if (choice.device == force_model::Device::OpenCL) {
                   try {
                       force_model::prepare_opencl();
                   } catch (const std::exception&) {   // the engine opens it again and says why
                   }
               }
               return choice;
           })
        .share();
}

nlohmann::json probe_spec() {
    return nlohmann::json::parse(R"({
      "tool": {"shape": "flat", "diameter_mm": 8, "flutes": 2, "helix_deg": 30, "corner_radius_mm": 0,
               "flute_length_mm": 20, "stickout_mm": 30, "holder": {"diameter_mm": 32, "length_mm": 40}},
      "material": {"name": "probe", "Ktc_N_mm2": 800, "Krc_N_mm2": 300, "Kac_N_mm2": 100,
                   "Kte_N_mm": 20, "Kre_N_mm": 20, "Kae_N_mm": 5},
      "stock": {"box_mm": {"min": [0, 0, 0], "max": [10, 10, 10]}}
    })");
}

force_model::ToolSpec parse_tool(const nlohmann::json& tool) {
    nlohmann::json spec = probe_spec();
    spec["tool"] = tool;
    return force_model::parse_run_spec(spec).tool;
}

force_model::ToolSpec load_tool(const std::string& path) {
    nlohmann::json j;
    try {
        j = textio::read_json_file(path, "tool file");
    } catch (const textio::TextError& e) {
        throw force_model::SpecError(e.what());   // "path:line:column: key: why"
    }
    try {
        return parse_tool(j.is_object() && j.contains("tool") ? j["tool"] : j);
    } catch (const force_model::SpecError& e) {
        throw force_model::SpecError(path + ": " + e.what());
    }
}

force_model::Material parse_material(const nlohmann::json& material) {
    nlohmann::json spec = probe_spec();
    spec["material"] = material;
    return force_model::parse_run_spec(spec).material;
}

}  // namespace cutload::app
