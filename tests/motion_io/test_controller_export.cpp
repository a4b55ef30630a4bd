// Controller exports of any shape through channel maps: per-axis columns without a time column,
// 3 significant digits in E-notation, commanded beside actual positions, and coarse data said out
// loud (position_quantized naming the step, sampling_coarse against the tooth period).
#include "controller_export.hpp"
#include "test_helpers.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>

using namespace cutload::motion_io;
using namespace cutload::motion_io::test;

namespace {

const IngestWarning* warning(const IngestReport& r, const std::string& code) {
    for (const auto& w : r.warnings)
        if (w.code == code) return &w;
    return nullptr;
}

std::size_t index_at(const MotionModel& m, double t_s) {
    const auto i = static_cast<std::size_t>(std::llround((t_s - m.t_s.front()) / m.step_s));
    REQUIRE(i < m.size());
    REQUIRE(m.t_s[i] == Approx(t_s).margin(1e-9));
    return i;
}

std::string block_at(const MotionModel& m, std::size_t i) {
    return m.block[i] < 0 ? std::string() : m.block_names[static_cast<std::size_t>(m.block[i])];
}

}  // namespace

TEST_CASE("controller export: per-axis E-notation columns without time read through a preset map", "[csv][map]") {
    for (const std::uint64_t seed : {1u, 2u, 3u}) {
        const ControllerExport log = umich_like_export(seed);
        TempFile f("umich_like_" + std::to_string(seed) + ".csv", log.csv);
        ReadOptions opt;
        opt.map_file = "umich_cnc_mill";
        opt.step_ms = 10;
        IngestReport report;
        const MotionModel m = ingest(f.path(), opt, &report);
        INFO("seed " << seed);

        // The time axis comes from the map's 100 ms period.
        CHECK(report.channels.at("pos").interval.median_s == Approx(0.1));
        CHECK(report.duration_s == Approx(0.1 * static_cast<double>(log.actual_mm.size() - 1)));
        // Written in 1 mm steps (3 significant digits at 100-999 mm): said, with the step.
        REQUIRE(report.position_step_mm);
        CHECK(*report.position_step_mm == 1.0);
        const IngestWarning* q = warning(report, "position_quantized");
        REQUIRE(q != nullptr);
        CHECK_THAT(q->message, Catch::Contains("steps of 1 mm") && Catch::Contains("E+02") && Catch::Contains("100 ms apart") &&
                                   Catch::Contains("+-5 mm/s"));
        CHECK(report.commanded_positions);

        // Every row's repaired position is the written one: within half a step of the truth. The
        // exception: a standstill reading followed by a move is dropped as a stale repeat by the
        // repair stage (docs/ingest.md), so at those rows the model already moves; there the error
        // stays under half of one row's travel at 50 mm/s (2.5 mm).
        const std::size_t stale = report.channels.at("pos").stale_dropped;
        auto check_rows = [&](const MotionModel& model, const std::vector<std::array<double, 3>>& truth, double tol_mm) {
            std::size_t off = 0;
            double worst_mm = 0;
            for (std::size_t k = 0; k < truth.size(); ++k) {
                const std::size_t i = index_at(model, 0.1 * static_cast<double>(k));
                const double e = std::max({std::fabs(model.x_mm[i] - truth[k][0]), std::fabs(model.y_mm[i] - truth[k][1]),
                                           std::fabs(model.z_mm[i] - truth[k][2])});
                worst_mm = std::max(worst_mm, e);
                off += e > 0.5 + tol_mm;
            }
            CHECK(off <= stale);
            CHECK(worst_mm < 2.5);
        };
        CHECK(stale <= 2);
        check_rows(m, log.actual_mm, 4 * 0.005);
        // Blocks: each row's line from its time on (the middle of the row interval, clear of rounding).
        for (std::size_t k = 0; k + 1 < log.line.size(); ++k)
            CHECK(block_at(m, index_at(m, 0.1 * static_cast<double>(k) + 0.05)) == "N" + std::to_string(log.line[k]));

        // The commanded positions read as a motion of their own.
        ReadOptions cmd = opt;
        cmd.positions = Positions::Commanded;
        const MotionModel c = ingest(f.path(), cmd);
        check_rows(c, log.command_mm, 1e-9);
        double lag_seen_mm = 0;
        for (std::size_t k = 0; k < log.command_mm.size(); ++k)
            for (int a = 0; a < 3; ++a) lag_seen_mm = std::max(lag_seen_mm, std::fabs(log.command_mm[k][a] - log.actual_mm[k][a]));
        CHECK(lag_seen_mm > 0.5);   // 30 ms at 20-50 mm/s: the two paths do differ
    }
}

TEST_CASE("controller export: the real UMich export through its preset, quantization named", "[csv][map][shared]") {
    ReadOptions opt;
    opt.map_file = "umich_cnc_mill";
    IngestReport report;
    const MotionModel m = ingest(shared_path("data/real/umich_cnc_mill/experiment_05.csv"), opt, &report);
    // 462 rows every 100 ms (SOURCE.md), positions 1.98E+02 style.
    CHECK(report.channels.at("pos").interval.median_s == Approx(0.1));
    CHECK(report.duration_s == Approx(46.1));
    REQUIRE(report.position_step_mm);
    CHECK(*report.position_step_mm == 1.0);
    const IngestWarning* q = warning(report, "position_quantized");
    REQUIRE(q != nullptr);
    CHECK_THAT(q->message, Catch::Contains("steps of 1 mm"));
    CHECK(report.commanded_positions);
    CHECK(std::find(m.block_names.begin(), m.block_names.end(), "N14") != m.block_names.end());
    CHECK(std::find(m.block_names.begin(), m.block_names.end(), "N2") != m.block_names.end());
    CHECK(std::none_of(m.block_names.begin(), m.block_names.end(), [](const std::string& b) { return b.find('E') != std::string::npos; }));
    // Its home position as the file writes it.
    CHECK(m.x_mm.front() == Approx(198));
    CHECK(m.y_mm.front() == Approx(158));
    CHECK(m.z_mm.front() == Approx(119));
    CHECK_NOTHROW(report_to_json(report).dump());
}

TEST_CASE("controller export: sampling_coarse compares the period with a tooth period at the logged speed", "[csv][map]") {
    // 6000 rpm and 2 teeth: a tooth every 60 / (6000 * 2) s = 5 ms.
    auto log = [](double period_s) {
        std::string s = "t,x,y,z,spindle\n";
        for (int i = 0; i <= 200; ++i) {
            const double t = i * period_s;
            s += std::to_string(t) + "," + std::to_string(10 + 20 * t) + ",0,0,6000\n";
        }
        return s;
    };
    TempFile coarse("coarse_10ms.csv", log(0.010)), fine("fine_1ms.csv", log(0.001));
    IngestReport rc, rf;
    (void)ingest(coarse.path(), ReadOptions{}, &rc);
    (void)ingest(fine.path(), ReadOptions{}, &rf);
    CHECK(rc.spindle_max_rpm == 6000);
    const SamplingCheck c = check_sampling(rc, 2), f = check_sampling(rf, 2);
    CHECK(c.tooth_period_s == Approx(0.005));
    CHECK(c.sample_period_s == Approx(0.010));
    CHECK(c.sampling_coarse);
    CHECK(c.coarse());
    REQUIRE(c.warnings.size() == 1);
    CHECK_THAT(c.warnings[0].message, Catch::Contains("every 10 ms") && Catch::Contains("5 ms at 6000 rpm with 2 teeth"));
    CHECK_FALSE(f.sampling_coarse);
    CHECK_FALSE(f.coarse());
    CHECK(f.warnings.empty());
    // Positions written to 1 um: not quantized.
    REQUIRE(rf.position_step_mm);
    CHECK(*rf.position_step_mm == Approx(1e-6));
    CHECK_FALSE(c.position_quantized);
    CHECK(to_json(c)["coarse"] == true);
}

TEST_CASE("controller export: steady motion in equal steps is not taken for quantization", "[csv][map]") {
    // Every reading 0.400 mm after the last, written to 1 um: one repeated difference is steady
    // motion, not a 0.4 mm resolution.
    std::string s = "t,x,y,z\n";
    for (int i = 0; i <= 100; ++i) s += std::to_string(0.004 * i) + "," + std::to_string(100 + 0.4 * i).substr(0, 7) + ",5.000,-2.000\n";
    TempFile f("steady.csv", s);
    IngestReport r;
    (void)ingest(f.path(), ReadOptions{}, &r);
    REQUIRE(r.position_step_mm);
    CHECK(*r.position_step_mm == Approx(0.001));
    CHECK(warning(r, "position_quantized") == nullptr);
    // The same motion written to 0.05 mm steps, differences varying: the step is the common divisor.
    std::string q = "t,x,y,z\n";
    for (int i = 0; i <= 100; ++i) {
        const double x = 100 + 0.05 * std::round((0.37 * i + 0.002 * i * i) / 0.05);
        char buf[64];
        std::snprintf(buf, sizeof buf, "%.3f,%.3f,5.000,-2.000\n", 0.004 * i, x);
        q += buf;
    }
    TempFile g("steps_50um.csv", q);
    (void)ingest(g.path(), ReadOptions{}, &r);
    REQUIRE(r.position_step_mm);
    CHECK(*r.position_step_mm == Approx(0.05));
    REQUIRE(warning(r, "position_quantized") != nullptr);
    CHECK_THAT(warning(r, "position_quantized")->message, Catch::Contains("steps of 0.05 mm"));
}

TEST_CASE("controller export: the axis_act and time_ms presets", "[csv][map]") {
    std::string a = "Time,X_ACT,Y_act,Z_Act,X_cmd,Y_cmd,Z_cmd,S_act,N\n";
    for (int i = 0; i <= 100; ++i) {
        const double t = 0.004 * i, x = 10 + 100 * t;
        char buf[160];
        std::snprintf(buf, sizeof buf, "%.3f,%.4f,2.0000,-5.0000,%.4f,2.0000,-5.0000,8000,%s\n", t, x - 0.3, x,
                      i < 50 ? "N10" : "N20");
        a += buf;
    }
    TempFile fa("axis_act.csv", a);
    ReadOptions opt;
    opt.map_file = "axis_act";
    opt.step_ms = 4;
    IngestReport r;
    const MotionModel m = ingest(fa.path(), opt, &r);
    CHECK(r.commanded_positions);
    CHECK(r.spindle_max_rpm == 8000);
    CHECK(warning(r, "unknown_column") == nullptr);
    CHECK(m.x_mm.front() == Approx(9.7));
    CHECK(m.vx_mm_s[50] == Approx(100));
    CHECK(block_at(m, m.size() - 1) == "N20");
    opt.positions = Positions::Commanded;
    CHECK(ingest(fa.path(), opt).x_mm.front() == Approx(10.0));

    std::string t = "time_ms,x,y,z\n";
    for (int i = 0; i <= 100; ++i) t += std::to_string(4 * i) + "," + std::to_string(10 + 0.4 * i) + ",0,0\n";
    TempFile ft("time_ms.csv", t);
    ReadOptions topt;
    topt.map_file = "time_ms";
    topt.step_ms = 4;
    IngestReport tr;
    const MotionModel tm = ingest(ft.path(), topt, &tr);
    CHECK(tr.duration_s == Approx(0.4));
    CHECK(tm.vx_mm_s[50] == Approx(100));
    // Without the preset the same file has no time column.
    CHECK_THROWS_WITH(ingest(ft.path(), ReadOptions{}), Catch::Contains("missing required time column"));
}

TEST_CASE("controller export: map files for CSV name their mistakes", "[csv][map]") {
    const std::string rows = "X1_ActualPosition,Y1_ActualPosition,Z1_ActualPosition,t\n1,2,3,0\n1.1,2,3,0.1\n";
    TempFile f("mapped.csv", rows);
    auto error_with = [&](const std::string& map_text) {
        TempFile map("csv_map.json", map_text);
        ReadOptions opt;
        opt.map_file = map.path();
        try {
            ingest(f.path(), opt);
        } catch (const IngestError& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    CHECK_THAT(error_with(R"({"position": "pos"})"), Catch::Contains("csv_map.json") && Catch::Contains("'position'"));
    CHECK_THAT(error_with(R"({"x": "X1_ActualPosition", "y": "Y1_ActualPosition", "z": "Z1_ActualPosition",
                              "sample_period_ms": 100})"),
               Catch::Contains("mapped.csv:1") && Catch::Contains("sample_period_ms"));
    CHECK_THAT(error_with(R"({"x": "X1_ActualPosition", "y": "Y1_ActualPosition", "z": "Z_nowhere"})"),
               Catch::Contains("mapped.csv:1") && Catch::Contains("'Z_nowhere'") && Catch::Contains("csv_map.json"));
    CHECK_THAT(error_with(R"({"x": "X1_ActualPosition", "y": "Y1_ActualPosition", "z": "Z1_ActualPosition",
                              "units": {"length": "furlong"}})"),
               Catch::Contains("unknown length unit 'furlong'"));
    CHECK_THAT(error_with(R"({"sample_period_ms": -1})"), Catch::Contains("sample_period_ms"));
    // A number beyond a double names the map's line, column and key (issue 19), not the JSON
    // library's bare "number overflow".
    CHECK_THAT(error_with("{\"x\": \"X1_ActualPosition\",\n \"sample_period_ms\": 1e400}"),
               Catch::Contains("csv_map.json:2:22: sample_period_ms: the number 1e400 is out of range") &&
                   !Catch::Contains("overflow"));
    CHECK_THAT(error_with(R"({"x": ["X1", )"), Catch::Contains("csv_map.json:1:") && Catch::Contains("not valid JSON"));
    // A preset name that does not exist lists the ones that do.
    ReadOptions opt;
    opt.map_file = "no_such_preset";
    CHECK_THROWS_WITH(ingest(f.path(), opt), Catch::Contains("no_such_preset") && Catch::Contains("umich_cnc_mill") &&
                                                 Catch::Contains("axis_act") && Catch::Contains("time_ms"));
    // block_prefix wants whole numbers.
    TempFile b("block_prefix.csv", "t,x,y,z,seq\n0,1,2,3,1.40E+01\n0.1,1.1,2,3,1.45E+01\n");
    TempFile map("prefix_map.json", R"({"block": "seq", "block_prefix": "N"})");
    opt.map_file = map.path();
    CHECK_THROWS_WITH(ingest(b.path(), opt), Catch::Contains("block_prefix.csv:3:") && Catch::Contains("'1.45E+01'") &&
                                                 Catch::Contains("whole block number"));
}
