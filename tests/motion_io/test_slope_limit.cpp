// The slope limit of the velocity stage (stages/velocity.hpp, SlopeLimit): the Hermite between two
// knots stays within their positions, up to the limit's tolerance; densely sampled motion is left
// as the least-squares slopes give it; linear axes are limited across sparse readings only.
#include "motion_io/hermite.hpp"
#include "pipeline.hpp"
#include "stages/standard.hpp"
#include "stages/velocity.hpp"
#include "test_helpers.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <optional>
#include <random>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;
using detail::limit_slope;

namespace {

// The grid of a whole CSV log through the standard chain with the given slope limit.
std::vector<detail::GridSample> resampled(const std::string& path, const detail::SlopeLimit& limit, double step_ms = 1) {
    struct Collect final : detail::GridSink {
        std::vector<detail::GridSample> samples;
        void sample(const detail::GridSample& g) override { samples.push_back(g); }
    } sink;
    detail::Diagnostics diag(path);
    detail::ChainSettings settings;
    settings.step_s = step_ms * 1e-3;
    settings.slopes = limit;
    const auto chain = detail::make_ingest_chain(diag, sink, settings);
    ReadOptions opt;
    opt.step_ms = step_ms;
    detail::BlockTable blocks;
    detail::read_csv(path, opt, diag, blocks, *chain);
    return sink.samples;
}

detail::SlopeLimit no_limit() {
    detail::SlopeLimit l;
    l.linear = l.rotary = false;
    return l;
}

}  // namespace

TEST_CASE("slope limit: the bound at a knot from its two secants", "[velocity][slope_limit]") {
    const double h = 0.3, no_tol = 0;
    // Locally monotone: the sign of the secants, at most 3 times the smaller.
    CHECK(limit_slope(10, 1.0, 2.0, h, no_tol) == 3);
    CHECK(limit_slope(2.5, 1.0, 2.0, h, no_tol) == 2.5);
    CHECK(limit_slope(-1, 1.0, 2.0, h, no_tol) == 0);
    CHECK(limit_slope(-10, -1.0, -2.0, h, no_tol) == -3);
    CHECK(limit_slope(1, -1.0, -2.0, h, no_tol) == 0);
    // Standing on one side: 0 (the index's last standing knot, whatever the fit says).
    CHECK(limit_slope(300, 0.0, 600.0, h, no_tol) == 0);
    CHECK(limit_slope(300, 600.0, 0.0, h, no_tol) == 0);
    CHECK(limit_slope(-1, 0.0, 0.0, h, no_tol) == 0);
    // Turning back (180 -> 180.0091 -> 166.29 on the Okuma log): 0.
    CHECK(limit_slope(-45, 0.03, -45.0, h, no_tol) == 0);
    CHECK(limit_slope(0.05, 0.03, -45.0, h, no_tol) == 0);
    // A session's end: the one secant's sign, at most 3 times it.
    CHECK(limit_slope(10, std::nullopt, 2.0, h, no_tol) == 6);
    CHECK(limit_slope(-1, 2.0, std::nullopt, h, no_tol) == 0);
    CHECK(limit_slope(-1, 0.0, std::nullopt, h, no_tol) == 0);
    CHECK(limit_slope(7, std::nullopt, std::nullopt, h, no_tol) == 7);
    // The tolerance widens every bound by 4 tol / h: 5 mm/s for 5 um over 4 ms, 0.067 over 0.3 s.
    CHECK(limit_slope(4, 0.0, 250.0, 0.004, 0.005) == 4);
    CHECK(limit_slope(8, 0.0, 250.0, 0.004, 0.005) == Approx(5));
    CHECK(limit_slope(-8, 0.0, 250.0, 0.004, 0.005) == Approx(-5));
    CHECK(limit_slope(300, 0.0, 600.0, 0.3, 0.005) == Approx(0.02 / 0.3));
}

TEST_CASE("slope limit: between two readings the Hermite stays within them, up to the tolerance",
          "[velocity][slope_limit]") {
    // Random readings: runs up, down and standing, unequally spaced, with slopes that overshoot.
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> u01(0, 1);
    for (const double tol : {0.0, 0.005}) {
        std::vector<double> t{0}, p{0};
        for (int i = 1; i < 400; ++i) {
            t.push_back(t.back() + 0.002 + 0.5 * u01(rng) * u01(rng));
            const double r = u01(rng);
            p.push_back(p.back() + (r < 0.3 ? 0.0 : r < 0.7 ? 200 * u01(rng) : -5 * u01(rng)));
        }
        std::vector<double> v(t.size());
        for (std::size_t i = 0; i < t.size(); ++i) {
            std::optional<double> dl, dr;
            if (i > 0) dl = (p[i] - p[i - 1]) / (t[i] - t[i - 1]);
            if (i + 1 < t.size()) dr = (p[i + 1] - p[i]) / (t[i + 1] - t[i]);
            const double h_max = std::max(i > 0 ? t[i] - t[i - 1] : 0.0, i + 1 < t.size() ? t[i + 1] - t[i] : 0.0);
            const double fitted = (2 * u01(rng) - 1) * 5000;   // whatever a fit gave
            v[i] = limit_slope(fitted, dl, dr, h_max, tol);
        }
        for (std::size_t i = 0; i + 1 < t.size(); ++i) {
            const HermiteSegment seg{p[i], v[i], p[i + 1], v[i + 1], t[i + 1] - t[i]};
            const double lo = std::min(p[i], p[i + 1]) - tol * (1 + 1e-9) - 1e-9, hi = std::max(p[i], p[i + 1]) + tol * (1 + 1e-9) + 1e-9;
            for (int k = 0; k <= 64; ++k) {
                const double x = seg.position(k / 64.0);
                INFO("interval " << i << " tol " << tol << " u " << k / 64.0);
                REQUIRE(x >= lo);
                REQUIRE(x <= hi);
            }
        }
    }
}

TEST_CASE("slope limit: densely sampled logs resample as without it", "[velocity][slope_limit]") {
    // The bundled dry runs (6 ms reads, 1 um and 0.001 deg, acceleration-limited corners, a five-axis
    // one with a C turn in G93) and a constant-feed line: the limit's widening (several mm/s over
    // a few ms) leaves the least-squares slopes alone.
    TempFile line("slope_line.csv", synth_csv(straight_line_spec(2000, 30)));
    for (const std::string& path : {source_path("data/demo_dryrun.csv"), source_path("data/demo3_dryrun.csv"), line.path()}) {
        INFO(path);
        const auto a = resampled(path, detail::SlopeLimit{}), b = resampled(path, no_limit());
        REQUIRE(a.size() == b.size());
        REQUIRE(a.size() > 1000);
        double dp = 0, dv = 0, dr = 0, dw = 0;
        for (std::size_t i = 0; i < a.size(); ++i)
            for (int k = 0; k < 3; ++k) {
                dp = std::max(dp, std::abs(a[i].p_mm[k] - b[i].p_mm[k]));
                dv = std::max(dv, std::abs(a[i].v_mm_s[k] - b[i].v_mm_s[k]));
                dr = std::max(dr, std::abs(a[i].rot_deg[k] - b[i].rot_deg[k]));
                dw = std::max(dw, std::abs(a[i].rot_vel_deg_s[k] - b[i].rot_vel_deg_s[k]));
            }
        CHECK(dp == 0);
        CHECK(dv == 0);
        CHECK(dr == 0);
        CHECK(dw == 0);
    }
}
