// Internal: stage "blocks" - the NC block running at each grid sample.
#pragma once

#include "stages/stage.hpp"

#include <deque>
#include <utility>

namespace cutload::motion_io::detail {

// Accepts sessions, block readings and grid samples; emits sessions and grid samples with their
// block: the last block reading at or before the sample's time (before the first reading, the
// block first read, which was already running; -1 without any).
class BlockAttribution final : public Stage {
public:
    BlockAttribution() : Stage("blocks") {}
    Flows accepts() const override { return Flow::Sessions | Flow::Blocks | Flow::Grid; }
    Flows emits() const override { return Flow::Sessions | Flow::Grid; }
    void begin_session() override;
    void record(const Record& r) override { readings_.emplace_back(r.t_s, r.block); }
    void grid(std::span<GridSample> batch) override;

private:
    std::deque<std::pair<double, std::int32_t>> readings_;   // not yet passed by the grid
    std::int32_t current_ = -1;
};

}  // namespace cutload::motion_io::detail
