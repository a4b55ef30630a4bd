// A constant shift of every time stamp of a log (a client clock started elsewhere) must not move
// a prediction: the demo moved by its first stamp, 3.028 ms, once changed the recovered CNC clock
// enough to move two blocks' (N230, N440) mean forces by 17-20 %. The motion itself is checked to
// the last digits in tests/motion_io/test_clock_origin.cpp; here the forces, block by block.
#include "app_fixtures.hpp"
#include "../motion_io/test_helpers.hpp"

#include <catch2/catch.hpp>

#include <cmath>

using namespace cutload;
using namespace cutload::apptest;

TEST_CASE("predict_run: the demo shifted by 3.028 ms gives the same block forces", "[app][predict][clock]") {
    Scratch dir("time_origin");
    const std::filesystem::path shifted = dir / "demo_shifted.csv";
    write_text(shifted, motion_io::test::shift_time_columns(read_text(source_path("data/demo_dryrun.csv")), 3028));
    const app::RunResult base = app::predict_run(demo_input(false));
    app::RunInput in = demo_input(false);
    in.log_path = shifted.string();
    const app::RunResult moved = app::predict_run(in);

    const auto& b0 = base.prediction.blocks;
    const auto& b1 = moved.prediction.blocks;
    REQUIRE(b1.size() == b0.size());
    REQUIRE(b0.size() > 20);
    std::size_t compared = 0;
    for (std::size_t i = 0; i < b0.size(); ++i) {
        INFO("block " << b0[i].block << ": mean " << b0[i].mean_force_N << " N, shifted " << b1[i].mean_force_N
                      << " N; peak " << b0[i].peak_force_N << " N, shifted " << b1[i].peak_force_N << " N");
        CHECK(b1[i].block == b0[i].block);
        CHECK(std::fabs(b1[i].mean_force_N - b0[i].mean_force_N) <= 1e-3 * std::max(b0[i].mean_force_N, 1.0));
        CHECK(std::fabs(b1[i].peak_force_N - b0[i].peak_force_N) <= 1e-3 * std::max(b0[i].peak_force_N, 1.0));
        compared += b0[i].mean_force_N > 1.0;
    }
    CHECK(compared >= 10);   // blocks that cut
}
