// Fuzz target: FORCES.bin read back for a comparison (docs/fuzzing.md, docs/formats.md).
#include "fuzz_support.hpp"

#include "force_model/compare.hpp"

#include <cmath>
#include <sstream>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace cutload::fuzz;
    namespace fm = cutload::force_model;
    std::istringstream in{std::string(as_text(data, size))};
    try {
        const fm::PredictedTrace t = fm::read_forces_bin(in, "fuzz.bin");
        if (t.samples.size() < 2) broken("fewer than two rows accepted");
        for (std::size_t i = 0; i < t.samples.size(); ++i) {
            const fm::ForceSample& s = t.samples[i];
            if (!std::isfinite(s.t_s) || !std::isfinite(s.fx_N) || !std::isfinite(s.fy_N) || !std::isfinite(s.fz_N))
                broken("non-finite value in row " + std::to_string(i));
            if (i > 0 && s.t_s < t.samples[i - 1].t_s) broken("time goes back in row " + std::to_string(i));
            if (s.block < -1 || s.block >= static_cast<std::int64_t>(t.block_names.size()))
                broken("block index out of range in row " + std::to_string(i));
        }
        check_output(nlohmann::json(t.block_names));
    } catch (const fm::MeasurementError& e) {
        check_output(nlohmann::json(e.what()));
    }
    return 0;
}
