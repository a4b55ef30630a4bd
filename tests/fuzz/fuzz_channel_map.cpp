// Fuzz target: a channel map's JSON text, for CSV logs and for SHDR logs (docs/fuzzing.md).
#include "fuzz_support.hpp"

#include "channel_map.hpp"   // motion_io's own header (a map is read only through ReadOptions::map_file)

namespace mio = cutload::motion_io;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace cutload::fuzz;
    for (const mio::Format f : {mio::Format::Csv, mio::Format::Shdr}) {
        try {
            const mio::detail::ChannelMap m = mio::detail::parse_channel_map(as_text(data, size), "fuzz map", f);
            if (f == mio::Format::Shdr) {
                const mio::ShdrKeyMap k = mio::detail::shdr_key_map(m);
                try {
                    (void)mio::shdr_unit_factors(k);
                } catch (const std::invalid_argument& e) {
                    check_output(nlohmann::json(e.what()));   // an unknown unit, said when the log is read
                }
            }
        } catch (const mio::IngestError& e) {
            check_output(nlohmann::json(e.what()));
        }
    }
    return 0;
}
