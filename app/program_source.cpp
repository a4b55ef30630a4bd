#include "app/program_source.hpp"
#include "app/tool_centre_point.hpp"

#include <fmt/format.h>

#include <fstream>
#include <sstream>

namespace cutload::app {

namespace {

motion_io::NcProgram read_as_written(const ProgramSource& source, const motion_io::NcReadOptions& ro) {
    if (source.text) return motion_io::parse_nc_program(*source.text, source.name.empty() ? source.path : source.name, ro);
    if (source.name.empty()) return motion_io::read_nc_program(source.path, ro);
    // Stored under another name than the one its errors should show (an upload kept on disk).
    std::ifstream in(source.path, std::ios::binary);
    if (!in) throw motion_io::NcProgramError(fmt::format("{}: cannot open the NC program", source.name));
    std::ostringstream text;
    text << in.rdbuf();
    if (text.str().empty()) throw motion_io::NcProgramError(fmt::format("{}: the NC program is empty", source.name));
    return motion_io::parse_nc_program(text.str(), source.name, ro);
}

}  // namespace

motion_io::NcProgram read_program(const ProgramSource& source, const force_model::RunSpec& spec,
                                  std::optional<std::array<double, 3>> start_mm) {
    const motion_io::NcReadOptions ro = program_read_options(source.settings, spec, start_mm);
    motion_io::NcProgram program = read_as_written(source, ro);
    // Every later stage reads machine axes; a tool-centre-point block becomes them here.
    if (ro.tool_centre_point && has_tool_centre_point(program)) program = machine_axis_program(program, *ro.tool_centre_point);
    return program;
}

}  // namespace cutload::app
