// Tool tables: one run, three flat end mills of different diameters, flute counts and helices, each
// selected per sample by the motion's tool channel, sharing one stock.
//
// Each tool cuts a full-width slot of its own; in steady state its mean forces and torque must be
// Altintas' closed-form averages for ITS diameter, flutes, depth and feed (tests/force_model/
// reference.cpp, written from the formulas, not from the engine). Before that, tools 2 and 3 each
// pass through the slot the tool before them cut, narrower than it and above its floor: the material
// there is gone, so nothing may be cut (zero force, nothing removed). Run again with tool 1 missing
// from the table, tool 1's samples get no forces and remove nothing (its block flagged
// unknown_tool), and the same pass of tool 2 then cuts: the zero force above came from tool 1's
// removal, not from a pass that misses the stock.
#include "force_model/engine.hpp"
#include "force_model/engine_fixtures.hpp"
#include "force_model/reference.hpp"

#include <catch2/catch.hpp>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

using namespace cutload;
using namespace cutload::testref;
using enginetest::Leg;
using enginetest::P3;

namespace {

constexpr double kTop = 20;   // the box's top face

struct SlotTool {
    int number;
    double diameter_mm;
    int flutes;
    double helix_deg;
    double rpm;
    double feed_per_tooth_mm;
    double depth_mm;    // of its own slot
    double slot_y_mm;   // its own slot runs along +X at this y
};

// T1 a coarse-pitch face-milling style cutter, T2 an end mill, T3 a small three-flute end mill.
const SlotTool kTools[] = {{1, 16, 4, 10, 6000, 0.08, 2.0, 15},
                           {2, 8, 2, 30, 10000, 0.05, 3.0, 40},
                           {3, 6, 3, 35, 12000, 0.04, 2.5, 53}};

double feed_mm_min(const SlotTool& t) { return t.feed_per_tooth_mm * t.flutes * t.rpm; }

force_model::ToolSpec tool_spec(const SlotTool& t) {
    force_model::ToolSpec s;
    s.shape = force_model::ToolShape::Flat;
    s.diameter_mm = t.diameter_mm;
    s.flutes = t.flutes;
    s.helix_deg = t.helix_deg;
    s.flute_length_mm = 20;
    s.stickout_mm = 30;
    s.holder = {32, 40};
    return s;
}

// The box 50 x 60 x 20 mm; the run's limits trip nothing, T2's own force limit trips in its slot.
force_model::RunSpec three_tool_spec(bool with_t1 = true) {
    const Coefficients k = test_coefficients();
    force_model::RunSpec spec;
    spec.has_tool = false;
    spec.material = {"reference", k.Ktc_N_mm2, k.Krc_N_mm2, k.Kac_N_mm2, k.Kte_N_mm, k.Kre_N_mm, k.Kae_N_mm};
    spec.stock.max_mm[0] = 50;
    spec.stock.max_mm[1] = 60;
    spec.stock.max_mm[2] = kTop;
    spec.resolution = {2.0, 0.1, 0.1};
    spec.limits.force_N = 1e5;
    for (const SlotTool& t : kTools) {
        if (t.number == 1 && !with_t1) continue;
        force_model::NumberedTool n{t.number, tool_spec(t), {}};
        if (t.number == 2) n.limits.force_N = 50;
        spec.tools.push_back(n);
    }
    return spec;
}

// Tool n: leave the previous tool's slot upwards, change tools at (-40, 0, 60) with the spindle
// stopped, then (from tool 2 on) pass through the previous tool's slot, centred, 0.5 mm above its
// floor, and cut its own slot from outside the box to x = 40.
std::vector<Leg> tool_legs(std::size_t n) {
    const SlotTool& t = kTools[n];
    const int T = t.number;
    const std::string name = fmt::format("T{}", T);
    std::vector<Leg> legs;
    legs.push_back({{-40, 0, 60}, 6000, name + " change", 0, T});
    if (n > 0) {
        const SlotTool& prev = kTools[n - 1];
        const double z = kTop - prev.depth_mm + 0.5;
        legs.push_back({{-12, prev.slot_y_mm, z}, 6000, name + " approach", t.rpm, T});
        legs.push_back({{30, prev.slot_y_mm, z}, 3000, name + " in the previous slot", t.rpm, T});
        legs.push_back({{30, prev.slot_y_mm, 40}, 3000, name + " up", t.rpm, T});
    }
    legs.push_back({{-12, t.slot_y_mm, kTop - t.depth_mm}, 6000, name + " to its slot", t.rpm, T});
    legs.push_back({{40, t.slot_y_mm, kTop - t.depth_mm}, feed_mm_min(t), name + " slot", t.rpm, T});
    legs.push_back({{40, t.slot_y_mm, 40}, 3000, name + " retract", t.rpm, T});
    return legs;
}

motion_io::MotionModel three_tool_motion() {
    std::vector<Leg> legs;
    for (std::size_t n = 0; n < 3; ++n)
        for (const Leg& l : tool_legs(n)) legs.push_back(l);
    return enginetest::legs_motion({-40, 0, 60}, legs);
}

std::int32_t block_index(const motion_io::MotionModel& m, const std::string& name) {
    const auto it = std::find(m.block_names.begin(), m.block_names.end(), name);
    REQUIRE(it != m.block_names.end());
    return std::int32_t(it - m.block_names.begin());
}

// The steady stretch of a slot: the whole front half of the cutter inside the box, 1 mm clear of
// its entry and of the end of the slot.
std::pair<double, double> steady_window(const motion_io::MotionModel& m, const SlotTool& t) {
    const std::int32_t b = block_index(m, fmt::format("T{} slot", t.number));
    double t0 = 1e300, t1 = -1e300;
    for (std::size_t i = 0; i < m.size(); ++i)
        if (m.block[i] == b && m.x_mm[i] >= t.diameter_mm / 2 + 1 && m.x_mm[i] <= 39) {
            t0 = std::min(t0, m.t_s[i]);
            t1 = std::max(t1, m.t_s[i]);
        }
    return {t0, t1};
}

const force_model::BlockSummary& summary(const force_model::Prediction& p, const std::string& name) {
    const auto it = std::find_if(p.blocks.begin(), p.blocks.end(), [&](const auto& b) { return b.block == name; });
    REQUIRE(it != p.blocks.end());
    return *it;
}

bool has_flag(const force_model::BlockSummary& b, const std::string& flag, std::int32_t* tool = nullptr) {
    for (const auto& f : b.flags)
        if (f.flag == flag) {
            if (tool) *tool = f.tool;
            return true;
        }
    return false;
}

// Peak force and removed volume over the rows of one block.
struct BlockLoad {
    double peak_N = 0, removed_mm3 = 0;
    std::size_t rows = 0;
};
BlockLoad block_load(const force_model::Prediction& p, const motion_io::MotionModel& m, const std::string& name) {
    const std::int32_t b = block_index(m, name);
    BlockLoad l;
    for (const auto& s : p.samples) {
        if (s.block != b) continue;
        l.peak_N = std::max(l.peak_N, std::sqrt(double(s.fx_N) * s.fx_N + double(s.fy_N) * s.fy_N + double(s.fz_N) * s.fz_N));
        l.removed_mm3 += s.removed_mm3;
        ++l.rows;
    }
    return l;
}

}  // namespace

TEST_CASE("tool table: three tools in one run, each slot at its own closed-form mean, none re-cuts what the one before removed",
          "[engine][tools]") {
    const Coefficients k = test_coefficients();
    const motion_io::MotionModel m = three_tool_motion();
    const force_model::RunSpec spec = three_tool_spec();
    std::vector<std::vector<Forces>> means_by_device;
    for (const force_model::Device device : devices_under_test()) {
        force_model::PredictOptions opt;
        opt.device = device;
        const force_model::Prediction p = force_model::predict(m, spec, opt);
        INFO(device_name(device));
        CHECK(p.stats.unknown_tool_samples == 0);

        std::vector<Forces> means;
        for (const SlotTool& t : kTools) {
            const Cut cut = slot_cut(t.diameter_mm, t.flutes, t.helix_deg, t.depth_mm, t.feed_per_tooth_mm);
            const Forces expected = average_forces(cut, k);
            const auto [t0, t1] = steady_window(m, t);
            const SteadyMean mean = steady_mean(p.samples, t0, t1, t.flutes);
            const std::string figures = fmt::format(
                "{} T{} (D{} N{} helix {} a{} f{}): mean F ({:.2f}, {:.2f}, {:.2f}) N vs closed ({:.2f}, {:.2f}, {:.2f}), "
                "error {:.3f} %; torque {:.4f} vs {:.4f} N m; {} tooth periods",
                device_name(device), t.number, t.diameter_mm, t.flutes, t.helix_deg, t.depth_mm, t.feed_per_tooth_mm,
                mean.forces.fx_N, mean.forces.fy_N, mean.forces.fz_N, expected.fx_N, expected.fy_N, expected.fz_N,
                100 * relative_force_error(mean.forces, expected), mean.forces.torque_Nm, expected.torque_Nm,
                mean.tooth_periods);
            report_figure(figures);
            INFO(figures);
            REQUIRE(mean.tooth_periods >= 50);
            CHECK(relative_force_error(mean.forces, expected) < 0.02);
            CHECK(mean.forces.torque_Nm == Approx(expected.torque_Nm).epsilon(0.02));
            means.push_back(mean.forces);

            // The slot's block names its tool, and so do its rows.
            const auto& slot = summary(p, fmt::format("T{} slot", t.number));
            CHECK(slot.tool == t.number);
            const std::int32_t b = block_index(m, fmt::format("T{} slot", t.number));
            CHECK(std::all_of(p.samples.begin(), p.samples.end(), [&](const auto& s) { return s.block != b || s.tool == t.number; }));
        }
        means_by_device.push_back(means);

        // Tools 2 and 3 in the slot the tool before them cut: nothing left to cut there.
        for (const char* pass : {"T2 in the previous slot", "T3 in the previous slot"}) {
            const BlockLoad l = block_load(p, m, pass);
            INFO(pass << ": peak " << l.peak_N << " N, removed " << l.removed_mm3 << " mm3 over " << l.rows << " rows");
            REQUIRE(l.rows > 1000);
            CHECK(l.peak_N == 0);
            CHECK(l.removed_mm3 == 0);
            CHECK(summary(p, pass).flags.empty());
        }

        // Per-tool limits: T2's own force limit (50 N) trips in its slot and names T2; the run's
        // (100 kN) trips nowhere else.
        std::int32_t flagged_tool = -1;
        CHECK(has_flag(summary(p, "T2 slot"), "force_limit", &flagged_tool));
        CHECK(flagged_tool == 2);
        CHECK_FALSE(has_flag(summary(p, "T1 slot"), "force_limit"));
        CHECK_FALSE(has_flag(summary(p, "T3 slot"), "force_limit"));
        CHECK(summary(p, "T1 slot").peak_force_N > 50);

        // The stock removed is the three slots: a rectangle and a half disc at the end of each
        // (the tools enter from outside the box), as deep as each slot.
        double slots_mm3 = 0;
        for (const SlotTool& t : kTools) {
            const double R = t.diameter_mm / 2;
            slots_mm3 += t.depth_mm * (40 * t.diameter_mm + 0.5 * std::numbers::pi * R * R);
        }
        const double removed_mm3 = 50 * 60 * kTop - force_model::stock_volume_mm3(*p.final_stock);
        INFO("removed " << removed_mm3 << " mm3, the three slots " << slots_mm3 << " mm3");
        CHECK(removed_mm3 == Approx(slots_mm3).epsilon(0.002));
    }
    // The kernels and their scalar twins agree per tool.
    if (means_by_device.size() == 2)
        for (std::size_t n = 0; n < 3; ++n) {
            INFO("T" << kTools[n].number);
            CHECK(relative_force_error(means_by_device[1][n], means_by_device[0][n]) < 0.005);
        }
}

TEST_CASE("tool table: a tool the table lacks is not guessed: no forces, nothing removed, its block flagged unknown_tool",
          "[engine][tools]") {
    const motion_io::MotionModel m = three_tool_motion();
    const force_model::RunSpec spec = three_tool_spec(false);
    for (const force_model::Device device : devices_under_test()) {
        force_model::PredictOptions opt;
        opt.device = device;
        const force_model::Prediction p = force_model::predict(m, spec, opt);
        INFO(device_name(device));
        std::size_t t1_samples = 0;
        for (std::int32_t t : m.tool) t1_samples += t == 1;
        CHECK(p.stats.unknown_tool_samples == t1_samples);
        CHECK(p.stats.unknown_tools == std::vector<int>{1});

        const BlockLoad t1 = block_load(p, m, "T1 slot");
        CHECK(t1.peak_N == 0);
        CHECK(t1.removed_mm3 == 0);
        std::int32_t flagged_tool = -1;
        const auto& slot = summary(p, "T1 slot");
        REQUIRE(has_flag(slot, "unknown_tool", &flagged_tool));
        CHECK(flagged_tool == 1);
        CHECK(slot.tool == 1);
        // With tool 1's slot still full of material, tool 2's pass there cuts it.
        const BlockLoad pass = block_load(p, m, "T2 in the previous slot");
        INFO("T2's pass through the uncut stock: peak " << pass.peak_N << " N, removed " << pass.removed_mm3 << " mm3");
        CHECK(pass.peak_N > 50);
        CHECK(pass.removed_mm3 > 0.5 * 30 * 8 * 1.5);
        CHECK_FALSE(has_flag(summary(p, "T2 in the previous slot"), "unknown_tool"));
    }
}

TEST_CASE("tool table: samples that name no tool take the spec's tool, else a table of one, else they are unknown", "[engine][tools]") {
    const SlotTool& t = kTools[1];
    // A slot with no tool channel.
    const auto m = enginetest::legs_motion({-12, t.slot_y_mm, kTop - t.depth_mm},
                                           {{{40, t.slot_y_mm, kTop - t.depth_mm}, feed_mm_min(t), "slot", t.rpm}});
    REQUIRE(m.tool.empty());
    force_model::RunSpec table_only = three_tool_spec();
    force_model::RunSpec table_of_one = table_only;
    table_of_one.tools = {table_only.tools[1]};
    force_model::RunSpec with_tool = table_only;
    with_tool.has_tool = true;
    with_tool.tool = tool_spec(t);

    const auto p_tool = enginetest::run_on(m, with_tool, force_model::Device::Cpu);
    const auto p_one = enginetest::run_on(m, table_of_one, force_model::Device::Cpu);
    const auto p_none = enginetest::run_on(m, table_only, force_model::Device::Cpu);
    const double t_mid = 30 / (feed_mm_min(t) / 60);   // x = 18: well inside the slot
    const double mean_tool = enginetest::load_between(p_tool, t_mid - 0.5, t_mid + 0.5).mean_N;
    const double mean_one = enginetest::load_between(p_one, t_mid - 0.5, t_mid + 0.5).mean_N;
    CHECK(mean_tool > 50);
    CHECK(mean_one == Approx(mean_tool).epsilon(1e-6));
    CHECK(p_tool.stats.unknown_tool_samples == 0);
    CHECK(p_one.stats.unknown_tool_samples == 0);
    CHECK(p_one.blocks[0].tool == 2);   // the table's one tool names its rows
    CHECK(p_tool.blocks[0].tool == -1);  // the run's tool has no T number
    // A table of three and nothing naming the tool: unknown.
    CHECK(p_none.stats.unknown_tool_samples == m.size());
    CHECK(p_none.stats.unknown_tools == std::vector<int>{-1});
    CHECK(has_flag(p_none.blocks[0], "unknown_tool"));
    CHECK(enginetest::load_between(p_none, t_mid - 0.5, t_mid + 0.5).peak_N == 0);
}

TEST_CASE("three tools: windows resumed at stock checkpoints across the tool changes and an unknown tool are the whole "
          "run's rows") {
    const motion_io::MotionModel m = three_tool_motion();
    for (const bool with_t1 : {true, false}) {   // without T1 in the table its stretch is an unknown tool
        const force_model::RunSpec spec = three_tool_spec(with_t1);
        for (const force_model::Device device : devices_under_test()) {
            INFO((device == force_model::Device::Cpu ? "cpu" : "opencl") << (with_t1 ? "" : ", T1 unknown"));
            std::vector<enginetest::TakenCheckpoint> taken;
            const auto full = enginetest::run_with_checkpoints(m, spec, device, 0.5, taken);
            REQUIRE(taken.size() >= 3);
            std::size_t windows = 0, cutting = 0;
            for (const enginetest::TakenCheckpoint& c : taken)
                for (const double dt : {0.0, 0.4}) {
                    const double from_s = c.at.t_s + dt, to_s = from_s + 0.5;
                    if (from_s >= m.t_s.back()) continue;
                    INFO("checkpoint at " << c.at.t_s << " s, window " << from_s << " .. " << to_s << " s");
                    const auto win = enginetest::resumed_window(m, spec, device, c, from_s, to_s);
                    auto first = std::lower_bound(full.samples.begin(), full.samples.end(), from_s,
                                                  [](const force_model::ForceSample& r, double t) { return r.t_s < t; });
                    std::size_t k = 0, same = 0;
                    for (auto it = first; it != full.samples.end() && it->t_s < to_s; ++it, ++k)
                        same += k < win.samples.size() && enginetest::same_row(*it, win.samples[k]) ? 1 : 0;
                    CHECK(win.samples.size() == k);
                    CHECK(same == k);
                    ++windows;
                    for (const auto& r : win.samples)
                        if (std::abs(r.fx_N) + std::abs(r.fy_N) > 10) {
                            ++cutting;
                            break;
                        }
                }
            CHECK(windows >= 6);
            CHECK(cutting >= 2);   // not a comparison of zeros
        }
    }
}
