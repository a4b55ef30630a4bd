// Reading NC programs from text in the reader's tests: each suite passes its own options (its
// defaults stay in its file), and the helpers that do not depend on them live here once.
#pragma once

#include "motion_io/nc_program.hpp"

#include <catch2/catch.hpp>

#include <string>

namespace cutload::nctest {

// `text` read as the file "t.nc".
inline motion_io::NcProgram read_text(const std::string& text, const motion_io::NcReadOptions& o) {
    return motion_io::parse_nc_program(text, "t.nc", o);
}

// The reader's refusal of `text`, or "(no error)" when it reads.
inline std::string read_error(const std::string& text, const motion_io::NcReadOptions& o) {
    try {
        read_text(text, o);
    } catch (const motion_io::NcProgramError& e) {
        return e.what();
    }
    return "(no error)";
}

// The program's first block of that name; fails the test when there is none.
inline const motion_io::NcBlock& named(const motion_io::NcProgram& p, const std::string& name) {
    for (const motion_io::NcBlock& b : p.blocks)
        if (b.name == name) return b;
    FAIL("no block " << name);
    throw;   // not reached: FAIL throws
}

}  // namespace cutload::nctest
