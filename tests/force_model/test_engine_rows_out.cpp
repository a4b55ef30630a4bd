// PredictOptions::rows_out: a long run's rows leave the engine as they become final, in pieces,
// instead of being held for the whole run. The pieces must put together the very rows predict()
// returns otherwise, and the block summaries, stats and final stock must not change.
#include "force_model/engine.hpp"
#include "force_model/engine_fixtures.hpp"

#include <catch2/catch.hpp>

#include <cstring>

using namespace cutload;
using namespace cutload::enginetest;
using force_model::Device;


TEST_CASE("rows_out: the rows handed out in pieces are predict()'s rows, blocks, stats and stock") {
    // About 3 s of slotting and side cutting at 10000 rpm with an air move and a plunge between:
    // some 100 000 rows, so the rows leave in several pieces, one of them in the air stretch.
    const auto spec = base_spec(120, 20, 10);
    const auto m = legs_motion({-6, 10, 7},
                               {{{126, 10, 7}, 3000, "slot"},
                                {{126, 10, 20}, 3000, "up"},
                                {{-6, 16, 20}, 6000, "back"},
                                {{-6, 16, 4}, 3000, "down"},
                                {{126, 16, 4}, 3000, "side"}});
    std::vector<Device> devices{Device::Cpu};
    if (opencl_available()) devices.push_back(Device::OpenCL);
    for (Device device : devices) {
        INFO((device == Device::Cpu ? "cpu" : "opencl"));
        force_model::PredictOptions held;
        held.device = device;
        const force_model::Prediction whole = force_model::predict(m, spec, held);
        REQUIRE(whole.samples.size() > 2 * force_model::kRowsOutPiece);

        std::vector<force_model::ForceSample> rows;
        std::size_t pieces = 0;
        force_model::PredictOptions streamed = held;
        streamed.rows_out = [&](std::span<const force_model::ForceSample> piece) {
            CHECK(!piece.empty());
            rows.insert(rows.end(), piece.begin(), piece.end());
            ++pieces;
        };
        const force_model::Prediction p = force_model::predict(m, spec, streamed);
        CHECK(p.samples.empty());
        CHECK(pieces >= 2);
        REQUIRE(rows.size() == whole.samples.size());
        std::size_t differ = 0;
        for (std::size_t i = 0; i < rows.size(); ++i) differ += same_row(rows[i], whole.samples[i]) ? 0 : 1;
        CHECK(differ == 0);

        REQUIRE(p.blocks.size() == whole.blocks.size());
        for (std::size_t b = 0; b < p.blocks.size(); ++b) {
            CHECK(p.blocks[b].block == whole.blocks[b].block);
            CHECK(p.blocks[b].peak_force_N == whole.blocks[b].peak_force_N);
            CHECK(p.blocks[b].mean_force_N == whole.blocks[b].mean_force_N);
            CHECK(p.blocks[b].removed_mm3 == whole.blocks[b].removed_mm3);
            CHECK(p.blocks[b].flags.size() == whole.blocks[b].flags.size());
        }
        CHECK(p.stats.steps == whole.stats.steps);
        CHECK(p.stats.cutting_steps == whole.stats.cutting_steps);
        CHECK(p.stats.cutting_steps > 0);
        CHECK(force_model::stock_volume_mm3(*p.final_stock) == force_model::stock_volume_mm3(*whole.final_stock));
    }
}

TEST_CASE("rows_out: the row limit counts the rows already handed out") {
    const auto spec = base_spec(120, 20, 10);
    // About 160 000 rows: the limit falls after the first piece has left.
    const auto m = legs_motion({-6, 10, 7}, {{{126, 10, 7}, 3000, "slot"}, {{126, 14, 7}, 3000, "over"}, {{-6, 14, 7}, 3000, "back"}});
    force_model::PredictOptions o;
    o.device = Device::Cpu;
    std::size_t handed = 0;
    o.rows_out = [&](std::span<const force_model::ForceSample> piece) { handed += piece.size(); };
    // Past a piece's worth with room for a batch, which may complete many rows at once.
    o.max_rows = 100000;
    CHECK_THROWS_AS(force_model::predict(m, spec, o), force_model::TooManyRows);
    CHECK(handed >= force_model::kRowsOutPiece);   // the limit was reached after rows had left
    CHECK(handed <= o.max_rows);
}
