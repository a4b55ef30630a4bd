// The reader stage's records handed out one by one (motion_io/readings.hpp).
#include "motion_io/readings.hpp"
#include "pipeline.hpp"

namespace cutload::motion_io {
namespace {

class CallbackSink final : public detail::RecordSink {
public:
    CallbackSink(const detail::BlockTable& blocks, const std::function<void(const LogReading&)>& fn)
        : blocks_(blocks), fn_(fn) {}
    void push(const detail::Record& r) override {
        LogReading out;
        out.t_s = r.t_s;
        out.line = r.line;
        switch (r.ch) {
            case detail::Chan::Feed: out.channel = LogReading::Channel::Feed; break;
            case detail::Chan::Spindle: out.channel = LogReading::Channel::Spindle; break;
            case detail::Chan::Block:
                out.channel = LogReading::Channel::Block;
                out.block = blocks_.names()[static_cast<std::size_t>(r.block)];
                break;
            case detail::Chan::Tool: return;   // a CSV tool column: not a reading the replay sends
            default: out.channel = LogReading::Channel::Position; break;   // CSV rows carry x, y, z together
        }
        for (int k = 0; k < 3; ++k) out.value[k] = r.v[k];
        fn_(out);
    }
    void finish() override {}

private:
    const detail::BlockTable& blocks_;
    const std::function<void(const LogReading&)>& fn_;
};

}  // namespace

void read_csv_readings(const std::string& path, const ReadOptions& opt,
                       const std::function<void(const LogReading&)>& on_reading) {
    detail::Diagnostics diag(path);
    detail::BlockTable blocks;
    CallbackSink sink(blocks, on_reading);
    detail::read_csv(path, opt, diag, blocks, sink);
}

Format detect_log_format(const std::string& path) {
    detail::Diagnostics diag(path);
    return detail::detect_format(path, diag);
}

}  // namespace cutload::motion_io
