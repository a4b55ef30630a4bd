// The two-slot pipeline (docs/force_model.md, "Pipeline"): queuing a batch's engagement before the
// batch in flight is completed gives the same rows and the same final stock, bit for bit, as
// completing each batch before queuing the next (EngineSettings::queue_before_completing = false),
// on both backends. The path makes the case the pipeline handles differently occur: a batch sized
// from tops one batch old (more elements, an engagement where nothing is left).
#include "engine_fixtures.hpp"
#include "force_model/stock.hpp"

using namespace cutload;
using namespace cutload::enginetest;

namespace {

// On a bar 3 mm wide (the fixture's block, 40 x 3 x 10 mm), with the 8 mm cutter centred on it.
// At 3000 mm/min and 10000 rpm a 2 deg step moves the tip 1/600 mm, and a batch of at most 16384
// steps (EngineSettings::max_batch_steps) spans 27.307 mm.
motion_io::MotionModel passes_along_a_bar() {
    // A pass 3 mm deep along the whole bar, started two batch lengths before x = 41: its third
    // batch begins 1 mm past the bar's end, with nothing within reach once the second batch's
    // removal is applied, but tops one batch old still show the bar's last 4 mm (an engagement is
    // queued that finds nothing). Then down beside the bar, back along it 2 mm deeper, up, a ramp
    // down into the bar and a pass to its end.
    const double batch_mm = 16384.0 / 600.0;
    return legs_motion({41 - 2 * batch_mm, 1.5, 7},
                       {{{60, 1.5, 7}, 3000, "N10"},
                        {{60, 1.5, 5}, 3000, "N20"},
                        {{-6, 1.5, 5}, 3000, "N30"},
                        {{-6, 1.5, 12}, 3000, "N40"},
                        {{20, 1.5, 4}, 1500, "N50"},
                        {{46, 1.5, 4}, 3000, "N60"}});
}

force_model::Prediction run(const motion_io::MotionModel& m, force_model::Device device, bool queue_first,
                            force_model::EnginePhases* phases) {
    force_model::PredictOptions o;
    o.device = device;
    force_model::EngineSettings settings;
    settings.queue_before_completing = queue_first;
    return force_model::predict_with(m, base_spec(40, 3, 10), o, settings, phases);
}

void check_same(force_model::Device device) {
    const auto m = passes_along_a_bar();
    force_model::EnginePhases serial_phases, pipelined_phases;
    const force_model::Prediction serial = run(m, device, false, &serial_phases);
    const force_model::Prediction pipelined = run(m, device, true, &pipelined_phases);
    REQUIRE(serial.samples.size() == pipelined.samples.size());
    std::size_t differing = 0, cutting = 0;
    double removed_mm3 = 0;
    for (std::size_t i = 0; i < serial.samples.size(); ++i) {
        differing += same_row(serial.samples[i], pipelined.samples[i]) ? 0 : 1;
        cutting += serial.samples[i].fx_N != 0 || serial.samples[i].fy_N != 0 ? 1 : 0;
        removed_mm3 += serial.samples[i].removed_mm3;
    }
    CHECK(differing == 0);
    REQUIRE(serial.final_stock);
    REQUIRE(pipelined.final_stock);
    CHECK(force_model::save_stock_bytes(*serial.final_stock) == force_model::save_stock_bytes(*pipelined.final_stock));
    // The run cuts: the bar loses 6 mm of its 10 mm height (720 mm3) over most of its length, in
    // several batches.
    CHECK(cutting > serial.samples.size() / 5);
    CHECK(removed_mm3 > 40 * 3 * 6 * 0.8);
    // Sized from older tops, the pipeline never queues fewer engagements, and here one more at least.
    CHECK(pipelined_phases.batches > serial_phases.batches);
    CHECK(serial_phases.batches > 5);
}

}  // namespace

TEST_CASE("pipeline: queuing the next batch before completing the one in flight gives the same rows and stock",
          "[engine][pipeline]") {
    SECTION("scalar twins") { check_same(force_model::Device::Cpu); }
    SECTION("OpenCL") {
        if (!opencl_available()) {
            WARN("no OpenCL device: only the scalar twins are checked");
            return;
        }
        check_same(force_model::Device::OpenCL);
    }
}
