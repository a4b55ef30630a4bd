// The chain of ingest stages: what each accepts and emits, binding by kind, inserting and removing
// stages by name.
#include "stage_rig.hpp"
#include "stages/standard.hpp"

#include <catch2/catch.hpp>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;
using cutload::motion_io::detail::Stage;

namespace {

// Counts positions on their way and passes them on: accepts nothing else.
class PositionTap final : public Stage {
public:
    PositionTap() : Stage("tap") {}
    Flows accepts() const override { return static_cast<Flows>(Flow::Positions); }
    Flows emits() const override { return static_cast<Flows>(Flow::Positions); }
    void record(const Record& r) override {
        ++positions;
        other_channels += r.ch != Chan::Pos;
        emit(Flow::Positions, r);
    }
    int positions = 0, other_channels = 0;
};

// Sees the grid after the blocks stage and checks that it is complete.
class GridTap final : public Stage {
public:
    GridTap() : Stage("grid_tap") {}
    Flows accepts() const override { return static_cast<Flows>(Flow::Grid); }
    Flows emits() const override { return static_cast<Flows>(Flow::Grid); }
    void grid(std::span<detail::GridSample> batch) override {
        for (const auto& s : batch) {
            ++samples;
            with_block += s.block >= 0;
        }
        emit(batch);
    }
    int samples = 0, with_block = 0;
};

struct Fixture {
    detail::Diagnostics diag{"chain.csv"};
    NoGrid sink;
};

std::unique_ptr<detail::StageChain> standard(Fixture& f, bool event_driven) {
    detail::ChainSettings s;
    s.event_driven = event_driven;
    return detail::make_ingest_chain(f.diag, f.sink, s);
}

// A straight move at 10 mm/s read every 6 ms, with a block and a spindle reading per row.
void push_move(detail::StageChain& chain, int rows) {
    for (int i = 0; i < rows; ++i) {
        const double t = 0.006 * i;
        chain.push(pos(t, 10 * t, 0, 0, static_cast<std::size_t>(i + 2)));
        chain.push(value(Chan::Spindle, t, 1000, static_cast<std::size_t>(i + 2)));
        chain.push(block(t, i < rows / 2 ? 0 : 1, static_cast<std::size_t>(i + 2)));
    }
    chain.finish();
}

}  // namespace

TEST_CASE("chain: the standard stages in order, polled and event-driven", "[chain]") {
    Fixture f;
    CHECK(standard(f, false)->names() == std::vector<std::string>{"validate", "sequence", "drop_jumps", "unwrap", "survey",
                                                                   "stale_repeats", "clock", "velocity", "resample",
                                                                   "spindle_angle", "blocks"});
    CHECK(standard(f, true)->names() == std::vector<std::string>{"validate", "sequence", "drop_jumps", "unwrap", "hold", "survey",
                                                                  "clock", "velocity", "resample", "spindle_angle",
                                                                  "blocks"});
}

TEST_CASE("chain: a removed stage whose output another one needs is refused, naming both", "[chain]") {
    Fixture f;
    auto chain = standard(f, false);
    CHECK_THROWS_WITH(chain->remove("velocity"),
                      Catch::Contains("'resample' accepts knots") && Catch::Contains("no stage before it emits"));
    auto chain2 = standard(f, false);
    CHECK_THROWS_WITH(chain2->remove("validate"), Catch::Contains("'sequence' accepts checked readings"));
    auto chain3 = standard(f, false);
    CHECK_THROWS_WITH(chain3->remove("spindle_angle"), Catch::Contains("spindle readings emitted by 'survey' reach no stage"));
    auto chain4 = standard(f, false);
    CHECK_THROWS_WITH(chain4->remove("no_such_stage"), Catch::Contains("no stage named 'no_such_stage'"));
}

TEST_CASE("chain: an optional stage is removed by name and the rest still fits", "[chain]") {
    Fixture f;
    auto chain = standard(f, false);
    CHECK(chain->remove("stale_repeats") != nullptr);
    CHECK(chain->find("stale_repeats") == nullptr);
    push_move(*chain, 50);   // still runs end to end
}

TEST_CASE("chain: an inserted stage gets only the kinds it accepts, the others bypass it", "[chain]") {
    Fixture f;
    auto chain = standard(f, false);
    auto tap = std::make_unique<PositionTap>();
    PositionTap* t = tap.get();
    chain->insert_before("clock", std::move(tap));
    auto grid = std::make_unique<GridTap>();
    GridTap* g = grid.get();
    chain->insert_after("blocks", std::move(grid));
    CHECK(chain->names()[6] == "tap");
    push_move(*chain, 50);
    CHECK(t->positions == 50);
    CHECK(t->other_channels == 0);   // spindle and block readings went around it
    CHECK(g->samples > 250);         // 0.294 s at 1 ms
    CHECK(g->with_block == g->samples);
}

TEST_CASE("chain: a stage that emits a kind already in flight, or accepts one not yet made, is refused", "[chain]") {
    // A second source of positions after the sequence stage: positions would come from two places.
    class PositionSource final : public Stage {
    public:
        PositionSource() : Stage("second_source") {}
        Flows accepts() const override { return static_cast<Flows>(Flow::Sessions); }
        Flows emits() const override { return Flow::Sessions | Flow::Positions; }
    };
    Fixture f;
    auto chain = standard(f, false);
    CHECK_THROWS_WITH(chain->insert_after("survey", std::make_unique<PositionSource>()),
                      Catch::Contains("'second_source' emits positions, which already flow past it"));
    auto chain2 = standard(f, false);
    CHECK_THROWS_WITH(chain2->insert_after("validate", std::make_unique<GridTap>()),
                      Catch::Contains("'grid_tap' accepts grid samples, which no stage before it emits"));
    auto chain3 = standard(f, false);
    CHECK_NOTHROW(chain3->insert_after("survey", std::make_unique<PositionTap>()));
}
