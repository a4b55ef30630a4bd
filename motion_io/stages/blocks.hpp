// Internal: stage "blocks" - the NC block running at each grid sample.
#pragma once

#include "stages/stage.hpp"

#include <deque>
#include <utility>

namespace cutload::motion_io::detail {

// Accepts sessions, block and tool readings and grid samples; emits sessions and grid samples with
// their block and tool: the last reading at or before the sample's time (before the first reading,
// the value first read, which was already in force; -1 without any).
class BlockAttribution final : public Stage {
public:
    BlockAttribution() : Stage("blocks") {}
    Flows accepts() const override { return Flow::Sessions | Flow::Blocks | Flow::Grid; }
    Flows emits() const override { return Flow::Sessions | Flow::Grid; }
    void begin_session() override;
    void record(const Record& r) override;
    void grid(std::span<GridSample> batch) override;

private:
    // Readings of one channel not yet passed by the grid, and the value in force.
    struct Channel {
        std::deque<std::pair<double, std::int32_t>> readings;
        std::int32_t current = -1;
        std::int32_t at(double t_s);
    };
    Channel blocks_, tools_;
};

}  // namespace cutload::motion_io::detail
