#include "app/program_source.hpp"

#include <fmt/format.h>

#include <fstream>
#include <sstream>

namespace cutload::app {

motion_io::NcProgram read_program(const ProgramSource& source, const force_model::RunSpec& spec,
                                  std::optional<std::array<double, 3>> start_mm) {
    const motion_io::NcReadOptions ro = program_read_options(source.settings, spec, start_mm);
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

}  // namespace cutload::app
