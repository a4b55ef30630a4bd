// Work bounds (app/work_bounds.hpp): the rows, cells and memory a run implies, estimated before it
// starts against figures worked out by hand for a log of known duration and spindle speed; the
// use case refusing a run past a limit before it maps or predicts; the engine stopping at the row
// limit on its own; and a cancel honoured inside block mapping.
#include "app_fixtures.hpp"

#include "app/ingest.hpp"
#include "app/predict_run.hpp"
#include "app/program_run.hpp"
#include "app/work_bounds.hpp"
#include "motion_io/block_mapping.hpp"

#include <cmath>

using namespace cutload;
using namespace cutload::apptest;

namespace {

// A straight cut along +X at 600 mm/min and a constant `rpm`, logged every 2 ms for `duration_s`
// (positions posted to 3 decimals as a controller writes them), 2 mm deep in the slot spec's stock.
std::string uniform_log(double duration_s, double rpm) {
    std::ostringstream log;
    log << "t,x,y,z,feed,spindle\n";
    const int n = int(std::lround(duration_s / 0.002));
    char line[128];
    for (int i = 0; i <= n; ++i) {
        const double t = i * 0.002;
        std::snprintf(line, sizeof line, "%.3f,%.3f,5.000,-2.000,600,%.0f\n", t, 2.0 + 10.0 * t, rpm);
        log << line;
    }
    return log.str();
}

app::RunInput slot_input(const Scratch& dir, const std::string& log_name) {
    app::RunInput in;
    in.log_path = (dir / log_name).string();
    in.read = app::read_options(app::LogFormat{});
    in.spec = force_model::load_run_spec((dir / "slot.json").string());
    in.device = force_model::Device::Cpu;
    return in;
}

}  // namespace

TEST_CASE("work bounds: a uniform log's rows, cells and memory are the hand-computed figures", "[app][bounds]") {
    Scratch dir("bounds_uniform");
    write_slot(dir);
    write_text(dir / "uniform.csv", uniform_log(10.0, 12000));
    const motion_io::ReadOptions ro = app::read_options(app::LogFormat{});
    const motion_io::IngestReport report = app::inspect_log((dir / "uniform.csv").string(), ro);
    force_model::RunSpec spec = force_model::load_run_spec((dir / "slot.json").string());
    spec.resolution.angle_step_deg = 0.5;

    // By hand: 10 s at 12000 rpm is 2000 revolutions, 720000 deg; at 0.5 deg a step that is
    // 1.44e6 rows, plus one per sample of the 1 ms model (10001) and one: 1 450 002. The spindle
    // is constant from the first reading, so the angle integrates exactly; the only slack is the
    // resampled span, which ends on the last whole step (at most one step, 72 deg, 144 rows).
    const app::WorkEstimate w = app::estimate_work(report, spec);
    CHECK(report.extent.samples == 10001);
    CHECK(w.spindle_revolutions == Approx(2000).margin(0.2));
    CHECK(w.force_rows == Approx(1'450'002).margin(145));
    CHECK(w.commanded_rows == 0);
    // The slot spec's stock: 100 x 10 mm at the default 0.1 mm grid, 1000 x 100 cells.
    CHECK(w.stock_cells == 100'000);
    CHECK(w.stocks == 1);
    const double bytes = 1'450'002 * app::kJobBytesPerForceRow + 10001 * app::kJobBytesPerMotionSample +
                         100'000 * (64 + app::kJobBytesPerStoredCell);
    CHECK(force_model::stock_bytes_per_cell() == 64);   // 8 floats of intervals, 2 walls of 4 floats
    // A held row at its peak: the rows twice while their vector doubles, and the engine's 24 B
    // beside each (work_bounds.hpp; measured: docs/api.md, "Work limits").
    CHECK(sizeof(force_model::ForceSample) == 96);
    CHECK(app::kJobBytesPerForceRow == 216);
    CHECK(w.memory_mb == Approx(bytes / 1048576.0).epsilon(1e-3));

    // The same log ingested: the extent the engine walks is the one inspect reported.
    const motion_io::MotionModel m = motion_io::ingest((dir / "uniform.csv").string(), ro);
    const motion_io::MotionExtent e = motion_io::motion_extent(m);
    CHECK(e.samples == report.extent.samples);
    CHECK(e.spindle_turned_deg == Approx(report.extent.spindle_turned_deg).epsilon(1e-12));

    // The log's own commanded positions as the commanded path predict the same extent again.
    app::CommandedWork twice;
    twice.from_log = true;
    const app::WorkEstimate w2 = app::estimate_work(report, spec, twice);
    CHECK(w2.total_rows() == Approx(2 * w.force_rows));
    CHECK(w2.stocks == 2);
}

TEST_CASE("work bounds: each limit refuses with the quantity, its figures and its option named", "[app][bounds]") {
    Scratch dir("bounds_limits");
    write_slot(dir);
    write_text(dir / "uniform.csv", uniform_log(10.0, 12000));
    const motion_io::IngestReport report = app::inspect_log((dir / "uniform.csv").string(), app::read_options(app::LogFormat{}));
    force_model::RunSpec spec = force_model::load_run_spec((dir / "slot.json").string());
    spec.resolution.angle_step_deg = 0.5;
    const app::WorkEstimate w = app::estimate_work(report, spec);

    CHECK_NOTHROW(app::check_work(w, app::WorkLimits{}));   // 1.45e6 rows, 1e5 cells: well inside the defaults

    app::WorkLimits rows;
    rows.max_force_rows = 1e6;
    try {
        app::check_work(w, rows);
        FAIL("1.45e6 rows passed a limit of 1e6");
    } catch (const app::TooMuchWork& e) {
        CHECK(e.key() == "force_rows");
        const std::string m = e.what();
        INFO(m);
        CHECK(m.find("10 s") != std::string::npos);
        CHECK(m.find("2000 revolutions") != std::string::npos);
        CHECK(m.find("12000 rpm") != std::string::npos);
        CHECK(m.find("angle_step_deg 0.5") != std::string::npos);
        CHECK(m.find("1.45e+06 force rows") != std::string::npos);
        CHECK(m.find("limit of 1e+06 (--max-force-rows)") != std::string::npos);
    }

    app::WorkLimits cells;
    cells.max_stock_cells = 50'000;
    CHECK_THROWS_WITH(app::check_work(w, cells),
                      Catch::Contains("stock_cells: resolution.grid_mm gives the stock box 1e+05 dexel cells, above the "
                                      "limit of 5e+04 (--max-stock-cells)"));

    // The demo's 105 x 90 mm stock at 0.01 mm: 10500 x 9000 = 9.45e7 cells, which the run spec
    // itself took up to 60e6 and which the defaults now refuse (20e6).
    force_model::RunSpec fine = force_model::load_run_spec(source_path("data/demo_run.json"));
    fine.resolution.grid_mm = 0.01;
    const app::WorkEstimate wf = app::estimate_work(report, fine);
    CHECK(wf.stock_cells == 94'500'000);
    CHECK_THROWS_WITH(app::check_work(wf, app::WorkLimits{}), Catch::StartsWith("stock_cells:") &&
                                                                 Catch::Contains("9.45e+07 dexel cells") &&
                                                                 Catch::Contains("limit of 2e+07"));

    app::WorkLimits memory;
    memory.max_job_memory_mb = 100;   // the estimate is about 350 MB
    CHECK_THROWS_WITH(app::check_work(w, memory), Catch::Contains("job_memory: the run would need about") &&
                                                      Catch::Contains("above the limit of 100 MB (--max-job-memory-mb)"));
}

TEST_CASE("work bounds: the estimate bounds the rows the engine writes and is close for a log that always cuts", "[app][bounds]") {
    Scratch dir("bounds_engine");
    write_slot(dir);
    // 1 s at 6000 rpm in the slot (x from 2 to 12 mm: the 8 mm cutter is in the stock throughout).
    write_text(dir / "uniform.csv", uniform_log(1.0, 6000));
    app::RunInput in = slot_input(dir, "uniform.csv");
    const app::RunResult r = app::predict_run(in);
    // Every angle step in material is a row: 100 revolutions at 2 deg are 18000 steps.
    INFO("rows " << r.prediction.samples.size() << ", estimate " << r.work.force_rows);
    CHECK(r.work.force_rows == Approx(18000 + 1001 + 1).margin(10));
    CHECK(double(r.prediction.samples.size()) <= r.work.force_rows);
    CHECK(double(r.prediction.samples.size()) >= 18000 * 0.99);
}

TEST_CASE("work bounds: predict_run refuses a run over a limit before it reads further", "[app][bounds]") {
    Scratch dir("bounds_refuse");
    write_slot(dir);
    write_text(dir / "uniform.csv", uniform_log(1.0, 6000));
    app::RunInput in = slot_input(dir, "uniform.csv");
    in.limits.max_force_rows = 10'000;   // the run needs about 19000
    Recorder rec;
    CHECK_THROWS_AS(app::predict_run(in, rec.control()), app::TooMuchWork);
    // Nothing was predicted: the refusal came before the Predict phase.
    CHECK_FALSE(rec.started(app::Phase::Predict).has_value());

    // With a program, the commanded motion's rows count too: the slot log is 1 s at 10000 rpm
    // (about 31000 rows at 2 deg), the program's 20 mm at 1200 mm/min another 1 s at 10000 rpm.
    app::RunInput with_program = slot_input(dir, "slot.csv");
    with_program.program.emplace();
    with_program.program->path = (dir / "slot.nc").string();
    with_program.limits.max_force_rows = 40'000;
    try {
        app::predict_run(with_program);
        FAIL("the slot with its program passed 40000 rows");
    } catch (const app::TooMuchWork& e) {
        INFO(e.what());
        CHECK(e.key() == "force_rows");
        CHECK(std::string(e.what()).find("the commanded motion's") != std::string::npos);
    }
}

TEST_CASE("work bounds: the engine stops at its row limit as it writes", "[app][bounds]") {
    Scratch dir("bounds_engine_limit");
    write_slot(dir);
    write_text(dir / "uniform.csv", uniform_log(1.0, 6000));
    const motion_io::MotionModel m = motion_io::ingest((dir / "uniform.csv").string(), app::read_options(app::LogFormat{}));
    const force_model::RunSpec spec = force_model::load_run_spec((dir / "slot.json").string());
    force_model::PredictOptions po;
    po.device = force_model::Device::Cpu;
    po.max_rows = 5000;   // about 19000 would be written
    CHECK_THROWS_AS(force_model::predict(m, spec, po), force_model::TooManyRows);
    CHECK_THROWS_WITH(force_model::predict(m, spec, po), Catch::Contains("above the limit of 5000"));
    po.max_rows = 20000;
    CHECK(force_model::predict(m, spec, po).samples.size() <= 20000);
}

TEST_CASE("work bounds: a cancel set before mapping stops the mapping itself", "[app][bounds][cancel]") {
    Scratch dir("bounds_cancel");
    write_slot(dir);
    const std::string slot_nc = (dir / "slot.nc").string();
    const force_model::RunSpec spec = force_model::load_run_spec((dir / "slot.json").string());
    motion_io::MotionModel log = motion_io::ingest((dir / "slot.csv").string(), app::read_options(app::LogFormat{}));
    app::ProgramSource source;
    source.path = slot_nc;
    const motion_io::NcProgram program = app::read_program(source, spec, app::log_start_mm(log));

    std::atomic<bool> cancel{true};
    app::Control control;
    control.cancel = &cancel;
    // The log names no block: it is mapped, and the mapping sees the flag.
    motion_io::MotionModel copy = log;
    CHECK_THROWS_AS(app::prepare_program_run(program, source.settings, copy, control), force_model::Cancelled);
    // Without the flag the same call maps the log.
    cancel = false;
    motion_io::MotionModel mapped = log;
    CHECK(app::prepare_program_run(program, source.settings, mapped, control).mapped);

    // The two loops of motion_io themselves, with a log that names its blocks (the lead estimate).
    cancel = true;
    motion_io::BlockMappingOptions mo;
    mo.cancel = &cancel;
    CHECK_THROWS_AS(motion_io::map_blocks(log, program, mo), motion_io::MappingCancelled);
    CHECK_THROWS_AS(motion_io::estimate_block_lead_s(mapped, program, mo), motion_io::MappingCancelled);
}
