// Where an NC program comes from and how to read it: a file (the CLI, the service's stored upload)
// or the text itself (an upload being checked), with the settings of the program's dialect and
// machine.
#pragma once

#include "app/program_run.hpp"
#include "force_model/force_model.hpp"
#include "motion_io/nc_program.hpp"

#include <array>
#include <optional>
#include <string>

namespace cutload::app {

struct ProgramSource {
    std::string path;                  // read from here unless `text` is given
    std::optional<std::string> text;   // the program itself
    std::string name;                  // names the program in errors ("prog.nc:12: ..."); empty: path
    ProgramSettings settings;
};

// The program interpreted in machine coordinates (program_read_options: the spec's setup offset
// as G54 unless the settings say otherwise, the machine at `start_mm` before the first block).
// Blocks under tool-centre-point control (G43.4/G43.5, with settings.tool_centre_point) come in
// machine-axis form (app::machine_axis_program).
// motion_io::NcProgramError naming file, line and word; an unreadable or empty file is one too.
motion_io::NcProgram read_program(const ProgramSource& source, const force_model::RunSpec& spec,
                                  std::optional<std::array<double, 3>> start_mm);

}  // namespace cutload::app
