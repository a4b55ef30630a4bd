// `cutload compare --frame workpiece|machine` as a user runs it: a five-axis run predicted with
// --machine, compared with a record taken by a dynamometer that does not turn with the part (fixed
// to the bed: machine axes), read from FORCES.csv and FORCES.bin; a prediction made without a
// machine has no machine-axis forces, and --frame machine refuses it in one line.
#include "cli/run_cli.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

using namespace cutload;
namespace fs = std::filesystem;

namespace {

// Readings every 4 ms of a side cut along the part's +X (tool centre 2 mm off the demo stock's
// y = -300 wall, so ae 2 mm, 3 mm deep, 20 mm/s, 10 000 rpm), commanded through the AC machine
// (data/machines/ac_table_table.json) with its C table at c_deg. A point of the part on the table
// at p (C = 0) lies at pivot + R_z(-c) (p - pivot) in machine axes, the C line's pivot at
// (-350, -275): the X and Y a controller reads.
std::string c_turned_side_cut_log(double c_deg) {
    const double c_rad = c_deg * 3.14159265358979323846 / 180;
    const double pivot_x_mm = -350, pivot_y_mm = -275;
    std::string csv = "t,x,y,z,a,c,spindle,block\n";
    for (int k = 0; k <= 250; ++k) {
        const double t_s = 0.004 * k;
        // The stock spans x 200..305 at C = 0: the tool (radius 4 mm) starts 2 mm clear of it.
        const double part_x_mm = 194 + 20 * t_s - pivot_x_mm, part_y_mm = -302 - pivot_y_mm;
        const double x_mm = pivot_x_mm + std::cos(c_rad) * part_x_mm + std::sin(c_rad) * part_y_mm;
        const double y_mm = pivot_y_mm - std::sin(c_rad) * part_x_mm + std::cos(c_rad) * part_y_mm;
        csv += fmt::format("{:.4f},{:.4f},{:.4f},-323.0000,0,{:.3f},10000,N10\n", t_s, x_mm, y_mm, c_deg);
    }
    return csv;
}

std::vector<std::string> split(const std::string& line) {
    std::vector<std::string> out;
    std::stringstream in(line);
    for (std::string field; std::getline(in, field, ',');) out.push_back(field);
    return out;
}

// What a dynamometer fixed to the bed would record of that prediction: the force on the workpiece
// (minus the force on the tool) in machine axes, one sample per FORCES.csv row (the engine's
// constant angle step gives an even sampling), noise-free. Returns the number of samples.
std::size_t write_bed_dyno_record(const fs::path& forces_csv, const fs::path& record) {
    std::ifstream in(forces_csv);
    std::string line;
    REQUIRE(std::getline(in, line));
    const std::vector<std::string> header = split(line);
    auto col = [&](const char* name) {
        const auto it = std::find(header.begin(), header.end(), name);
        REQUIRE(it != header.end());
        return static_cast<std::size_t>(it - header.begin());
    };
    const std::size_t ct = col("t_s"), cx = col("fx_machine_N"), cy = col("fy_machine_N"), cz = col("fz_machine_N");
    std::ofstream out(record);
    out << "t,fx,fy,fz\n";
    std::size_t samples = 0;
    while (std::getline(in, line)) {
        const std::vector<std::string> f = split(line);
        out << fmt::format("{},{:.3f},{:.3f},{:.3f}\n", f.at(ct), -std::stod(f.at(cx)), -std::stod(f.at(cy)),
                           -std::stod(f.at(cz)));
        ++samples;
    }
    return samples;
}

nlohmann::json compare_json(const std::string& args) {
    const clitest::Result r = clitest::run("compare " + args + " --json");
    INFO("compare " << args << "\n" << r.output);
    REQUIRE(r.exit_code == 0);
    return nlohmann::json::parse(r.output);
}

double metric(const nlohmann::json& report, const char* axis, const char* name) {
    return report.at("overall").at(axis).at(name).get<double>();
}

}  // namespace

TEST_CASE("compare --frame machine: a bed dynamometer's record of a C-turned cut matches the machine-axis forces, "
          "the workpiece frame is a quarter turn off",
          "[cli][compare][five_axis]") {
    const fs::path dir = clitest::scratch("compare_frame_cli");
    const std::string spec = clitest::source("data/demo_run.json");
    const std::string machine = clitest::source("data/machines/ac_table_table.json");
    std::ofstream(dir / "c90.csv") << c_turned_side_cut_log(90);
    for (const char* out : {"turned.csv", "turned.bin"}) {
        const clitest::Result r = clitest::run("predict " + (dir / "c90.csv").string() + " --spec " + spec +
                                               " --machine " + machine + " --device cpu -q --out " + (dir / out).string());
        INFO(r.output);
        REQUIRE(r.exit_code == 0);
    }
    const fs::path record = dir / "bed_dyno.csv";
    CHECK(write_bed_dyno_record(dir / "turned.csv", record) > 20000);   // 1 s at 30 kHz (2 deg steps)

    // --offset-s 0: the record is the prediction's own clock, so the two frames are compared at the
    // same instants rather than each at its best cross-correlation.
    const std::string given = " --measured " + record.string() + " --offset-s 0";
    const std::string csv = "--predicted " + (dir / "turned.csv").string() + given;
    const nlohmann::json machine_frame = compare_json(csv + " --frame machine");
    const nlohmann::json workpiece_frame = compare_json(csv + " --frame workpiece");
    CHECK(machine_frame["predicted"]["frame"] == "machine");
    CHECK(workpiece_frame["predicted"]["frame"] == "workpiece");

    const double peak_N = std::max(metric(machine_frame, "x", "peak_measured_N"), metric(machine_frame, "y", "peak_measured_N"));
    INFO("peak |Fx|, |Fy| measured " << peak_N << " N");
    REQUIRE(peak_N > 50);   // it cuts
    // The record is the machine-axis columns to their last printed digit. What is left is timing:
    // the record's sampling grid is the even one its first and last times give, while each row's
    // t_s is rounded to 1 us (of a 33 us step), so the prediction is read up to 0.5 us off its rows
    // where the force changes at up to a few N per us (tooth entry): 0.04 N rmse, 2e-4 of the peak.
    const double rounding_N = 1e-3 * peak_N;
    for (const char* axis : {"x", "y", "z", "resultant"}) {
        INFO("machine frame, axis " << axis);
        CHECK(std::abs(metric(machine_frame, axis, "mean_error_N")) < rounding_N);
        CHECK(metric(machine_frame, axis, "rmse_N") < rounding_N);
        CHECK(metric(machine_frame, axis, "correlation") > 0.99999);
    }
    // At C = 90 deg, machine (Fx, Fy) = workpiece (Fy, -Fx): compared in workpiece axes, x and y are
    // off by far more than any model error, while |F| (no frame has it turned) still matches.
    for (const char* axis : {"x", "y"}) {
        INFO("workpiece frame, axis " << axis);
        CHECK(metric(workpiece_frame, axis, "rmse_N") > 0.2 * peak_N);
    }
    CHECK(metric(workpiece_frame, "z", "rmse_N") < rounding_N);
    CHECK(metric(workpiece_frame, "resultant", "rmse_N") < rounding_N);

    // workpiece is the default: the same report without the option.
    CHECK(compare_json(csv) == workpiece_frame);

    // FORCES.bin holds FORCES.csv's digits, machine-axis columns included: the same comparison.
    nlohmann::json from_bin = compare_json("--predicted " + (dir / "turned.bin").string() + given + " --frame machine");
    nlohmann::json from_csv = machine_frame;
    from_bin["predicted"].erase("file");
    from_csv["predicted"].erase("file");
    CHECK(from_bin == from_csv);

    // Left to find, the offset is the record's own clock, to well under one sample (33 us).
    const nlohmann::json found = compare_json("--predicted " + (dir / "turned.bin").string() + " --measured " +
                                              record.string() + " --frame machine");
    CHECK(found["offset_source"] == "cross-correlation");
    CHECK(std::abs(found["offset_s"].get<double>()) < 5e-6);

    // The text report says which columns it compared, only when they are the machine's.
    const clitest::Result text = clitest::run("compare " + csv + " --frame machine");
    INFO(text.output);
    CHECK(text.exit_code == 0);
    CHECK_THAT(text.output, Catch::Contains("frame: machine axes (predicted fx_machine_N, fy_machine_N, fz_machine_N)"));
    const clitest::Result plain_text = clitest::run("compare " + csv);
    CHECK(plain_text.exit_code == 0);
    CHECK_THAT(plain_text.output, !Catch::Contains("frame:"));
}

TEST_CASE("compare --frame machine refuses a prediction made without --machine in one line naming it",
          "[cli][compare][five_axis][errors]") {
    const fs::path dir = clitest::scratch("compare_frame_refused_cli");
    const std::string spec = clitest::source("data/demo_run.json");
    std::ofstream(dir / "c0.csv") << c_turned_side_cut_log(0);
    // A record to compare with: 1 s of zeros at 1 kHz (the prediction is refused before it is read).
    {
        std::ofstream dyno(dir / "dyno.csv");
        dyno << "t,fx,fy,fz\n";
        for (int k = 0; k <= 1000; ++k) dyno << fmt::format("{:.3f},0,0,0\n", 0.001 * k);
    }
    for (const char* name : {"three_axis.csv", "three_axis.bin"}) {
        const fs::path forces = dir / name;
        const clitest::Result p =
            clitest::run("predict " + (dir / "c0.csv").string() + " --spec " + spec + " --device cpu -q --out " + forces.string());
        INFO(p.output);
        REQUIRE(p.exit_code == 0);

        const std::string args = "compare --predicted " + forces.string() + " --measured " + (dir / "dyno.csv").string();
        const clitest::Result r = clitest::run(args + " --frame machine");
        INFO(r.output);
        CHECK(r.exit_code == 2);
        CHECK(std::count(r.output.begin(), r.output.end(), '\n') == 1);
        CHECK_THAT(r.output, Catch::StartsWith("cutload: error: " + forces.string() + ": ") &&
                                 Catch::Contains("predicted without --machine"));
        // The default frame takes it as before (its fx_N, fy_N, fz_N are machine axes too).
        const clitest::Result ok = clitest::run(args + " --offset-s 0 --cutoff-hz 0");
        INFO(ok.output);
        CHECK(ok.exit_code == 0);
    }
}
