// Fuzz target: an NC program, parsed, turned into commanded motion when that is small, and written
// back with new feeds (docs/fuzzing.md).
#include "fuzz_support.hpp"

#include "motion_io/commanded.hpp"
#include "motion_io/nc_program.hpp"

#include <cmath>
#include <stdexcept>

namespace mio = cutload::motion_io;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace cutload::fuzz;
    static const mio::NcReadOptions opt = [] {
        mio::NcReadOptions o;
        const double zero[3] = {0, 0, 0};
        o.work_offsets_mm = mio::default_work_offsets(zero);   // G54-G59 all usable
        return o;
    }();
    try {
        const mio::NcProgram p = mio::parse_nc_program(std::string(as_text(data, size)), "fuzz.nc", opt);
        for (const mio::NcBlock& b : p.blocks)
            for (const double v : {b.start_mm[0], b.start_mm[1], b.start_mm[2], b.end_mm[0], b.end_mm[1], b.end_mm[2],
                                   b.feed_mm_min, b.spindle_rpm, b.dwell_s, b.sweep_rad, mio::block_length_mm(b)})
                if (!std::isfinite(v)) broken("non-finite value in block " + b.name);
        mio::CommandedOptions c;
        c.step_s = 0.01;
        const double samples = mio::commanded_sample_count(p, c);
        if (!(samples >= 0)) broken("negative or NaN commanded sample count");
        if (samples <= 1e5) {
            try {
                const mio::MotionModel m = mio::commanded_motion(p, c);
                for (std::size_t i = 0; i < m.size(); ++i)
                    for (const double v : {m.t_s[i], m.x_mm[i], m.y_mm[i], m.z_mm[i], m.vx_mm_s[i], m.vy_mm_s[i],
                                           m.vz_mm_s[i], m.spindle_rpm[i], m.spindle_angle_deg[i]})
                        if (!std::isfinite(v)) broken("non-finite value in the commanded motion");
            } catch (const std::invalid_argument&) {
                // a program without motion
            }
        }
        (void)mio::rewrite_feeds(p, std::vector<double>(p.blocks.size(), 1234.0));
    } catch (const mio::NcProgramError& e) {
        check_output(nlohmann::json(e.what()));
    }
    return 0;
}
