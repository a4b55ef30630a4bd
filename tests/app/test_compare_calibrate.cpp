// app::compare_measurement and app::calibrate on the generated dynamometer records of the calib
// suite: what `cutload compare` / `cutload calibrate` and the service's measurement and calibration
// routes asserted (tests/calib/test_cli.cpp, tests/server/test_calibration.cpp), records read from
// a file or from memory alike, progress and cancellation.
#include "app_fixtures.hpp"

#include "app/calibrate.hpp"
#include "app/compare.hpp"
#include "calib/dyno_fixture.hpp"

#include <fmt/format.h>

#include <cmath>

using namespace cutload;
using namespace cutload::apptest;
using namespace cutload::calibtest;

namespace {

struct Records {
    app::CalibrationInput input;
    force_model::Prediction down;   // the down-milling test's prediction (compared below)
};

// The CLI test's four straight tests (three slot feeds, one down-milling pass), each predicted
// with the true coefficients and written as a DynoWare export with 0.5 % noise.
Records write_records(const std::filesystem::path& dir) {
    Records r;
    
    r.input.tool = test_tool();
    r.input.axes = kSeedAxes;
    using force_model::Immersion;
    struct Test {
        double c;
        Side side;
        double ae;
        Immersion mode;
    };
    unsigned seed = 400;
    for (const Test& t : {Test{0.05, Side::Slot, 0, Immersion::Slot}, Test{0.1, Side::Slot, 0, Immersion::Slot},
                          Test{0.15, Side::Slot, 0, Immersion::Slot}, Test{0.1, Side::Down, 2, Immersion::Down}}) {
        const StraightCut cut = straight_cut(t.c, 2, t.side, t.ae);
        force_model::PredictOptions po;
        po.device = force_model::Device::Cpu;
        force_model::Prediction p = force_model::predict(cut.motion, cut.spec, po);
        const auto file = dir / fmt::format("{}_{}.csv", force_model::immersion_name(t.mode), t.c);
        DynoOptions dyno;
        dyno.seed = seed++;
        dyno.noise_rel = 0.005;
        write_dyno_file(p, file.string(), dyno);
        app::CalibrationTest test;
        test.file = file.string();
        test.test = {10000, t.c * 2 * 10000, 2, t.ae, t.mode, 0};
        r.input.tests.push_back(test);
        if (t.side == Side::Down) r.down = std::move(p);
    }
    return r;
}

}  // namespace

TEST_CASE("calibrate: four straight tests re-identify the coefficients within 2 %, from files or from memory",
          "[app][calibrate]") {
    const Scratch dir("calibrate");
    const Records rec_files = write_records(dir);
    Recorder rec;
    const app::Calibration cal = app::calibrate(rec_files.input, rec.control());
    rec.require_monotonic();
    CHECK(rec.phases() == std::vector<app::Phase>{app::Phase::Calibrate, app::Phase::Done});
    CHECK(rec.calls.back().second == 1.0);
    REQUIRE(cal.tests.size() == 4);
    const auto g = force_model::coefficients_of(cal.fit.material), w = force_model::coefficients_of(true_material());
    for (std::size_t k = 0; k < 6; ++k) {
        INFO(force_model::kCoefficientKeys[k] << " " << g[k] << " vs " << w[k]);
        CHECK(std::abs(g[k] / w[k] - 1) < 0.02);
    }
    CHECK(cal.fit.material.name == "calibrated");
    for (const auto& t : cal.tests) {
        CHECK(t.steady.revolutions >= 3);
        CHECK(t.steady.zeroed);   // the records start with idle revolutions
    }

    // The service reads uploads from memory: the same records give the same fit.
    app::CalibrationInput uploaded = rec_files.input;
    for (auto& t : uploaded.tests) {
        t.content = read_text(t.file);
        t.file = std::filesystem::path(t.file).filename().string();
    }
    uploaded.model = app::RegressorModel::ClosedForm;   // cheaper, and the same for both sources
    app::CalibrationInput from_files = rec_files.input;
    from_files.model = app::RegressorModel::ClosedForm;
    const auto a = force_model::coefficients_of(app::calibrate(uploaded).fit.material);
    const auto b = force_model::coefficients_of(app::calibrate(from_files).fit.material);
    CHECK(a == b);
}

TEST_CASE("calibrate: a bad record fails before any engine time, a cancel stops it", "[app][calibrate][cancel]") {
    const Scratch dir("calibrate_bad");
    const Records r = write_records(dir);
    app::CalibrationInput in = r.input;
    in.tests.back().content = "DynoWare,Version 3\nSampling rate [Hz]:,10000\nTime,Fx,Fy,Fz\n0,1,2,3\n";
    in.tests.back().file = "bad.csv";
    Recorder rec;
    CHECK_THROWS_WITH(app::calibrate(in, rec.control()), Catch::Contains("bad.csv:4: missing units row"));
    CHECK(*rec.reached(app::Phase::Calibrate) == 0.0);   // no regressor was computed

    Recorder cancelled;
    cancelled.cancel_at = app::Phase::Calibrate;
    CHECK_THROWS_AS(app::calibrate(r.input, cancelled.control()), force_model::Cancelled);
    CHECK(cancelled.phases() == std::vector<app::Phase>{app::Phase::Calibrate});

    in = r.input;
    in.tests.front().test.axial_mm = 50;   // deeper than the flutes
    CHECK_THROWS_AS(app::calibrate(in), force_model::SpecError);
}

TEST_CASE("compare_measurement: the down-milling record against its prediction, from a file or a stream",
          "[app][compare]") {
    const Scratch dir("compare");
    const Records r = write_records(dir);
    const std::string measured = r.input.tests.back().file;
    const force_model::PredictedTrace trace = force_model::predicted_trace(r.down);
    app::CompareSettings s;
    s.axes = kSeedAxes;
    const app::MeasurementComparison c = app::compare_measurement(trace, measured, s);
    CHECK(c.measured.tool_machine_axes);
    CHECK(c.comparison.offset_found);
    CHECK(c.comparison.offset_s == Approx(-DynoOptions{}.delay_s).margin(1e-4));
    CHECK(c.comparison.overall.axes[3].correlation > 0.98);
    CHECK(c.comparison.blocks.size() == 1);

    std::ifstream in(measured);
    const app::MeasurementComparison streamed = app::compare_measurement(trace, in, "down.csv", s);
    CHECK(streamed.measured.source == "down.csv");
    CHECK(streamed.comparison.offset_s == c.comparison.offset_s);
    CHECK(streamed.comparison.overall.axes[3].rmse_N == c.comparison.overall.axes[3].rmse_N);

    // A given offset is used as given (the CLI's --offset-s).
    s.options.offset_s = -0.15123;
    const app::MeasurementComparison given = app::compare_measurement(trace, measured, s);
    CHECK_FALSE(given.comparison.offset_found);
    CHECK(given.comparison.offset_s == -0.15123);
}
