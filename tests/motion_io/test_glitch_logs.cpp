// Issue 19, reproducer class 2: one glitched sample must not spoil or stall a run. A synthesized
// dry-run log (seeded, the seed's sampling pattern) is read clean and with glitches written into
// it as a logging PC writes them: spindle 1e10 and 1e9 rpm in 3 rows, a 5e6 rpm spike, positions
// of 1e308 in 6 rows and in one, NaN and infinity in every numeric field. The glitched reading is
// dropped with a counted warning (or the log refused naming line and column), the motion is the
// clean log's, and the report judges the sampling by what was kept.
#include "test_helpers.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <sstream>
#include <string>
#include <vector>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;

namespace {

struct Csv {
    std::string header;
    std::vector<std::vector<std::string>> rows;
};

Csv split(const std::string& text) {
    Csv c;
    std::istringstream in(text);
    std::getline(in, c.header);
    for (std::string line; std::getline(in, line);) {
        std::vector<std::string> fields;
        std::size_t start = 0;
        for (std::size_t comma; (comma = line.find(',', start)) != std::string::npos; start = comma + 1)
            fields.push_back(line.substr(start, comma - start));
        fields.push_back(line.substr(start));
        c.rows.push_back(std::move(fields));
    }
    return c;
}

std::string join(const Csv& c) {
    std::string s = c.header + "\n";
    for (const auto& r : c.rows) {
        for (std::size_t i = 0; i < r.size(); ++i) s += (i ? "," : "") + r[i];
        s += '\n';
    }
    return s;
}

// Columns of synthesize_dry_run's log.
enum Col { TSpindle, Spindle, TFeed, Feed, TPos, X, Y, Z, Block };

// A 30 mm diagonal at 1200 mm/min: 1.5 s of cutting-speed motion, about 300 rows.
const std::string& clean_log() {
    static const std::string text = [] {
        DryRunSpec spec = straight_line_spec(1200, 30, 19);
        spec.machine.spindle_ramp_s = 0.1;
        return synth_csv(spec);
    }();
    return text;
}

// The clean log with `value` written into column `col` of the given rows (0-based, after the header).
std::string glitched(Col col, std::initializer_list<std::size_t> rows, const std::string& value) {
    Csv c = split(clean_log());
    for (const std::size_t r : rows) {
        REQUIRE(r < c.rows.size());
        c.rows[r][col] = value;
    }
    return join(c);
}

struct Read {
    MotionModel model;
    IngestReport report;
};

Read read(const std::string& name, const std::string& text) {
    TempFile f(name, text);
    Read r;
    r.model = ingest(f.path(), ReadOptions{}, &r.report);
    return r;
}

std::size_t glitches(const IngestReport& r) {
    for (const auto& w : r.warnings)
        if (w.code == "glitch_dropped") return w.count;
    return 0;
}

double max_abs(const std::vector<double>& v) {
    double m = 0;
    for (const double x : v) m = std::max(m, std::fabs(x));
    return m;
}

// Over the samples both grids hold (they start alike; a lost reading may move the recovered end of
// a session by one step).
double max_diff(const std::vector<double>& a, const std::vector<double>& b) {
    REQUIRE(a.size() + 1 >= b.size());
    REQUIRE(b.size() + 1 >= a.size());
    double m = 0;
    for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) m = std::max(m, std::fabs(a[i] - b[i]));
    return m;
}

// Bounded: the glitched log's grid is the clean one's, to a step at the end.
void require_same_grid(const MotionModel& g, const MotionModel& clean) {
    REQUIRE(g.size() + 1 >= clean.size());
    REQUIRE(clean.size() + 1 >= g.size());
    REQUIRE(std::fabs(g.t_s.front() - clean.t_s.front()) < 1e-6);   // the CNC clock's phase, refit
    REQUIRE(g.session_start == clean.session_start);
}

std::string fmt_3(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.3f", v);
    return buf;
}

void require_finite(const MotionModel& m) {
    for (const auto* v : {&m.t_s, &m.x_mm, &m.y_mm, &m.z_mm, &m.vx_mm_s, &m.vy_mm_s, &m.vz_mm_s, &m.spindle_rpm,
                          &m.spindle_angle_deg})
        for (const double x : *v) REQUIRE(std::isfinite(x));
}

}  // namespace

TEST_CASE("glitched log: spindle readings of 1e10, 1e9 and 5e6 rpm in 3 rows are dropped, the run is the clean one's",
          "[glitch][issue19]") {
    const Read clean = read("glitch_clean.csv", clean_log());
    REQUIRE(clean.model.size() > 1000);
    REQUIRE(glitches(clean.report) == 0);
    const std::size_t mid = split(clean_log()).rows.size() / 2;
    for (const std::string value : {"1e10", "1e9", "5e6", "-1e10"}) {
        INFO("spindle " << value);
        const Read g = read("glitch_spindle.csv", glitched(Spindle, {mid, mid + 7, mid + 14}, value));
        CHECK(glitches(g.report) == 3);
        // Bounded: the same grid as the clean log, nothing faster than the clean spindle.
        REQUIRE(g.model.size() == clean.model.size());
        CHECK(max_abs(g.model.spindle_rpm) <= max_abs(clean.model.spindle_rpm));
        // A neighbour's reading stands in for each dropped one: the 2 rpm ripple at most twice.
        CHECK(max_diff(g.model.spindle_rpm, clean.model.spindle_rpm) <= 4.0);
        CHECK(max_diff(g.model.x_mm, clean.model.x_mm) == 0.0);
        // The tooth period the sampling check judges by is the clean log's, not 1e10 rpm's.
        CHECK(g.report.spindle_max_rpm == clean.report.spindle_max_rpm);
        const SamplingCheck sc = check_sampling(g.report, 2), cc = check_sampling(clean.report, 2);
        CHECK(sc.tooth_period_s == cc.tooth_period_s);
        CHECK(sc.sampling_coarse == cc.sampling_coarse);
    }
}

TEST_CASE("glitched log: positions of 1e308 in 6 rows or in one are dropped, the path is the clean one's",
          "[glitch][issue19]") {
    const Read clean = read("glitch_clean.csv", clean_log());
    const std::size_t mid = split(clean_log()).rows.size() / 2;
    struct Case {
        Col col;
        std::vector<std::size_t> rows;
        const char* value;
    };
    for (const Case& c : {Case{X, {mid, mid + 11, mid + 22, mid + 33, mid + 44, mid + 55}, "1e308"},
                          Case{X, {mid}, "1e308"}, Case{Y, {mid + 3}, "-1.7976931348623157e308"},
                          Case{Z, {mid, mid + 1}, "9e9"}}) {
        INFO("column " << int(c.col) << " = " << c.value << " in " << c.rows.size() << " rows");
        Csv csv = split(clean_log());
        for (const std::size_t r : c.rows) csv.rows[r][c.col] = c.value;
        const Read g = read("glitch_pos.csv", join(csv));
        CHECK(glitches(g.report) == c.rows.size());
        require_same_grid(g.model, clean.model);
        CHECK(max_diff(g.model.t_s, clean.model.t_s) < 1e-6);
        require_finite(g.model);
        // One reading missing on a straight line at constant feed: the interpolant bridges it.
        CHECK(max_diff(g.model.x_mm, clean.model.x_mm) < 0.002);
        CHECK(max_diff(g.model.y_mm, clean.model.y_mm) < 0.002);
        CHECK(max_diff(g.model.z_mm, clean.model.z_mm) < 0.002);
        CHECK(g.report.feed_repaired_max_mm_min == Approx(clean.report.feed_repaired_max_mm_min).epsilon(0.01));
    }
}

TEST_CASE("glitched log: NaN or infinity in any numeric field is refused naming line and column", "[glitch][issue19]") {
    const std::size_t mid = split(clean_log()).rows.size() / 2;
    for (const Col col : {TSpindle, Spindle, TFeed, Feed, TPos, X, Y, Z})
        for (const std::string value : {"nan", "NaN", "inf", "-inf", "Infinity"}) {
            INFO("column " << int(col) << " = " << value);
            TempFile f("glitch_nan.csv", glitched(col, {mid}, value));
            try {
                (void)ingest(f.path(), ReadOptions{});
                FAIL("read");
            } catch (const IngestError& e) {
                const std::string line = ":" + std::to_string(mid + 2) + ":";
                CHECK_THAT(e.what(), Catch::Contains(line) && Catch::Contains("'" + value + "'"));
            }
        }
}

TEST_CASE("glitched log: an SHDR stream drops the same glitches and bridges the lost reading", "[glitch][issue19][shdr]") {
    // An adapter sampling every 8 ms (0.3 ms jitter, seeded), positions to 3 decimals, along a
    // straight line at 1200 mm/min, spindle 10000 rpm with a 1 rpm ripple. Two samples in the middle
    // carry spindle 1e10 rpm and a position of 1e308.
    const double vx = 12, vy = -16;   // mm/s: 20 mm/s along the diagonal
    const std::size_t samples = 200, glitch = 100;
    auto shdr = [&](bool glitched) {
        std::mt19937 rng(1919);
        std::uniform_real_distribution<double> jitter(-0.0003, 0.0003);
        std::string s;
        char line[200];
        for (std::size_t k = 0; k < samples; ++k) {
            const double t = 0.008 * double(k) + jitter(rng);
            const bool g = glitched && (k == glitch || k == glitch + 1);
            std::snprintf(line, sizeof line, "2024-05-06T07:00:%09.6fZ|Sspeed|%s|path_pos|%s %.3f -20.000\n", 10 + t,
                          g ? "1e10" : std::to_string(10000 + int(k % 3) - 1).c_str(),
                          g ? "1e308" : fmt_3(100 + vx * t).c_str(), 50 + vy * t);
            s += line;
        }
        return s;
    };
    auto read_shdr = [](const std::string& name, const std::string& text) {
        TempFile f(name, text);
        Read r;
        r.model = ingest(f.path(), ReadOptions{}, &r.report);
        return r;
    };
    const Read clean = read_shdr("glitch_clean.shdr", shdr(false));
    const Read g = read_shdr("glitch.shdr", shdr(true));
    CHECK(glitches(clean.report) == 0);
    CHECK(glitches(g.report) == 4);
    require_same_grid(g.model, clean.model);
    require_finite(g.model);
    CHECK(max_abs(g.model.spindle_rpm) <= max_abs(clean.model.spindle_rpm));
    CHECK(g.report.spindle_max_rpm == clean.report.spindle_max_rpm);
    // The lost readings are bridged, not taken for a held value (a hold would stall the path for
    // a sample, tenths of a mm off the line at 20 mm/s).
    // The line the clean model follows (least squares over its middle; the model's clock has its
    // own origin), and the largest distance of a model from it there.
    const MotionModel& c = clean.model;
    const double lo = c.t_s.front() + 0.1, hi = c.t_s.back() - 0.1;
    double n = 0, st = 0, stt = 0, sx = 0, stx = 0, sy = 0, sty = 0;
    for (std::size_t i = 0; i < c.size(); ++i)
        if (c.t_s[i] >= lo && c.t_s[i] <= hi) {
            const double t = c.t_s[i] - lo;
            n += 1, st += t, stt += t * t, sx += c.x_mm[i], stx += t * c.x_mm[i], sy += c.y_mm[i], sty += t * c.y_mm[i];
        }
    REQUIRE(n > 1000);
    const double fit_vx = (n * stx - st * sx) / (n * stt - st * st), fit_vy = (n * sty - st * sy) / (n * stt - st * st);
    CHECK(fit_vx == Approx(vx).epsilon(1e-3));
    CHECK(fit_vy == Approx(vy).epsilon(1e-3));
    const double x0 = (sx - fit_vx * st) / n, y0 = (sy - fit_vy * st) / n;
    auto off_line = [&](const MotionModel& m) {
        double worst = 0;
        for (std::size_t i = 0; i < m.size(); ++i)
            if (m.t_s[i] >= lo && m.t_s[i] <= hi) {
                const double t = m.t_s[i] - lo;
                worst = std::max(worst, std::hypot(m.x_mm[i] - x0 - fit_vx * t, m.y_mm[i] - y0 - fit_vy * t));
            }
        return worst;
    };
    CHECK(off_line(clean.model) < 0.003);
    CHECK(off_line(g.model) < 0.003);
}
