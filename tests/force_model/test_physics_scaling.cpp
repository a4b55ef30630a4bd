// Symmetry and scaling of predict(): rotating the path rotates the forces, doubling the axial
// depth doubles them, and the chip-area part is linear in the feed per tooth while the edge part
// does not depend on it.
#include "force_model/reference.hpp"

#include <catch2/catch.hpp>
#include <fmt/format.h>

#include <cmath>

using namespace cutload;
using namespace cutload::testref;

namespace {

constexpr double kRpm = 10000;
constexpr double kGridMm = 0.02;

// Steady mean forces of a straight cut on one device.
Forces steady_forces(const Cut& cut, const Coefficients& k, force_model::Device device, int quarter_turns = 0) {
    const StraightSetup setup = straight_setup(cut, kRpm, quarter_turns);
    force_model::PredictOptions opt;
    opt.device = device;
    const force_model::Prediction p =
        force_model::predict(uniform_motion(setup.path), flat_tool_spec(cut, k, setup.box, kGridMm), opt);
    const SteadyMean m = steady_mean(p.samples, setup.steady_t0_s, setup.steady_t1_s, cut.flutes);
    REQUIRE(m.tooth_periods >= 10);
    return m.forces;
}

Forces scaled(const Forces& f, double s) { return {f.fx_N * s, f.fy_N * s, f.fz_N * s, f.torque_Nm * s}; }
Forces minus(const Forces& a, const Forces& b) {
    return {a.fx_N - b.fx_N, a.fy_N - b.fy_N, a.fz_N - b.fz_N, a.torque_Nm - b.torque_Nm};
}

std::string show(const Forces& f) { return fmt::format("({:.3f},{:.3f},{:.3f}) N", f.fx_N, f.fy_N, f.fz_N); }

}  // namespace

TEST_CASE("physics: rotating the path by 90 degrees rotates the force vector", "[physics][scaling]") {
    // Up milling is asymmetric, so both in-plane components are large and distinct.
    const Cut cut = up_cut(8, 2, 30, 2, 0.1, 3);
    const Coefficients k = test_coefficients();
    for (force_model::Device device : devices_under_test()) {
        const Forces along_x = steady_forces(cut, k, device, 0);
        for (int turns : {1, 2}) {
            const Forces rotated = steady_forces(cut, k, device, turns);
            const Forces expected = rotate_quarter_turns(along_x, turns);
            const double err = relative_force_error(rotated, expected);
            const std::string figures = fmt::format("{} rotation {} x 90 deg: {} vs rotated +X run {}: err {:.3f}%",
                                                    device_name(device), turns, show(rotated), show(expected), 100 * err);
            report_figure(figures);
            INFO(figures);
            CHECK(err < 0.01);
            CHECK(rotated.torque_Nm == Approx(along_x.torque_Nm).epsilon(0.01));
        }
    }
}

TEST_CASE("physics: doubling the axial depth doubles the forces", "[physics][scaling]") {
    const Coefficients k = test_coefficients();
    for (force_model::Device device : devices_under_test()) {
        const Forces shallow = steady_forces(slot_cut(8, 2, 30, 1, 0.1), k, device);
        const Forces deep = steady_forces(slot_cut(8, 2, 30, 2, 0.1), k, device);
        const double err = relative_force_error(deep, scaled(shallow, 2));
        const std::string figures = fmt::format("{} axial 1 -> 2 mm: {} vs 2 x {}: err {:.3f}%", device_name(device),
                                                show(deep), show(shallow), 100 * err);
        report_figure(figures);
        INFO(figures);
        CHECK(err < 0.01);
        CHECK(deep.torque_Nm == Approx(2 * shallow.torque_Nm).epsilon(0.01));
    }
}

TEST_CASE("physics: doubling the feed per tooth scales the chip-area part and leaves the edge part",
          "[physics][scaling]") {
    const Coefficients k = test_coefficients();
    const Cut slow = down_cut(8, 2, 30, 2, 0.05, 3);
    Cut fast = slow;
    fast.feed_per_tooth_mm = 0.1;
    for (force_model::Device device : devices_under_test()) {
        // Chip-area terms alone: proportional to the feed per tooth.
        const Forces cut_slow = steady_forces(slow, cutting_part(k), device);
        const Forces cut_fast = steady_forces(fast, cutting_part(k), device);
        const double linear_err = relative_force_error(cut_fast, scaled(cut_slow, 2));
        // Edge terms alone: independent of it.
        const Forces edge_slow = steady_forces(slow, edge_part(k), device);
        const Forces edge_fast = steady_forces(fast, edge_part(k), device);
        const double edge_err = relative_force_error(edge_fast, edge_slow);
        // Both together: the increase from doubling is the closed-form chip-area part at the
        // slower feed (the edge part cancels), and the mean at each feed matches the closed form.
        const Forces both_slow = steady_forces(slow, k, device);
        const Forces both_fast = steady_forces(fast, k, device);
        const Forces increase = minus(both_fast, both_slow);
        const Forces expected_increase = average_forces(slow, cutting_part(k));
        const double increase_err = relative_force_error(increase, expected_increase);
        const double fast_err = relative_force_error(both_fast, average_forces(fast, k));
        const std::string figures = fmt::format(
            "{} feed 0.05 -> 0.1 mm/tooth: chip-area part ratio err {:.3f}%, edge part change {:.3f}%, "
            "increase {} vs closed chip-area part {} err {:.3f}%, full at 0.1 vs closed err {:.3f}%",
            device_name(device), 100 * linear_err, 100 * edge_err, show(increase), show(expected_increase),
            100 * increase_err, 100 * fast_err);
        report_figure(figures);
        INFO(figures);
        CHECK(linear_err < 0.01);
        CHECK(edge_err < 0.01);
        // A difference of two measurements, each within 2 % of the closed form: 3 % allowed.
        CHECK(increase_err < 0.03);
        CHECK(fast_err < 0.02);
    }
}
