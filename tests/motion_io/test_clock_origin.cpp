// The clock stage recovers the CNC's update grid from the readings' time stamps. Where the log's
// time zero lies is an accident of the client (when it started, or a machine clock that has run
// for days), so moving every stamp by a constant must move the repaired motion by that constant
// and change nothing else: the recovered period, the ticks, the positions on the resampled grid,
// the velocities, the spindle angle and the block boundaries.
//
// And the phase scan behind the period search (roughness_over_phases) must give what evaluating
// tick_roughness phase by phase gives, bit for bit: it is the same figure, computed incrementally.
#include "cnc_reads.hpp"
#include "stages/clock.hpp"
#include "test_helpers.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>
#include <random>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;
using detail::PosRead;

namespace {

std::string read_text_file(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    REQUIRE(in);
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

struct Ingested {
    MotionModel model;
    IngestReport report;
};

Ingested ingest_text(const std::string& name, const std::string& csv) {
    const TempFile file(name, csv);
    Ingested out;
    out.model = ingest(file.path(), ReadOptions{}, &out.report);
    return out;
}

double max_speed_mm_s(const MotionModel& m) {
    double v = 0;
    for (std::size_t i = 0; i < m.size(); ++i) v = std::max(v, speed_mm_min(m, i) / 60.0);
    return v;
}

// The shifted model is the original moved by shift_s. Time stamps near 1e6 s carry only about
// 1e-10 s (a double's resolution there), so times are compared to a few of their units in the
// last place, and positions to the distance the fastest motion covers in that time (below
// 1e-9 mm for shifts up to a few thousand seconds).
void check_same_up_to_shift(const Ingested& a, const Ingested& b, double shift_s) {
    const MotionModel &m0 = a.model, &m1 = b.model;
    REQUIRE(m1.size() == m0.size());
    REQUIRE(m0.size() > 1000);
    CHECK(m1.session_start == m0.session_start);
    CHECK(m1.block_names == m0.block_names);
    CHECK(m1.block == m0.block);   // block boundaries on the same samples
    CHECK(m1.tool == m0.tool);
    const double t_max = std::max(std::fabs(m1.t_s.front()), std::fabs(m1.t_s.back()));
    const double ulp = t_max * std::numeric_limits<double>::epsilon();
    const double tol_t = 1e-12 + 8 * ulp;
    const double v_max = max_speed_mm_s(m0);
    const double tol_mm = 1e-9 + v_max * tol_t;
    double worst_t = 0, worst_mm = 0, worst_v = 0, worst_angle = 0;
    for (std::size_t i = 0; i < m0.size(); ++i) {
        worst_t = std::max(worst_t, std::fabs(m1.t_s[i] - m0.t_s[i] - shift_s));
        worst_mm = std::max({worst_mm, std::fabs(m1.x_mm[i] - m0.x_mm[i]), std::fabs(m1.y_mm[i] - m0.y_mm[i]),
                             std::fabs(m1.z_mm[i] - m0.z_mm[i])});
        worst_v = std::max({worst_v, std::fabs(m1.vx_mm_s[i] - m0.vx_mm_s[i]), std::fabs(m1.vy_mm_s[i] - m0.vy_mm_s[i]),
                            std::fabs(m1.vz_mm_s[i] - m0.vz_mm_s[i])});
        worst_angle = std::max(worst_angle, std::fabs(m1.spindle_angle_deg[i] - m0.spindle_angle_deg[i]));
    }
    INFO("shift " << shift_s << " s: worst time " << worst_t << " s (tolerance " << tol_t << "), position " << worst_mm
                  << " mm (" << tol_mm << "), velocity " << worst_v << " mm/s, spindle angle " << worst_angle << " deg");
    CHECK(worst_t <= tol_t);
    CHECK(worst_mm <= tol_mm);
    // A velocity is a position difference over a sample step: the position tolerance over 1 ms.
    CHECK(worst_v <= 2 * tol_mm / 1e-3);
    // The angle integrates the speed over the session: the time error at 10000 rpm (60000 deg/s).
    CHECK(worst_angle <= 1e-9 + 6e4 * tol_t * 4);
    const double p0 = a.report.channels.at("pos").update_period_s, p1 = b.report.channels.at("pos").update_period_s;
    CHECK(p0 > 0);
    CHECK(std::fabs(p1 - p0) <= 1e-12 * p0);
}

// 3.028 ms: the demo's first stamp (the shift that was seen to move two blocks' mean forces by
// 17-20 %); minus it, a log starting at 0; 1234.5678 s; 1e6 s, a machine clock running for days.
constexpr long long kShiftsUs[] = {3028, -3028, 1234567800, 1000000000000};

}  // namespace

TEST_CASE("clock origin: the demo log shifted in time gives the same motion, shifted", "[clock][origin]") {
    const std::string csv = read_text_file(source_path("data/demo_dryrun.csv"));
    const Ingested base = ingest_text("origin_demo.csv", csv);
    for (long long shift_us : kShiftsUs) {
        SECTION("shift " + std::to_string(shift_us) + " us") {
            const Ingested moved = ingest_text("origin_demo_shifted.csv", shift_time_columns(csv, shift_us));
            check_same_up_to_shift(base, moved, static_cast<double>(shift_us) * 1e-6);
        }
    }
}

TEST_CASE("clock origin: a generated log with client stalls, shifted in time, gives the same motion", "[clock][origin]") {
    // The first demo's program, another client seed and a logging PC that stalls now and then:
    // unequal sampling on top of the beat against the 4 ms grid.
    DryRunSpec spec = demo_dry_run_spec();
    spec.seed = 20261123;
    spec.client.stall_probability = 0.004;
    spec.client.start_s = 0.0029;
    const std::string csv = synth_csv(spec);
    const Ingested base = ingest_text("origin_gen.csv", csv);
    for (long long shift_us : kShiftsUs) {
        SECTION("shift " + std::to_string(shift_us) + " us") {
            const Ingested moved = ingest_text("origin_gen_shifted.csv", shift_time_columns(csv, shift_us));
            check_same_up_to_shift(base, moved, static_cast<double>(shift_us) * 1e-6);
        }
    }
}

TEST_CASE("clock origin: the phase scan equals tick_roughness phase by phase, bit for bit", "[clock]") {
    std::mt19937_64 rng(14);
    std::size_t checked = 0;
    for (int trial = 0; trial < 40; ++trial) {
        CncReadSpec s;
        s.reads = 20 + 9 * static_cast<std::size_t>(trial);
        s.seed = 100 + static_cast<std::uint64_t>(trial);
        s.jitter_s = trial % 3 == 0 ? 0 : 40e-6;
        const std::vector<PosRead> reads = cnc_reads(s);
        // Trial periods around the true one and far from it (a scan visits both), on the
        // coarse, tracking and fine phase counts the period search uses.
        std::uniform_real_distribution<double> period(0.0005, 0.018);
        for (double T : {s.period_s, s.period_s * 1.0004, period(rng), period(rng)}) {
            for (int phases : {16, 32, 256}) {
                for (double offset : {0.0, 0.5}) {
                    std::vector<double> fast(static_cast<std::size_t>(phases));
                    std::size_t fast_pairs = 0, slow_pairs = 0;
                    detail::roughness_over_phases(reads.data(), reads.size(), T, phases, offset, fast.data(), &fast_pairs);
                    double least = 1e300;
                    for (int i = 0; i < phases; ++i) {
                        const double slow = detail::tick_roughness(reads.data(), reads.size(), T, T * (i + offset) / phases, &slow_pairs);
                        least = std::min(least, slow);
                        if (fast[static_cast<std::size_t>(i)] != slow) FAIL("phase " << i << " of " << phases << ", period " << T);
                    }
                    CHECK(fast_pairs == slow_pairs);
                    CHECK(detail::least_roughness_over_phases(reads.data(), reads.size(), T, phases, offset) == least);
                    ++checked;
                }
            }
        }
    }
    CHECK(checked == 40 * 4 * 3 * 2);
}
