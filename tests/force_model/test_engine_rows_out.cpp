// PredictOptions::rows_out: a long run's rows leave the engine as they become final, in pieces,
// instead of being held for the whole run. The pieces must put together the very rows predict()
// returns otherwise, and the block summaries, stats and final stock must not change. A prediction
// that keeps its rows summarises and checks them in pieces too, during the walk: its summaries
// must be those of its own rows, worked out here from the rows alone.
#include "force_model/engine.hpp"
#include "force_model/engine_fixtures.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <string>

using namespace cutload;
using namespace cutload::enginetest;
using force_model::Device;

namespace {

// About 3 s of slotting and side cutting at 10000 rpm with an air move and a plunge between (120 x
// 20 x 10 mm stock): some 100 000 rows, so the rows leave in several pieces, one of them in the
// air stretch.
motion_io::MotionModel slot_air_side() {
    return legs_motion({-6, 10, 7}, {{{126, 10, 7}, 3000, "slot"},
                                     {{126, 10, 20}, 3000, "up"},
                                     {{-6, 16, 20}, 6000, "back"},
                                     {{-6, 16, 4}, 3000, "down"},
                                     {{126, 16, 4}, 3000, "side"}});
}

std::vector<Device> devices() {
    std::vector<Device> d{Device::Cpu};
    if (opencl_available()) d.push_back(Device::OpenCL);
    return d;
}

}  // namespace

TEST_CASE("rows_out: the rows handed out in pieces are predict()'s rows, blocks, stats and stock") {
    const auto spec = base_spec(120, 20, 10);
    const auto m = slot_air_side();
    for (Device device : devices()) {
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

TEST_CASE("rows: a kept run's block summaries are those of its rows, summed here in row order") {
    // Several watch pieces, five blocks.
    const auto spec = base_spec(120, 20, 10);
    const auto m = slot_air_side();
    for (Device device : devices()) {
        INFO((device == Device::Cpu ? "cpu" : "opencl"));
        force_model::PredictOptions o;
        o.device = device;
        const force_model::Prediction p = force_model::predict(m, spec, o);
        REQUIRE(p.samples.size() > 8 * 4096);
        struct Sums {
            double peak_N = 0, removed_mm3 = 0, peak_torque_Nm = 0;
        };
        std::map<std::string, Sums> by_block;
        for (const force_model::ForceSample& r : p.samples) {
            Sums& s = by_block[p.block_names.at(std::size_t(r.block))];
            const double f = std::sqrt(double(r.fx_N) * r.fx_N + double(r.fy_N) * r.fy_N + double(r.fz_N) * r.fz_N);
            s.peak_N = std::max(s.peak_N, f);
            s.peak_torque_Nm = std::max(s.peak_torque_Nm, double(r.torque_Nm));
            s.removed_mm3 += r.removed_mm3;
        }
        REQUIRE(p.blocks.size() == by_block.size());
        double removed_total_mm3 = 0;
        for (const force_model::BlockSummary& b : p.blocks) {
            INFO(b.block);
            REQUIRE(by_block.count(b.block) == 1);
            const Sums& s = by_block.at(b.block);
            CHECK(b.peak_force_N == s.peak_N);
            CHECK(b.peak_torque_Nm == s.peak_torque_Nm);
            CHECK(b.removed_mm3 == s.removed_mm3);
            removed_total_mm3 += b.removed_mm3;
        }
        CHECK(by_block.at("slot").peak_N > 100);   // a full slot in aluminium: the check has teeth
        CHECK(by_block.at("up").removed_mm3 < by_block.at("slot").removed_mm3);
        CHECK(removed_total_mm3 > 0);
    }
}

TEST_CASE("rows: a non-finite force is refused, whether the rows are kept or handed out") {
    // A coefficient past float's range makes the kernels' forces infinite: an engine fault that
    // must be reported, not written.
    auto spec = base_spec(40, 20, 10);
    spec.material.Ktc_N_mm2 = 1e300;
    const auto m = legs_motion({-6, 10, 7}, {{{30, 10, 7}, 3000, "slot"}});
    for (Device device : devices()) {
        INFO((device == Device::Cpu ? "cpu" : "opencl"));
        force_model::PredictOptions kept;
        kept.device = device;
        CHECK_THROWS_WITH(force_model::predict(m, spec, kept), Catch::Contains("non-finite value"));
        force_model::PredictOptions streamed = kept;
        std::size_t handed = 0;
        streamed.rows_out = [&](std::span<const force_model::ForceSample> piece) { handed += piece.size(); };
        CHECK_THROWS_WITH(force_model::predict(m, spec, streamed), Catch::Contains("non-finite value"));
    }
}
