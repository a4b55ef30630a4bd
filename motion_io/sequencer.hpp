// Internal: the "align channels" stage (see sequencer.cpp).
#pragma once

#include "pipeline.hpp"

#include <array>
#include <deque>

namespace cutload::motion_io::detail {

class Sequencer final : public RecordSink {
public:
    Sequencer(Diagnostics& diag, SessionConsumer& out, bool event_driven, StageLimits limits = {});
    void push(const Record& r) override;
    void finish() override;

private:

    static constexpr std::size_t kIntervalRing = 15;
    struct Held {
        bool have = false;
        Record last;
        std::array<double, kIntervalRing> intervals{};
        std::size_t n_intervals = 0;
    };

    void drain(bool all);
    void release(const Record& r);
    void flush_axes();
    void forward_held(const Record& r);
    void end_session();

    Diagnostics& diag_;
    SessionConsumer& out_;
    bool event_driven_;
    StageLimits limits_;
    // Records in time order (equal times in file order). Logs arrive nearly sorted, so an
    // insertion from the back costs O(1) on average.
    std::deque<Record> queue_;
    bool have_max_ = false;
    double max_t_ = 0;
    bool in_session_ = false;
    double last_t_ = 0;
    Record axes_;
    unsigned axes_known_ = 0;
    bool axis_pending_ = false;
    double axis_t_ = 0;
    Held held_pos_, held_spindle_;
};

}  // namespace cutload::motion_io::detail
