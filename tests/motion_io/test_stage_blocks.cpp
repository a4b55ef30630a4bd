// Stage "blocks": the block running at each grid sample.
#include "stage_rig.hpp"
#include "stages/blocks.hpp"

#include <catch2/catch.hpp>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;

TEST_CASE("blocks: the last block reading at or before each sample, before the first, the first", "[blocks]") {
    StageRig rig{std::make_unique<detail::BlockAttribution>(), Flow::Sessions | Flow::Blocks | Flow::Grid,
                 Flow::Sessions | Flow::Grid};
    rig.feeder->begin();
    rig.feeder->session_record(block(0.10, 4));
    rig.feeder->session_record(block(0.20, 5));
    rig.feeder->session_record(block(0.30, 6));
    for (double t : {0.05, 0.10, 0.15, 0.2, 0.29, 0.31}) {
        detail::GridSample s;
        s.t_s = t;
        rig.feeder->grid(s);
    }
    std::vector<std::int32_t> got;
    for (const auto& s : rig.out->samples) got.push_back(s.block);
    CHECK(got == std::vector<std::int32_t>{4, 4, 4, 5, 5, 6});
    rig.feeder->end();
    rig.feeder->begin();   // a new session without block readings
    detail::GridSample s;
    s.t_s = 1.0;
    rig.feeder->grid(s);
    CHECK(rig.out->samples.back().block == -1);
}

TEST_CASE("blocks: tool readings travel with the blocks and give each sample its tool on their own timeline",
          "[blocks]") {
    StageRig rig{std::make_unique<detail::BlockAttribution>(), Flow::Sessions | Flow::Blocks | Flow::Grid,
                 Flow::Sessions | Flow::Grid};
    rig.feeder->begin();
    // A tool change (T2) between two block readings: the tool follows its own readings, not the
    // block's, and the block its own.
    rig.feeder->session_record(block(0.10, 4));
    rig.feeder->session_record(value(detail::Chan::Tool, 0.12, 1));
    rig.feeder->session_record(value(detail::Chan::Tool, 0.25, 2));
    rig.feeder->session_record(block(0.30, 5));
    for (double t : {0.05, 0.12, 0.2, 0.25, 0.29, 0.31}) {
        detail::GridSample s;
        s.t_s = t;
        rig.feeder->grid(s);
    }
    std::vector<std::int32_t> blocks, tools;
    for (const auto& s : rig.out->samples) blocks.push_back(s.block), tools.push_back(s.tool);
    CHECK(blocks == std::vector<std::int32_t>{4, 4, 4, 4, 4, 5});
    // Before the first tool reading, the tool first read was already in the spindle.
    CHECK(tools == std::vector<std::int32_t>{1, 1, 1, 2, 2, 2});
    rig.feeder->end();
    rig.feeder->begin();   // a new session without tool readings
    detail::GridSample s;
    s.t_s = 1.0;
    rig.feeder->grid(s);
    CHECK(rig.out->samples.back().tool == -1);
}
