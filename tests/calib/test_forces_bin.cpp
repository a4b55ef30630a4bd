// FORCES.bin: the compact export against FORCES.csv (same values to the CSV's digits), against the
// format as docs/formats.md writes it (bytes built here by hand, not by the writer), and every way a
// damaged file is refused with its byte offset.
#include "force_model/compare.hpp"
#include "force_model/force_model.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include <unistd.h>

using namespace cutload::force_model;
namespace fs = std::filesystem;

namespace {

struct Scratch {
    fs::path dir = fs::temp_directory_path() / ("cutload_forces_bin_" + std::to_string(::getpid()));
    Scratch() { fs::create_directories(dir); }
    ~Scratch() { fs::remove_all(dir); }
    std::string path(const char* name) const { return (dir / name).string(); }
};

std::string slurp(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
}

// Rows as a milling prediction writes them: time on a 1/30000 s grid with air between cuts, the
// spindle angle stepping by 2 deg, forces swinging with the tooth passes, blocks changing now and then.
Prediction made_up_run(std::size_t rows) {
    Prediction p;
    p.block_names = {"N10 G1 X10", "N20 G2 X20 Y5 R5", "N30 (Ausräumen \u00d8 10)"};
    std::mt19937 rng(14);
    std::normal_distribution<double> noise(0, 3);
    for (std::size_t i = 0; i < rows; ++i) {
        ForceSample s;
        s.t_s = 1.25 + static_cast<double>(i) / 30000.0;
        s.spindle_angle_deg = std::fmod(2.0 * static_cast<double>(i), 360.0);
        s.block = static_cast<std::int32_t>((i / 40000) % 3);
        if (i % 50000 == 7) s.block = -1;
        s.tool = i < rows / 2 ? 3 : 12;
        const bool cutting = (i / 1000) % 5 != 0;
        const double phase = s.spindle_angle_deg * M_PI / 180.0;
        if (cutting) {
            s.fx_N = static_cast<float>(320 * std::sin(2 * phase) + noise(rng));
            s.fy_N = static_cast<float>(-180 * std::cos(2 * phase) + noise(rng));
            s.fz_N = static_cast<float>(-45.5 + noise(rng));
            s.torque_Nm = static_cast<float>(1.6 + 0.01 * noise(rng));
            s.power_kW = static_cast<float>(s.torque_Nm * 10000 * 2 * M_PI / 60 / 1000);
            s.chip_mm = static_cast<float>(0.05 * std::abs(std::sin(phase)));
            s.bending_MPa = static_cast<float>(41.2 + noise(rng));
            s.radial_engagement_mm = 1.0f;
            s.axial_engagement_mm = 3.0f;
            s.removed_mm3 = static_cast<float>(0.0123 + 1e-4 * noise(rng));
            s.holder_contact = i % 77777 == 5;
        }
        p.samples.push_back(s);
    }
    return p;
}

// The value FORCES.csv prints, parsed back: what a reader of either file must see.
double printed(double v, int decimals) {
    char buf[64];
    const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed, decimals);
    return std::stod(std::string(buf, r.ptr));
}

std::string error_of(const std::string& bytes) {
    std::istringstream in(bytes);
    try {
        read_forces_bin(in, "f.bin");
    } catch (const MeasurementError& e) {
        return e.what();
    }
    return "no error";
}

void u32(std::string& s, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) s += static_cast<char>(v >> (8 * i) & 0xff);
}

}  // namespace

TEST_CASE("FORCES.bin holds every column to FORCES.csv's digits in a fifth of its size", "[calib][forces_bin]") {
    Scratch scratch;
    const Prediction p = made_up_run(150000);   // three chunks, the last one partial
    const std::string csv = scratch.path("FORCES.csv"), bin = scratch.path("FORCES.bin");
    write_forces_file(p, csv);
    write_forces_file(p, bin);
    REQUIRE(slurp(bin).rfind("\x89" "CLF\r\n\x1a\n", 0) == 0);
    const auto csv_bytes = fs::file_size(csv), bin_bytes = fs::file_size(bin);
    INFO("FORCES.csv " << csv_bytes << " B, FORCES.bin " << bin_bytes << " B");
    CHECK(bin_bytes * 4 < csv_bytes);

    const PredictedTrace from_csv = read_predicted_forces(csv);
    const PredictedTrace from_bin = read_predicted_forces(bin);
    REQUIRE(from_bin.samples.size() == p.samples.size());
    REQUIRE(from_csv.samples.size() == p.samples.size());
    CHECK(from_bin.block_names == p.block_names);
    std::size_t mismatches = 0;
    for (std::size_t i = 0; i < p.samples.size(); ++i) {
        const ForceSample &b = from_bin.samples[i], &c = from_csv.samples[i], &o = p.samples[i];
        // What FORCES.csv read back holds, exactly.
        mismatches += b.t_s != c.t_s || b.spindle_angle_deg != c.spindle_angle_deg || b.block != c.block ||
                      b.fx_N != c.fx_N || b.fy_N != c.fy_N || b.fz_N != c.fz_N;
        // The columns FORCES.csv's reader skips, against the digits it prints.
        mismatches += b.tool != o.tool || b.holder_contact != o.holder_contact ||
                      b.torque_Nm != static_cast<float>(printed(o.torque_Nm, 4)) ||
                      b.power_kW != static_cast<float>(printed(o.power_kW, 4)) ||
                      b.chip_mm != static_cast<float>(printed(o.chip_mm, 5)) ||
                      b.bending_MPa != static_cast<float>(printed(o.bending_MPa, 3)) ||
                      b.radial_engagement_mm != static_cast<float>(printed(o.radial_engagement_mm, 3)) ||
                      b.axial_engagement_mm != static_cast<float>(printed(o.axial_engagement_mm, 3)) ||
                      b.removed_mm3 != static_cast<float>(printed(o.removed_mm3, 5));
    }
    CHECK(mismatches == 0);
    CHECK(from_bin.samples[7].block == -1);
    CHECK(from_bin.samples.back().tool == 12);
}

TEST_CASE("FORCES.bin with machine axes: six more columns, read back to FORCES.csv's digits", "[calib][forces_bin]") {
    Scratch scratch;
    Prediction p = made_up_run(70000);   // two chunks
    for (std::size_t i = 0; i < p.samples.size(); ++i) {   // the table turned 90 deg: (Fx, Fy, Fz) -> (Fy, -Fx, Fz)
        ForceSample& s = p.samples[i];
        s.fx_machine_N = s.fy_N, s.fy_machine_N = -s.fx_N, s.fz_machine_N = s.fz_N;
        // and a head nodding up to 0.3 rad about Y
        const double lean_rad = 0.3 * std::sin(static_cast<double>(i) * 1e-4);
        s.tool_axis_x = static_cast<float>(std::sin(lean_rad)), s.tool_axis_y = 0, s.tool_axis_z = static_cast<float>(std::cos(lean_rad));
    }
    const std::string plain = scratch.path("plain.bin"), turned = scratch.path("turned.bin"), csv = scratch.path("turned.csv");
    write_forces_file(p, plain);
    ForcesColumns columns;
    columns.machine_axes = true;
    write_forces_file(p, turned, columns);
    write_forces_file(p, csv, columns);
    const std::string header = slurp(turned).substr(16, 2000);
    CHECK(header.find(R"({"decimals":3,"name":"fz_machine_N"})") != std::string::npos);
    CHECK(slurp(plain).find("machine") == std::string::npos);   // without the option: as before
    CHECK(slurp(csv).substr(0, slurp(csv).find('\n'))
              .ends_with(",holder_contact,fx_machine_N,fy_machine_N,fz_machine_N,tool_axis_x,tool_axis_y,tool_axis_z"));
    CHECK(header.find(R"({"decimals":6,"name":"tool_axis_z"})") != std::string::npos);

    const PredictedTrace back = read_predicted_forces(turned);
    REQUIRE(back.samples.size() == p.samples.size());
    std::size_t mismatches = 0;
    for (std::size_t i = 0; i < p.samples.size(); ++i) {
        const ForceSample &b = back.samples[i], &o = p.samples[i];
        mismatches += b.fx_machine_N != static_cast<float>(printed(o.fx_machine_N, 3)) ||
                      b.fy_machine_N != static_cast<float>(printed(o.fy_machine_N, 3)) ||
                      b.fz_machine_N != static_cast<float>(printed(o.fz_machine_N, 3)) ||
                      b.fx_N != static_cast<float>(printed(o.fx_N, 3)) ||
                      b.tool_axis_x != static_cast<float>(printed(o.tool_axis_x, 6)) ||
                      b.tool_axis_y != static_cast<float>(printed(o.tool_axis_y, 6)) ||
                      b.tool_axis_z != static_cast<float>(printed(o.tool_axis_z, 6));
    }
    CHECK(mismatches == 0);
    // A machine-axis force beyond +-1e6 N is refused like a workpiece one.
    p.samples[5].fy_machine_N = 2e6f;
    write_forces_file(p, turned, columns);
    CHECK_THROWS_WITH(read_predicted_forces(turned), Catch::Contains("row 6: force 2e+06 N is beyond"));
}

TEST_CASE("FORCES.bin read from bytes laid out as docs/formats.md describes", "[calib][forces_bin]") {
    // Two rows, the columns in another order, other decimals, and a column this reader does not
    // know (skipped by its length): t_s (3 decimals), an unknown one, fx_N (1), block, fy_N (0),
    // fz_N (2), spindle_angle_deg (0).
    const std::string header = R"({"columns":[{"name":"t_s","decimals":3},{"name":"new_column","decimals":2},)"
                               R"({"name":"fx_N","decimals":1},{"name":"block","decimals":0},)"
                               R"({"name":"fy_N","decimals":0},{"name":"fz_N","decimals":2},)"
                               R"({"name":"spindle_angle_deg","decimals":0}],"chunk_rows":4,"block_names":["N5"]})";
    std::string f = "\x89" "CLF\r\n\x1a\n";
    u32(f, 1);
    u32(f, static_cast<std::uint32_t>(header.size()));
    f += header;
    u32(f, 2);   // a chunk of two rows
    // t_s: 1.5 s, 1.501 s -> 1500, +1: zigzag 3000 = 0xb8 0x17, 2 = 0x02
    u32(f, 3);
    f += "\xb8\x17\x02";
    // new_column: anything, two one-byte varints
    u32(f, 2);
    f += "\x05\x06";
    // fx_N: -12.3 N, -12.1 N -> -123, +2: zigzag 245 = 0xf5 0x01, 4 = 0x04
    u32(f, 3);
    f += "\xf5\x01\x04";
    // block: -1, then 0 (+1): zigzag 1, 2
    u32(f, 2);
    f += "\x01\x02";
    // fy_N: 7 N, 7 N
    u32(f, 2);
    f += std::string("\x0e\x00", 2);
    // fz_N: 0.05 N, -0.05 N -> 5, -10: zigzag 10, 19
    u32(f, 2);
    f += "\x0a\x13";
    // spindle_angle_deg: 0, 2
    u32(f, 2);
    f += std::string("\x00\x04", 2);
    u32(f, 0);
    f += std::string("\x02\0\0\0\0\0\0\0", 8);

    std::istringstream in(f);
    const PredictedTrace t = read_forces_bin(in, "doc.bin");
    REQUIRE(t.samples.size() == 2);
    CHECK(t.block_names == std::vector<std::string>{"N5"});
    CHECK(t.samples[0].t_s == 1.5);
    CHECK(t.samples[1].t_s == 1.501);
    CHECK(t.samples[0].fx_N == -12.3f);
    CHECK(t.samples[1].fx_N == -12.1f);
    CHECK(t.samples[0].block == -1);
    CHECK(t.samples[1].block == 0);
    CHECK(t.samples[1].fy_N == 7.0f);
    CHECK(t.samples[0].fz_N == 0.05f);
    CHECK(t.samples[1].fz_N == -0.05f);
    CHECK(t.samples[1].spindle_angle_deg == 2.0);
    CHECK(t.samples[0].tool == -1);   // a column the file does not have keeps its default
}

TEST_CASE("a damaged FORCES.bin is refused at its byte offset", "[calib][forces_bin][errors]") {
    Scratch scratch;
    const std::string path = scratch.path("small.bin");
    write_forces_file(made_up_run(5), path);
    const std::string good = slurp(path);
    REQUIRE(error_of(good) == "no error");

    SECTION("every truncation, at every byte") {
        std::size_t refused = 0;
        for (std::size_t n = 0; n < good.size(); ++n) {
            const std::string e = error_of(good.substr(0, n));
            refused += e.find("f.bin: byte ") == 0;
            if (e.find("f.bin: byte ") != 0) FAIL_CHECK("cut at " << n << ": " << e);
        }
        CHECK(refused == good.size());
        CHECK_THAT(error_of(good.substr(0, 10)), Catch::Contains("byte 10: the file ends inside the version"));
    }
    SECTION("wrong magic, a newer version, an oversized header") {
        CHECK_THAT(error_of("t_s,spindle_angle_deg\n" + good), Catch::Contains("byte 0: not a FORCES.bin file"));
        std::string v2 = good;
        v2[8] = 2;
        CHECK_THAT(error_of(v2), Catch::Contains("byte 8: FORCES.bin version 2; this cutload reads version 1"));
        std::string big = good;
        big[15] = 0x10;   // header length 2^28
        CHECK_THAT(error_of(big), Catch::Contains("byte 12: a header of 2684") && Catch::Contains("beyond 8388608"));
    }
    SECTION("trailing bytes, a wrong total") {
        CHECK_THAT(error_of(good + "x"), Catch::Contains("byte " + std::to_string(good.size()) + ": bytes after the end"));
        std::string total = good;
        total[good.size() - 8] = 9;
        CHECK_THAT(error_of(total), Catch::Contains("the file says 9 rows where its chunks hold 5"));
    }
    SECTION("a column's length that no row count allows") {
        // The first column's length follows the header and the chunk's row count.
        std::uint32_t header_len = 0;
        for (int i = 0; i < 4; ++i) header_len |= std::uint32_t(static_cast<unsigned char>(good[12 + i])) << (8 * i);
        const std::size_t length_at = 16 + header_len + 4;
        std::string bad = good;
        bad[length_at] = 100;
        CHECK_THAT(error_of(bad), Catch::Contains("byte " + std::to_string(length_at) + ": column t_s: 100 bytes for 5 rows"));
    }
    SECTION("a header that is not what the format says") {
        auto with_header = [](const std::string& h) {
            std::string f = "\x89" "CLF\r\n\x1a\n";
            u32(f, 1);
            u32(f, static_cast<std::uint32_t>(h.size()));
            return f + h;
        };
        CHECK_THAT(error_of(with_header("{\"columns\": [")), Catch::Contains("byte 16: the header is not JSON"));
        CHECK_THAT(error_of(with_header(R"({"columns":[{"name":"t_s","decimals":6}],"chunk_rows":5,"block_names":[]})")),
                   Catch::Contains("no `spindle_angle_deg` column"));
        CHECK_THAT(error_of(with_header(R"({"columns":[{"name":"t_s","decimals":12}]})")),
                   Catch::Contains("decimals\": 0 to 9"));
        CHECK_THAT(error_of(with_header(R"({"columns":[{"name":"block","decimals":1}]})")),
                   Catch::Contains("column `block` holds whole numbers: its decimals must be 0"));
        // 8 MiB of `[` would be millions of nested values: refused while parsing.
        CHECK_THAT(error_of(with_header(std::string(1 << 20, '['))), Catch::Contains("byte 16: the header nests deeper"));
    }
    SECTION("values no row can hold: a block past int32, a varint of 2^63") {
        // One chunk of two rows over the six columns a reader needs; `block` is the third.
        const std::string header = R"({"columns":[{"name":"t_s","decimals":0},{"name":"spindle_angle_deg","decimals":0},)"
                                   R"({"name":"block","decimals":0},{"name":"fx_N","decimals":0},)"
                                   R"({"name":"fy_N","decimals":0},{"name":"fz_N","decimals":0}],)"
                                   R"("chunk_rows":2,"block_names":[]})";
        auto file = [&](const std::string& block_column) {
            std::string f = "\x89" "CLF\r\n\x1a\n";
            u32(f, 1);
            u32(f, static_cast<std::uint32_t>(header.size()));
            f += header;
            u32(f, 2);
            for (int c = 0; c < 6; ++c) {
                const std::string bytes = c == 2 ? block_column : std::string("\x02\x02", 2);
                u32(f, static_cast<std::uint32_t>(bytes.size()));
                f += bytes;
            }
            u32(f, 0);
            return f + std::string("\x02\0\0\0\0\0\0\0", 8);
        };
        CHECK_THAT(error_of(file(std::string("\x01\x00", 2))), Catch::Contains("no error"));   // -1, -1: valid
        // zigzag(2^31) = 2^32: a block index no row can hold (was a float-to-int overflow).
        CHECK_THAT(error_of(file("\x80\x80\x80\x80\x10\x00")),
                   Catch::Contains("column block: row 0 of the chunk holds 2147483648, outside -1 to 2147483647"));
        // Nine 0xff and a 0x01 decode to -2^63, whose absolute value does not exist.
        CHECK_THAT(error_of(file(std::string(9, '\xff') + "\x01\x00")),
                   Catch::Contains("column block: row 0 of the chunk is beyond 9e+15 steps"));
    }
}

TEST_CASE("a tool-axis component beyond 1.001 is refused by both readers, naming where", "[calib][forces_bin][errors]") {
    Scratch scratch;
    Prediction p = made_up_run(8);
    for (ForceSample& s : p.samples) s.tool_axis_x = 0.6f, s.tool_axis_y = 0, s.tool_axis_z = 0.8f;
    ForcesColumns columns;
    columns.machine_axes = true;
    const std::string bin = scratch.path("axis.bin"), csv = scratch.path("axis.csv");
    // The bound itself passes: 1.001000 is read as float(1.001), which lies a little above 1.001.
    p.samples[2].tool_axis_z = -1.001f;
    write_forces_file(p, bin, columns);
    write_forces_file(p, csv, columns);
    CHECK(read_predicted_forces(bin).samples[2].tool_axis_z == -1.001f);
    CHECK(read_predicted_forces(csv).samples[2].tool_axis_z == -1.001f);

    p.samples[3].tool_axis_x = 1.5f;   // row 4: FORCES.csv's line 5 (after the header)
    write_forces_file(p, bin, columns);
    write_forces_file(p, csv, columns);
    CHECK_THROWS_WITH(read_predicted_forces(bin),
                      Catch::Contains("axis.bin: byte ") && Catch::Contains("row 4: tool_axis_x 1.5 is not a unit vector's component"));
    // tool_axis_x is FORCES.csv's 19th column.
    CHECK_THROWS_WITH(read_predicted_forces(csv), Catch::Contains("axis.csv:5:") &&
                                                      Catch::Contains("column 19 (tool_axis_x): 1.5 is not a unit vector's component"));

    p.samples[3].tool_axis_x = 0.6f;
    p.samples[6].tool_axis_y = -1.001001f;   // one step of the 6th decimal past the bound
    write_forces_file(p, bin, columns);
    write_forces_file(p, csv, columns);
    CHECK_THROWS_WITH(read_predicted_forces(bin), Catch::Contains("row 7: tool_axis_y -1.001001 is not a unit vector's component"));
    CHECK_THROWS_WITH(read_predicted_forces(csv), Catch::Contains("axis.csv:8:") && Catch::Contains("column 20 (tool_axis_y)"));
}

TEST_CASE("the FORCES.bin writer refuses what it cannot carry and leaves nothing behind", "[calib][forces_bin][errors]") {
    Scratch scratch;
    const std::string path = scratch.path("nan.bin");
    {
        Prediction p = made_up_run(3);
        p.samples[1].fy_N = std::numeric_limits<float>::quiet_NaN();
        CHECK_THROWS_WITH(write_forces_file(p, path), Catch::Contains("fy_N = nan") && Catch::Contains("cannot be stored"));
    }
    CHECK(fs::is_empty(scratch.dir));   // neither the file nor its temporary
    {
        const auto w = make_forces_bin_writer(path);
        w->set_block_names({"N1"});
        w->write(made_up_run(3).samples);
        CHECK(w->bytes_written() > 0);
        CHECK_THROWS_AS(w->set_block_names({"N2"}), std::logic_error);
    }   // never committed
    CHECK(fs::is_empty(scratch.dir));   // neither the file nor its temporary
}

TEST_CASE("FORCES.bin files written by scripts/forces_bin_seeds.py from the document read as written",
          "[calib][forces_bin]") {
    const std::string dir = std::string(CUTLOAD_SOURCE_DIR) + "/tests/fuzz/seeds/forces_bin/";
    const PredictedTrace slot = read_predicted_forces(dir + "slot.bin");   // chunks of 3, 3 and 2 rows
    REQUIRE(slot.samples.size() == 8);
    CHECK(slot.block_names == std::vector<std::string>{"N10 G1 X20", "N20 G1 Y5"});
    for (std::size_t i = 0; i < 8; ++i) {
        const ForceSample& s = slot.samples[i];
        INFO("row " << i);
        CHECK(s.t_s == Approx(0.5 + static_cast<double>(i) / 30000).margin(5e-7));
        CHECK(s.spindle_angle_deg == 2.0 * static_cast<double>(i));
        CHECK(s.block == (i < 4 ? 0 : 1));
        CHECK(s.tool == 7);
        CHECK(s.fx_N == (i < 6 ? static_cast<float>(120.5 - 10.0 * static_cast<double>(i)) : 0.0f));
        CHECK(s.removed_mm3 == (i < 6 ? 0.01234f : 0.0f));
        CHECK_FALSE(s.holder_contact);
    }
    const PredictedTrace minimal = read_predicted_forces(dir + "minimal.bin");
    REQUIRE(minimal.samples.size() == 2);
    CHECK(minimal.samples[1].t_s == 0.002);
    CHECK(minimal.samples[1].fy_N == 3.5f);
    CHECK(minimal.samples[0].fz_N == -1.5f);
    CHECK(minimal.samples[1].spindle_angle_deg == 90.0);
    CHECK(minimal.samples[0].block == -1);
}
