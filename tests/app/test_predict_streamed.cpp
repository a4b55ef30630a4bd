// predict_run with RunInput::keep_motion false: a log alone is read in pieces and walked as it is
// read. Its FORCES.csv, BLOCKS.csv, stats, warnings, final stock and stock checkpoints are those of
// the run that holds the motion whole, byte for byte; a window recomputed later resumes at the
// checkpoints it wrote; runs that need the motion whole keep it.
#include "app_fixtures.hpp"
#include "app/checkpoints.hpp"
#include "force_model/stock.hpp"

#include <map>
#include <set>

using namespace cutload;
using namespace cutload::apptest;

namespace {

struct Outcome {
    app::RunResult r;
    std::string forces_csv, blocks_csv;
    std::map<std::string, std::string> checkpoints;   // file name -> bytes
    std::size_t motion_out_samples = 0, motion_out_pieces = 0;
};

Outcome run(app::RunInput in, bool keep_motion, const std::filesystem::path& dir) {
    Outcome o;
    const std::string forces = (dir / "FORCES.csv").string();
    const auto writer = force_model::open_forces_writer(forces);
    in.rows_out = app::RunInput::RowsOut{[&](const std::vector<std::string>& names, double) { writer->set_block_names(names); },
                                         [&](std::span<const force_model::ForceSample> rows) { writer->write(rows); }};
    in.keep_motion = keep_motion;
    in.motion_out = [&](const motion_io::MotionModel& piece) {
        o.motion_out_samples += piece.size();
        ++o.motion_out_pieces;
    };
    in.checkpoints = app::CheckpointFolder{dir / "checkpoints", 1.0};
    o.r = app::predict_run(in);
    writer->commit();
    o.forces_csv = read_text(forces);
    force_model::write_blocks_csv(o.r.prediction, (dir / "BLOCKS.csv").string());
    o.blocks_csv = read_text((dir / "BLOCKS.csv").string());
    for (const auto& e : std::filesystem::directory_iterator(dir / "checkpoints"))
        o.checkpoints[e.path().filename().string()] = read_text(e.path().string());
    return o;
}

void check_same(const Outcome& kept, const Outcome& streamed) {
    CHECK(kept.r.motion_kept);
    CHECK_FALSE(streamed.r.motion_kept);
    CHECK(streamed.r.motion.size() == 0);
    // The motion went out piece by piece instead, all of it.
    CHECK(kept.motion_out_samples == 0);
    CHECK(streamed.motion_out_samples == kept.r.motion.size());
    CHECK(streamed.motion_out_pieces >= 1);
    CHECK(streamed.forces_csv.size() > 1000000);
    CHECK(streamed.forces_csv == kept.forces_csv);
    CHECK(streamed.blocks_csv == kept.blocks_csv);
    CHECK(streamed.r.rows == kept.r.rows);
    CHECK(streamed.r.prediction.stats.steps == kept.r.prediction.stats.steps);
    CHECK(streamed.r.prediction.stats.cutting_steps == kept.r.prediction.stats.cutting_steps);
    CHECK(streamed.r.prediction.stats.simulated_s == kept.r.prediction.stats.simulated_s);
    CHECK(streamed.r.prediction.block_names == kept.r.prediction.block_names);
    CHECK(streamed.r.warnings == kept.r.warnings);
    CHECK(streamed.r.ingest.warnings.size() == kept.r.ingest.warnings.size());
    CHECK(streamed.r.sampling.coarse() == kept.r.sampling.coarse());
    CHECK(streamed.r.work.force_rows == kept.r.work.force_rows);
    CHECK(streamed.r.walked_from_s == kept.r.walked_from_s);
    REQUIRE(kept.r.prediction.final_stock);
    REQUIRE(streamed.r.prediction.final_stock);
    CHECK(force_model::save_stock_bytes(*streamed.r.prediction.final_stock) ==
          force_model::save_stock_bytes(*kept.r.prediction.final_stock));
    // The same checkpoints under the same key: either run's serve the other's windows.
    CHECK(streamed.checkpoints == kept.checkpoints);
}

}  // namespace

TEST_CASE("predict_run streamed: the demo walked as it is read writes the kept run's files, and its checkpoints serve a window",
          "[app][predict][streamed]") {
    Scratch kept_dir("streamed_kept"), streamed_dir("streamed_streamed");
    const Outcome kept = run(demo_input(false), true, kept_dir);
    const Outcome streamed = run(demo_input(false), false, streamed_dir);
    check_same(kept, streamed);
    REQUIRE(kept.checkpoints.size() >= 2);

    // A window of the log, later, resumes at a checkpoint the streamed run wrote, and is that run's
    // rows there.
    app::RunInput in = demo_input(false);
    in.window = force_model::TimeWindow{6, 6.5};
    in.checkpoints = app::CheckpointFolder{static_cast<const std::filesystem::path&>(streamed_dir) / "checkpoints", 1.0};
    in.keep_motion = false;   // a window needs the motion whole: it keeps it
    const app::RunResult win = app::predict_run(in);
    CHECK(win.motion_kept);
    CHECK(win.resumed);
    CHECK(win.walked_from_s > 1);
    CHECK(win.walked_from_s <= 6);
    const std::string window_csv = (static_cast<const std::filesystem::path&>(streamed_dir) / "WINDOW.csv").string();
    force_model::write_forces_file(win.prediction, window_csv);
    // The whole run's FORCES.csv lines from 6 s up to 6.5 s, after the header.
    std::istringstream whole(kept.forces_csv), part(read_text(window_csv));
    std::string line, header;
    std::getline(whole, header);
    std::string expected;
    while (std::getline(whole, line)) {
        const double t_s = std::stod(line.substr(0, line.find(',')));
        if (t_s >= 6 && t_s < 6.5) expected += line + "\n";
    }
    std::getline(part, line);
    CHECK(line == header);
    std::ostringstream rest;
    rest << part.rdbuf();
    CHECK(expected.size() > 10000);
    CHECK(rest.str() == expected);
}

TEST_CASE("predict_run streamed: the multi-tool demo's tool table and tool changes, walked as read, are the kept run's",
          "[app][predict][streamed]") {
    app::RunInput in;
    in.log_path = source_path("data/demo2_dryrun.csv");
    in.read = app::read_options(app::LogFormat{});
    in.spec = force_model::load_run_spec(source_path("data/demo2_run.json"));
    in.device = force_model::Device::Cpu;
    Scratch kept_dir("streamed2_kept"), streamed_dir("streamed2_streamed");
    const Outcome kept = run(in, true, kept_dir);
    const Outcome streamed = run(in, false, streamed_dir);
    check_same(kept, streamed);
    // Three tools cut.
    std::set<std::int32_t> tools;
    for (const auto& b : kept.r.prediction.blocks) tools.insert(b.tool);
    CHECK(tools.count(1) + tools.count(2) + tools.count(3) == 3);
}

TEST_CASE("predict_run streamed: a run with its program keeps the motion it maps the program onto", "[app][predict][streamed]") {
    app::RunInput in = demo_input(true);
    in.keep_motion = false;
    std::size_t handed_out = 0;
    in.motion_out = [&](const motion_io::MotionModel& piece) { handed_out += piece.size(); };
    const app::RunResult r = app::predict_run(in);
    CHECK(r.motion_kept);
    CHECK(r.motion.size() > 1000);
    CHECK(handed_out == 0);
    CHECK(r.commanded);
}

TEST_CASE("predict_run streamed: a log that grows between its two reads is refused, saying so", "[app][predict][streamed]") {
    Scratch dir("streamed_growing");
    const std::filesystem::path log = static_cast<const std::filesystem::path&>(dir) / "growing.csv";
    write_text(log, read_text(source_path("data/demo_dryrun.csv")));
    app::RunInput in = demo_input(false);
    in.log_path = log.string();
    in.keep_motion = false;
    // The controller's logger appends two more seconds after the first read, as a log still being
    // written does.
    app::Control control;
    bool appended = false;
    control.progress = [&](app::Phase phase, double) {
        if (phase != app::Phase::Predict || appended) return;
        appended = true;
        std::ofstream more(log, std::ios::app);
        for (int i = 1; i <= 1000; ++i) {
            const double t = 14.877752 + 0.002 * i;
            more << t << ",9998," << t + 0.002 << ",0," << t + 0.004 << ",185.000,-295.000,-310.000,N610\n";
        }
    };
    REQUIRE_THROWS_WITH(app::predict_run(in, control), Catch::Contains("the log changed while it was read") &&
                                                           Catch::Contains("growing.csv"));
    CHECK(appended);
}
