// app::predict_run on the bundled demo: what `cutload predict --program` and the service's run
// jobs asserted before they called it (tests/cli/test_program_cli.cpp, tests/server/test_program.cpp,
// tests/server/test_runs.cpp), the same forces as the engine called directly, progress that only
// goes forward and ends at 1, and a cancel honoured in every phase.
#include "app_fixtures.hpp"

#include "app/predict_run.hpp"

#include <algorithm>
#include <map>
#include <set>

using namespace cutload;
using namespace cutload::apptest;

TEST_CASE("predict_run: the demo with its program gives the results the CLI and the service gave", "[app][predict]") {
    Recorder rec;
    const app::RunResult r = app::predict_run(demo_input(true), rec.control());

    // Progress: every phase in order, never back, ending at (Done, 1).
    rec.require_monotonic();
    CHECK(rec.phases() == std::vector<app::Phase>{app::Phase::Ingest, app::Phase::Program, app::Phase::Mapping,
                                                  app::Phase::Predict, app::Phase::Commanded, app::Phase::Done});
    REQUIRE(!rec.calls.empty());
    CHECK(rec.calls.back() == std::pair{app::Phase::Done, 1.0});
    // The two predictions share the bar by duration: the actual one ends where the commanded one starts.
    REQUIRE(rec.started(app::Phase::Commanded));
    CHECK(*rec.reached(app::Phase::Predict) == Approx(*rec.started(app::Phase::Commanded)));
    CHECK(*rec.started(app::Phase::Commanded) > 0.3);
    CHECK(*rec.started(app::Phase::Commanded) < 0.7);

    // The service's expectations: the demo log names its blocks, the mapping agrees with them.
    REQUIRE(r.program);
    REQUIRE(r.commanded);
    CHECK_FALSE(r.program->mapped);
    REQUIRE(r.program->mapping.quality.agreement);
    CHECK(*r.program->mapping.quality.agreement > 0.95);
    CHECK(r.program->mapping.quality.matched_fraction > 0.99);
    const force_model::Prediction& cmd = r.commanded->commanded;
    double commanded_peak_N = 0;
    for (const auto& b : cmd.blocks) commanded_peak_N = std::max(commanded_peak_N, b.peak_force_N);
    CHECK(commanded_peak_N > 100);
    std::size_t cutting = 0;
    double worst_deviation_mm = 0, worst_deficit_pct = 0;
    for (const auto& b : r.commanded->blocks) {
        if (b.actual_peak_force_N < 50) continue;
        ++cutting;
        CHECK(b.commanded_peak_force_N > 0);
        CHECK(b.force_difference_N == Approx(b.actual_peak_force_N - b.commanded_peak_force_N).margin(1e-6));
        worst_deviation_mm = std::max(worst_deviation_mm, b.max_deviation_mm);
        worst_deficit_pct = std::max(worst_deficit_pct, b.feed_deficit_pct);
    }
    CHECK(cutting > 30);
    CHECK(worst_deviation_mm > 0.2);
    CHECK(worst_deficit_pct > 20);
    CHECK(std::count(cmd.block_names.begin(), cmd.block_names.end(), "N70") == 1);

    // The CLI's expectations: BLOCKS.csv's actual peaks are the comparison's, blocks over 100 N
    // are many, and the commanded forces end earlier (no acceleration) but not by much once warped.
    std::map<std::string, const force_model::BlockComparison*> by_name;
    for (const auto& c : r.commanded->blocks) by_name[c.block] = &c;
    std::size_t over_100_N = 0;
    for (const auto& b : r.prediction.blocks) {
        INFO(b.block);
        const auto it = by_name.find(b.block);
        REQUIRE(it != by_name.end());
        CHECK(b.peak_force_N == Approx(it->second->actual_peak_force_N).margin(0.002));
        if (b.peak_force_N > 100) ++over_100_N;
    }
    CHECK(over_100_N > 30);
    REQUIRE(cmd.samples.size() > 1000);
    CHECK(cmd.samples.back().t_s < r.prediction.samples.back().t_s);
    const double warped_end_s = r.commanded->to_actual_time(cmd.samples.back().t_s);
    CHECK(warped_end_s <= r.motion.t_s.back() + 1e-6);
    CHECK(warped_end_s > r.prediction.samples.back().t_s - 0.5);

    // The service's demo run: blocks, removed material, a final stock.
    CHECK(r.prediction.blocks.size() > 3);
    double removed_mm3 = 0;
    for (const auto& b : r.prediction.blocks) removed_mm3 += b.removed_mm3;
    CHECK(removed_mm3 > 0);
    REQUIRE(r.prediction.final_stock);
    CHECK(force_model::stock_volume_mm3(*r.prediction.final_stock) == Approx(105.0 * 90 * 30 - removed_mm3).epsilon(0.01));

    // The same forces as the engine called directly on the log, as the front ends did before.
    motion_io::ReadOptions ro;
    const motion_io::MotionModel motion = motion_io::ingest(source_path("data/demo_dryrun.csv"), ro);
    REQUIRE(motion.t_s == r.motion.t_s);
    REQUIRE(motion.block == r.motion.block);
    force_model::PredictOptions po;
    po.device = force_model::Device::Cpu;
    const force_model::Prediction direct =
        force_model::predict(motion, force_model::load_run_spec(source_path("data/demo_run.json")), po);
    REQUIRE(direct.samples.size() == r.prediction.samples.size());
    std::size_t differing = 0;
    for (std::size_t i = 0; i < direct.samples.size(); ++i)
        differing += same_sample(direct.samples[i], r.prediction.samples[i]) ? 0 : 1;
    CHECK(differing == 0);
}

TEST_CASE("predict_run: a cancel is honoured in every phase, and nothing after it runs", "[app][predict][cancel]") {
    using app::Phase;
    for (const Phase phase : {Phase::Ingest, Phase::Program, Phase::Mapping, Phase::Predict, Phase::Commanded}) {
        DYNAMIC_SECTION("cancelled in " << app::phase_name(phase)) {
            Recorder rec;
            rec.cancel_at = phase;
            CHECK_THROWS_AS(app::predict_run(demo_input(true), rec.control()), force_model::Cancelled);
            rec.require_monotonic();
            REQUIRE(!rec.phases().empty());
            CHECK(rec.phases().back() == phase);   // no later phase started
            // Inside a prediction the engine stops at its next check: the phase made no progress.
            CHECK(*rec.reached(phase) == *rec.started(phase));
        }
    }
}

TEST_CASE("predict_run: a cancel set before the start computes nothing", "[app][predict][cancel]") {
    Recorder rec;
    rec.cancel = true;
    CHECK_THROWS_AS(app::predict_run(demo_input(false), rec.control()), force_model::Cancelled);
    CHECK(rec.calls.empty());
}

TEST_CASE("predict_run: a step that fails after a cancel ends in the cancel", "[app][predict][cancel]") {
    // The service deletes a run's files right after cancelling the job that reads them.
    app::RunInput in = demo_input(true);
    in.log_path += ".deleted";
    CHECK_THROWS_AS(app::predict_run(in), motion_io::IngestError);
    Recorder rec;
    rec.cancel_at = app::Phase::Ingest;
    CHECK_THROWS_AS(app::predict_run(in, rec.control()), force_model::Cancelled);
}

TEST_CASE("predict_run: without a program, Predict is the whole bar, a log of one sample is refused naming it",
          "[app][predict]") {
    const Scratch dir("predict_slot");
    write_slot(dir);
    app::RunInput in;
    in.log_path = (dir / "slot.csv").string();
    in.spec = force_model::load_run_spec((dir / "slot.json").string());
    Recorder rec;
    const app::RunResult r = app::predict_run(in, rec.control());
    rec.require_monotonic();
    CHECK(rec.phases() == std::vector<app::Phase>{app::Phase::Ingest, app::Phase::Predict, app::Phase::Done});
    CHECK(*rec.reached(app::Phase::Predict) == Approx(1.0));
    CHECK_FALSE(r.program);
    CHECK_FALSE(r.commanded);
    // The slot's peak passes its 400 N limit (the CLI test's optimizer raises the feed towards it).
    CHECK(r.prediction.samples.size() > 1000);

    write_text(dir / "one.csv", "t,x,y,z,feed,spindle\n0,-6,5,-2,1200,10000\n");
    in.log_path = (dir / "one.csv").string();
    CHECK_THROWS_AS(app::predict_run(in), motion_io::IngestError);
}

TEST_CASE("predict_run: a base stock passed as bytes is the one loaded from a file", "[app][predict][stock]") {
    // The slot twice, as the service's base_run test does: the second pass on the first one's
    // stock cuts (almost) only air, whether the stock came from a file or from bytes.
    const Scratch dir("predict_stock");
    write_slot(dir);
    app::RunInput in;
    in.log_path = (dir / "slot.csv").string();
    in.spec = force_model::load_run_spec((dir / "slot.json").string());
    const app::RunResult first = app::predict_run(in);
    const std::string path = (dir / "final.stock").string();
    force_model::save_stock(*first.prediction.final_stock, path);
    const std::string bytes = force_model::save_stock_bytes(*first.prediction.final_stock);
    CHECK(bytes == read_text(path));

    const force_model::StockPtr from_file = force_model::load_stock(path);
    const force_model::StockPtr from_bytes = force_model::load_stock_bytes(bytes, "run 1 stock");
    in.base_stock = from_file.get();
    const app::RunResult on_file = app::predict_run(in);
    in.base_stock = from_bytes.get();
    const app::RunResult on_bytes = app::predict_run(in);

    auto removed = [](const force_model::Prediction& p) {
        double v = 0;
        for (const auto& b : p.blocks) v += b.removed_mm3;
        return v;
    };
    CHECK(removed(first.prediction) > 100);
    CHECK(removed(on_file.prediction) < 0.05 * removed(first.prediction));
    REQUIRE(on_bytes.prediction.samples.size() == on_file.prediction.samples.size());
    std::size_t differing = 0;
    for (std::size_t i = 0; i < on_file.prediction.samples.size(); ++i)
        differing += same_sample(on_file.prediction.samples[i], on_bytes.prediction.samples[i]) ? 0 : 1;
    CHECK(differing == 0);
    CHECK(force_model::save_stock_bytes(*on_bytes.prediction.final_stock) ==
          force_model::save_stock_bytes(*on_file.prediction.final_stock));
}

TEST_CASE("predict_run: a window counts its own rows against the limits, and is the whole run's rows there",
          "[app][predict][window]") {
    const app::RunResult whole = app::predict_run(demo_input(true));
    REQUIRE(whole.prediction.samples.size() > 100000);
    app::RunInput in = demo_input(true);
    in.window = force_model::TimeWindow{5, 6};
    // Too small for the whole log's rows held in memory, and for its commanded run's: not for 1 s.
    in.limits.max_force_rows = double(whole.prediction.samples.size()) / 4;
    const app::RunResult win = app::predict_run(in);
    CHECK_FALSE(win.commanded);   // the comparison is the whole run's
    REQUIRE(win.program);         // the program still names the blocks
    CHECK(win.work.force_rows < in.limits.max_force_rows);
    CHECK(win.work.commanded_rows == 0);
    CHECK(win.work.memory_mb < whole.work.memory_mb);
    std::vector<force_model::ForceSample> expected;
    for (const auto& s : whole.prediction.samples)
        if (s.t_s >= 5 && s.t_s < 6) expected.push_back(s);
    REQUIRE(win.prediction.samples.size() == expected.size());
    REQUIRE(expected.size() > 10000);
    std::size_t differing = 0;
    for (std::size_t k = 0; k < expected.size(); ++k) {
        const force_model::ForceSample &a = win.prediction.samples[k], &b = expected[k];
        differing += !(a.t_s == b.t_s && a.block == b.block && a.tool == b.tool && a.fx_N == b.fx_N && a.fy_N == b.fy_N &&
                       a.fz_N == b.fz_N && a.torque_Nm == b.torque_Nm && a.chip_mm == b.chip_mm &&
                       a.removed_mm3 == b.removed_mm3 && a.holder_contact == b.holder_contact);
    }
    CHECK(differing == 0);
    CHECK(win.prediction.block_names == whole.prediction.block_names);
    // The whole log's estimate is refused at that limit.
    in.window.reset();
    CHECK_THROWS_AS(app::predict_run(in), app::TooMuchWork);
    // With the log's commanded positions, or a machine, a window is refused by name.
    in.window = force_model::TimeWindow{5, 6};
    in.program.reset();
    in.commanded_from_log = true;
    CHECK_THROWS_WITH(app::predict_run(in), Catch::Contains("window"));
}
