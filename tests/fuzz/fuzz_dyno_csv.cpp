// Fuzz target: a dynamometer record (DynoWare export or plain CSV) (docs/fuzzing.md).
#include "fuzz_support.hpp"

#include "force_model/measurement.hpp"

#include <cmath>
#include <sstream>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace cutload::fuzz;
    namespace fm = cutload::force_model;
    std::istringstream in{std::string(as_text(data, size))};
    try {
        fm::Measurement m = fm::read_measurement(in, "fuzz.csv");
        if (!(m.rate_Hz > 0) || !std::isfinite(m.rate_Hz) || !std::isfinite(m.t0_s)) broken("bad sampling grid");
        if (m.fy_N.size() != m.size() || m.fz_N.size() != m.size()) broken("channels differ in length");
        for (std::size_t i = 0; i < m.size(); ++i)
            if (!std::isfinite(m.fx_N[i]) || !std::isfinite(m.fy_N[i]) || !std::isfinite(m.fz_N[i]))
                broken("non-finite force at sample " + std::to_string(i));
        fm::map_to_tool_machine_axes(m, fm::kIdentityAxes);
        check_output(nlohmann::json(m.ignored_channels));
    } catch (const fm::MeasurementError& e) {
        check_output(nlohmann::json(e.what()));
    }
    return 0;
}
