// app::inspect_log, app::ingest_log and app::resample_log on the demo log: what `cutload inspect`
// and `cutload resample` asserted (tests/motion_io/test_cli.cpp, test_repair.cpp), the read options
// both front ends build, progress and cancellation.
#include "app_fixtures.hpp"

#include "app/ingest.hpp"

using namespace cutload;
using namespace cutload::apptest;

TEST_CASE("inspect_log: the demo log's sampling, sessions and blocks", "[app][ingest]") {
    const motion_io::IngestReport r = app::inspect_log(source_path("data/demo_dryrun.csv"), app::read_options({}));
    CHECK(r.duration_s > 10);
    CHECK(r.sessions == 1);
    CHECK(r.blocks > 20);
    CHECK(r.channels.at("pos").samples > 2000);
    CHECK(r.channels.at("pos").interval.median_s == Approx(0.006).epsilon(0.05));
    CHECK(r.channels.at("pos").update_period_s == Approx(0.004).epsilon(0.01));
    REQUIRE(r.first_position_mm);
}

TEST_CASE("ingest_log: the demo log in one session on a 1 ms step, with progress and cancel", "[app][ingest]") {
    Recorder rec;
    const app::IngestedLog log =
        app::ingest_log(source_path("data/demo_dryrun.csv"), app::read_options({}, 1.0), rec.control());
    rec.require_monotonic();
    CHECK(rec.phases() == std::vector<app::Phase>{app::Phase::Ingest, app::Phase::Done});
    CHECK(rec.calls.back().second == 1.0);
    CHECK(log.report.sessions == 1);
    REQUIRE(log.motion.session_start == std::vector<std::size_t>{0});
    CHECK(log.motion.step_s == Approx(0.001));
    CHECK(log.motion.block_names.front() == "N10");
    CHECK(log.motion.spindle_rpm[log.motion.size() / 2] == Approx(10000).margin(3));
    CHECK(log.report.feed_repaired_max_mm_min < log.report.feed_raw_max_mm_min);
    // The first position is where the streaming inspect says the log starts.
    const auto first = app::inspect_log(source_path("data/demo_dryrun.csv"), app::read_options({})).first_position_mm;
    REQUIRE(first);
    CHECK(log.motion.x_mm.front() == Approx((*first)[0]).margin(1e-9));
    CHECK(log.motion.z_mm.front() == Approx((*first)[2]).margin(1e-9));

    Recorder cancelled;
    cancelled.cancel_at = app::Phase::Ingest;
    CHECK_THROWS_AS(app::ingest_log(source_path("data/demo_dryrun.csv"), app::read_options({}), cancelled.control()),
                    force_model::Cancelled);
    CHECK(cancelled.phases() == std::vector<app::Phase>{app::Phase::Ingest});
}

TEST_CASE("resample_log: the demo on a 2 ms step with the documented header", "[app][ingest]") {
    const Scratch dir("resample");
    const std::string out = (dir / "resampled.csv").string();
    const app::Resampled r = app::resample_log(source_path("data/demo_dryrun.csv"), app::read_options({}, 2.0), out);
    std::ifstream in(out);
    std::string header, first;
    std::getline(in, header);
    std::getline(in, first);
    CHECK(header == "t_s,x_mm,y_mm,z_mm,feed_mm_min,spindle_rpm,spindle_angle_deg,block");
    CHECK(first.find(",N10") != std::string::npos);
    std::size_t rows = 1;
    for (std::string line; std::getline(in, line);) ++rows;
    CHECK(rows > 7000);   // about 15 s at 2 ms
    CHECK(r.rows == rows);
    CHECK(r.report.sessions == 1);
}

TEST_CASE("read_options: the format, map and units a front end names, bad values naming the key", "[app][inputs]") {
    app::LogFormat f;
    f.format = "shdr";
    f.map_file = "map.json";
    f.length_unit = "in";
    f.feed_unit = "in/min";
    const motion_io::ReadOptions o = app::read_options(f, 4.0);
    CHECK(o.format == motion_io::Format::Shdr);
    CHECK(o.map_file == "map.json");
    CHECK(o.length_unit == std::optional<std::string>("in"));
    CHECK(o.feed_unit == std::optional<std::string>("in/min"));
    CHECK(o.step_ms == 4.0);
    CHECK(app::read_options({}).format == motion_io::Format::Auto);
    CHECK(app::read_options({}).step_ms == motion_io::ReadOptions{}.step_ms);
    f.format = "csv";
    CHECK(app::read_options(f).format == motion_io::Format::Csv);

    f.format = "xlsx";
    CHECK_THROWS_WITH(app::read_options(f), "format: 'xlsx' is not auto, csv or shdr");
    f.format = "auto";
    f.length_unit = "furlong";
    try {
        app::read_options(f);
        FAIL("a length unit of furlongs was accepted");
    } catch (const app::InputError& e) {
        CHECK(e.key() == "units");
        CHECK(std::string(e.what()) == "units: 'furlong' is not mm or in");
    }
}

TEST_CASE("choose_device: opencl, cpu, auto with its fallback, and nothing else", "[app][inputs]") {
    CHECK(app::choose_device("cpu").device == force_model::Device::Cpu);
    CHECK(app::choose_device("cpu").note.empty());
    CHECK(app::choose_device("opencl").device == force_model::Device::OpenCL);
    // auto: OpenCL exactly when the engine finds a device; otherwise the CPU, saying why.
    bool have_opencl = true;
    std::string why;
    try {
        force_model::opencl_device_name();
    } catch (const std::runtime_error& e) {
        have_opencl = false;
        why = e.what();
    }
    const app::DeviceChoice a = app::choose_device("auto");
    CHECK(a.device == (have_opencl ? force_model::Device::OpenCL : force_model::Device::Cpu));
    CHECK(a.note == (have_opencl ? std::string() : why + "; using the CPU path"));
    CHECK_THROWS_WITH(app::choose_device("gpu"), "device: 'gpu' is not opencl, cpu or auto");
}

TEST_CASE("prepare_device: the same choice as choose_device, made in the background, the kernels ready", "[app][inputs]") {
    CHECK(app::prepare_device("cpu").get().device == force_model::Device::Cpu);
    const app::DeviceChoice now = app::choose_device("auto");
    const app::DeviceChoice later = app::prepare_device("auto").get();
    CHECK(later.device == now.device);
    CHECK(later.note == now.note);
    CHECK(app::prepare_device("opencl").get().device == force_model::Device::OpenCL);
    // A bad name is the same error, taken from the future.
    auto bad = app::prepare_device("gpu");
    CHECK_THROWS_WITH(bad.get(), "device: 'gpu' is not opencl, cpu or auto");
}
