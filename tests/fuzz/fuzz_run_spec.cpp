// Fuzz target: a run spec's JSON text (docs/fuzzing.md).
#include "fuzz_support.hpp"

#include "force_model/force_model.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace cutload::fuzz;
    try {
        const cutload::force_model::RunSpec spec = cutload::force_model::parse_run_spec_text(as_text(data, size), "fuzz.json");
        check_output(cutload::force_model::to_json(spec));
    } catch (const cutload::force_model::SpecError& e) {
        check_output(nlohmann::json(e.what()));
    }
    return 0;
}
