// PredictOptions::window: a stretch of a run recomputed on demand at full resolution. The window's
// rows must be the whole run's rows over the same times (within 0.1 % of the window's peak force,
// the bar; in fact bit for bit), although the motion before the window is walked only for
// its removal, with no engagement evaluated and no rows.
#include "force_model/engine.hpp"
#include "force_model/engine_fixtures.hpp"
#include "force_model/motion_fixtures.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <span>
#include <string>

using namespace cutload;
using namespace cutload::enginetest;
using force_model::Device;
using testref::line_to;

namespace {

// Two layers of zig-zag pocketing over a 40 x 30 mm block (ap 3 mm, stepover 3 mm with half-circle
// turns, so later passes cut against the walls the earlier ones left, round ones included), an air
// move between the layers, then a short side pass far from the rest, at 3000 mm/min and 10000 rpm.
testref::Path pocket_path() {
    testref::Path p;
    p.feed_mm_min = 3000;
    p.spindle_rpm = 10000;
    p.start_mm = {-6, 4, 7};
    auto layer = [&](double z, const std::string& name) { testref::add_zigzag_layer(p, z, name, 4, 3, 2, 34); };
    layer(7, "L1");
    p.segments.push_back(line_to({-6, 19, 20}, "lift"));
    p.segments.push_back(line_to({-6, 4, 20}, "back"));
    p.segments.push_back(line_to({-6, 4, 4}, "down"));
    layer(4, "L2");
    p.segments.push_back(line_to({-6, 19, 20}, "lift 2"));
    p.segments.push_back(line_to({-6, 28, 20}, "over"));
    p.segments.push_back(line_to({-6, 28, 7}, "down 2"));
    p.segments.push_back(line_to({46, 28, 7}, "far side"));
    return p;
}

const force_model::ForceSample* row_at(const force_model::Prediction& p, double t_s) {
    const auto it = std::lower_bound(p.samples.begin(), p.samples.end(), t_s,
                                     [](const force_model::ForceSample& r, double t) { return r.t_s < t; });
    return it != p.samples.end() && it->t_s == t_s ? &*it : nullptr;
}

struct Agreement {
    std::size_t rows = 0, full_rows = 0, missing = 0, exact = 0;
    double peak_N = 0, max_diff_N = 0;
};

Agreement compare(const force_model::Prediction& full, const force_model::Prediction& win, double from_s, double to_s) {
    Agreement a;
    for (const auto& r : full.samples)
        if (r.t_s >= from_s && r.t_s < to_s) {
            ++a.full_rows;
            a.peak_N = std::max(a.peak_N, double(std::hypot(r.fx_N, r.fy_N, r.fz_N)));
        }
    for (const auto& w : win.samples) {
        ++a.rows;
        const force_model::ForceSample* r = row_at(full, w.t_s);
        if (!r) {
            ++a.missing;
            continue;
        }
        const double d = std::max({std::abs(double(w.fx_N) - r->fx_N), std::abs(double(w.fy_N) - r->fy_N),
                                   std::abs(double(w.fz_N) - r->fz_N), 1e3 * std::abs(double(w.torque_Nm) - r->torque_Nm)});
        a.max_diff_N = std::max(a.max_diff_N, d);
        if (same_row(w, *r)) ++a.exact;
    }
    return a;
}

force_model::Prediction window_of(const motion_io::MotionModel& m, const force_model::RunSpec& spec, Device d,
                                  double from_s, double to_s) {
    force_model::PredictOptions o;
    o.device = d;
    o.window = force_model::TimeWindow{from_s, to_s};
    return force_model::predict(m, spec, o);
}

}  // namespace

TEST_CASE("window: rows recomputed on demand are the whole run's rows over the window") {
    const auto spec = base_spec(40, 30, 10);
    const testref::Path path = pocket_path();
    const auto m = testref::uniform_motion(path);
    std::vector<Device> devices{Device::Cpu};
    if (opencl_available()) devices.push_back(Device::OpenCL);
    for (Device device : devices) {
        INFO((device == Device::Cpu ? "cpu" : "opencl"));
        const auto full = run_on(m, spec, device);
        REQUIRE(full.samples.size() > 100000);
        // Where the windows lie: mid-pass of the second layer, across one of its round turns, the
        // run's start, the far side pass (nothing before it reaches it), and the run's end.
        const double t_end = m.t_s.back();
        double l2_turn = -1, far_side = -1;
        for (std::size_t i = 0; i < m.size(); ++i) {
            const std::string& b = m.block_names[std::size_t(m.block[i])];
            if (l2_turn < 0 && b == "L2 turn 2") l2_turn = m.t_s[i];
            if (far_side < 0 && b == "far side") far_side = m.t_s[i];
        }
        REQUIRE(l2_turn > 0);
        REQUIRE(far_side > 0);
        // And windows whose ends fall exactly on motion samples and on rows of the whole run.
        const std::size_t k = m.size() / 3;
        const std::size_t j = full.samples.size() / 2;
        const std::vector<std::pair<double, double>> windows{
            {l2_turn - 0.35, l2_turn - 0.05}, {l2_turn - 0.04, l2_turn + 0.12}, {0, 0.5},
            {far_side + 0.2, far_side + 0.45}, {t_end - 0.2, t_end + 1},
            {m.t_s[k], m.t_s[k + 150]}, {full.samples[j].t_s, full.samples[j + 4000].t_s}};
        for (const auto& [from_s, to_s] : windows) {
            INFO("window " << from_s << " .. " << to_s << " s");
            const auto win = window_of(m, spec, device, from_s, to_s);
            const Agreement a = compare(full, win, from_s, to_s);
            INFO(a.rows << " rows (" << a.full_rows << " in the whole run), " << a.exact << " bit for bit, largest "
                        << "difference " << a.max_diff_N << " N against a peak of " << a.peak_N << " N");
            CHECK(a.rows == a.full_rows);
            CHECK(a.missing == 0);
            CHECK(a.max_diff_N <= 1e-3 * std::max(a.peak_N, 1.0));
            // Stronger than the bar: the walk before the window is the whole run's, so the stock,
            // the batches and the removal lag are too.
            CHECK(a.exact == a.rows);
            for (const auto& r : win.samples) {
                CHECK(r.t_s >= from_s);
                CHECK(r.t_s < to_s);
            }
            CHECK(win.stats.simulated_s == Approx(std::min(to_s, t_end) - std::max(from_s, 0.0)));
            CHECK(win.stats.steps < full.stats.steps);
            CHECK(!win.final_stock);
        }
        // The cutting windows do cut (the comparison is not of zeros).
        const auto mid = window_of(m, spec, device, l2_turn - 0.35, l2_turn - 0.05);
        double peak_N = 0;
        for (const auto& r : mid.samples) peak_N = std::max(peak_N, double(std::hypot(r.fx_N, r.fy_N, r.fz_N)));
        CHECK(peak_N > 100);
        // Blocks: those the window covers, their spans inside it, their peaks the window's.
        REQUIRE(!mid.blocks.empty());
        for (const auto& b : mid.blocks) {
            CHECK(b.t_start_s >= l2_turn - 0.35);
            CHECK(b.t_end_s < l2_turn - 0.05);
        }
        CHECK(mid.blocks.front().block == "L2 pass 2");
        // Handed out as they come (rows_out), the window's rows are the same rows.
        force_model::PredictOptions o;
        o.device = device;
        o.window = force_model::TimeWindow{l2_turn - 0.35, l2_turn - 0.05};
        std::vector<force_model::ForceSample> streamed;
        o.rows_out = [&](std::span<const force_model::ForceSample> rows) {
            streamed.insert(streamed.end(), rows.begin(), rows.end());
        };
        const auto piecewise = force_model::predict(m, spec, o);
        CHECK(piecewise.samples.empty());
        REQUIRE(streamed.size() == mid.samples.size());
        for (std::size_t k = 0; k < streamed.size(); ++k) {
            INFO("row " << k);
            CHECK(same_row(streamed[k], mid.samples[k]));
        }
    }
}

TEST_CASE("window: bad windows are refused by name") {
    const auto spec = base_spec(40, 30, 10);
    auto m = testref::uniform_motion(pocket_path());
    const double t_end = m.t_s.back();
    auto refused = [&](double from_s, double to_s, const std::string& words) {
        INFO(from_s << " .. " << to_s);
        CHECK_THROWS_WITH(window_of(m, spec, Device::Cpu, from_s, to_s), Catch::Contains(words));
    };
    refused(2, 2, "must be below");
    refused(3, 1, "must be below");
    refused(std::nan(""), 1, "must be below");
    refused(t_end + 1, t_end + 2, "outside the log's motion");
    refused(-5, -1, "outside the log's motion");
    m.session_start = {0, m.size() / 2};
    refused(1, 2, "2 sessions");
}

TEST_CASE("window: resumed at a stock checkpoint, a window gives the whole run's rows") {
    const auto spec = base_spec(40, 30, 10);
    const auto m = testref::uniform_motion(pocket_path());
    std::vector<Device> devices{Device::Cpu};
    if (opencl_available()) devices.push_back(Device::OpenCL);
    for (Device device : devices) {
        INFO((device == Device::Cpu ? "cpu" : "opencl"));
        const auto plain = run_on(m, spec, device);
        std::vector<TakenCheckpoint> taken;
        const auto full = run_with_checkpoints(m, spec, device, 1.0, taken);
        // Taking checkpoints changes nothing of the run.
        REQUIRE(full.samples.size() == plain.samples.size());
        std::size_t same = 0;
        for (std::size_t k = 0; k < full.samples.size(); ++k) same += same_row(full.samples[k], plain.samples[k]) ? 1 : 0;
        CHECK(same == full.samples.size());
        // The air moves between the layers and before the far side are clean points; none comes
        // sooner than a second after the one before, and each is a sample the tool is in air at.
        REQUIRE(taken.size() >= 2);
        double last_s = m.t_s.front();
        for (const TakenCheckpoint& c : taken) {
            CHECK(c.at.t_s - last_s >= 1.0);
            CHECK(m.t_s[c.at.sample] == c.at.t_s);
            last_s = c.at.t_s;
        }
        // A checkpoint's stock holds what the whole run had removed by then: less than the box.
        const double box_mm3 = 40.0 * 30 * 10;
        CHECK(force_model::stock_volume_mm3(*taken.front().stock) < box_mm3 - 100);
        double peak_N = 0;
        for (const TakenCheckpoint& c : taken) {
            for (const double from_s : {c.at.t_s, c.at.t_s + 0.3, c.at.t_s + 1.1}) {
                const double to_s = from_s + 0.4;
                INFO("checkpoint at " << c.at.t_s << " s, window " << from_s << " .. " << to_s << " s");
                const auto win = resumed_window(m, spec, device, c, from_s, to_s);
                const Agreement a = compare(full, win, from_s, to_s);
                INFO(a.rows << " rows (" << a.full_rows << " in the whole run), " << a.exact << " bit for bit, largest "
                            << "difference " << a.max_diff_N << " N against a peak of " << a.peak_N << " N");
                CHECK(a.rows == a.full_rows);
                CHECK(a.rows > 0);
                CHECK(a.exact == a.rows);
                // From the log's start, the same window evaluates the same steps, and perhaps the
                // last batch before the checkpoint's air move too (its rows lie before from_s).
                const auto from_start = window_of(m, spec, device, from_s, to_s);
                CHECK(win.stats.steps <= from_start.stats.steps);
                CHECK(win.samples.size() == from_start.samples.size());
                for (const auto& r : win.samples) peak_N = std::max(peak_N, double(std::hypot(r.fx_N, r.fy_N, r.fz_N)));
            }
        }
        // The comparison is not of zeros: some of the resumed windows cut.
        CHECK(peak_N > 100);
    }
}

TEST_CASE("window: a resume that does not fit the motion or the window is refused by name") {
    const auto spec = base_spec(40, 30, 10);
    const auto m = testref::uniform_motion(pocket_path());
    const auto stock = force_model::make_stock(spec.stock, spec.resolution.grid_mm);
    const std::size_t k = m.size() / 2;
    auto refused = [&](force_model::PredictOptions o, const std::string& words) {
        o.device = Device::Cpu;
        CHECK_THROWS_WITH(force_model::predict(m, spec, o), Catch::Contains(words));
    };
    force_model::PredictOptions o;
    o.base_stock = stock.get();
    o.resume = force_model::StockCheckpoint{k, m.t_s[k]};
    refused(o, "no window was given");
    o.window = force_model::TimeWindow{m.t_s[k] + 0.1, m.t_s[k] + 0.2};
    o.resume->t_s += 1e-9;
    refused(o, "is not of this motion");
    o.resume = force_model::StockCheckpoint{m.size() + 5, 1.0};
    refused(o, "is not of this motion");
    o.resume = force_model::StockCheckpoint{k, m.t_s[k]};
    o.window = force_model::TimeWindow{m.t_s[k] - 0.2, m.t_s[k] - 0.1};
    refused(o, "lies after the window's start");
    o.window = force_model::TimeWindow{m.t_s[k] + 0.1, m.t_s[k] + 0.2};
    o.base_stock = nullptr;
    refused(o, "stock was not given");
}

TEST_CASE("window: a checkpoint's key changes with anything the walk reads") {
    const auto spec = base_spec(40, 30, 10);
    const auto m = testref::uniform_motion(pocket_path());
    const std::uint64_t key = force_model::checkpoint_key(m, spec, nullptr);
    CHECK(force_model::checkpoint_key(m, spec, nullptr) == key);   // a key, not a nonce
    auto other_motion = m;
    other_motion.z_mm[m.size() / 2] += 1e-9;
    CHECK(force_model::checkpoint_key(other_motion, spec, nullptr) != key);
    other_motion = m;
    other_motion.block[m.size() / 3] += 1;
    CHECK(force_model::checkpoint_key(other_motion, spec, nullptr) != key);
    auto other_spec = spec;
    other_spec.material.Krc_N_mm2 *= 1.001;
    CHECK(force_model::checkpoint_key(m, other_spec, nullptr) != key);
    other_spec = spec;
    other_spec.resolution.angle_step_deg = 1;
    CHECK(force_model::checkpoint_key(m, other_spec, nullptr) != key);
    // A base stock counts by its contents: a fresh box and one cut by a whole run differ.
    const auto box = force_model::make_stock(spec.stock, spec.resolution.grid_mm);
    const std::uint64_t with_box = force_model::checkpoint_key(m, spec, box.get());
    CHECK(with_box != key);
    force_model::PredictOptions o;
    o.device = Device::Cpu;
    const auto cut = force_model::predict(m, spec, o).final_stock;
    REQUIRE(cut);
    CHECK(force_model::checkpoint_key(m, spec, cut.get()) != with_box);
}
