// Reading dynamometer files: DynoWare exports and plain CSV, units, windows, and the errors for bad
// files (each must say where and why).
#include "force_model/measurement.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <sstream>
#include <string>

using namespace cutload::force_model;

namespace {

Measurement read_text(const std::string& text, const MeasurementWindow& w = {}) {
    std::istringstream in(text);
    return read_measurement(in, "test.csv", w);
}

std::string error_of(const std::string& text, const MeasurementWindow& w = {}) {
    try {
        read_text(text, w);
    } catch (const MeasurementError& e) {
        return e.what();
    }
    return "no error";
}

const char* kDynoWare =
    "DynoWare,Version 3.2.2.0\r\n"
    "Measurement:,slot test\r\n"
    "Sampling rate [Hz]:,10000\r\n"
    "\r\n"
    "Time,Fx,Fy,Fz,Mz\r\n"
    "s,N,N,N,N*cm\r\n"
    "0.0000,1.5,-2.0,3.25,0.1\r\n"
    "0.0001,1.6,-2.1,3.5,0.1\r\n"
    "0.0002,1.7,-2.2,3.75,0.1\r\n"
    "0.0003,1.8,-2.3,4.0,0.1\r\n";

}  // namespace

TEST_CASE("a DynoWare export is read with its rate, channels and extra columns", "[calib][measurement]") {
    const Measurement m = read_text(kDynoWare);
    CHECK(m.format == "dynoware");
    CHECK(m.rate_Hz == 10000);
    REQUIRE(m.size() == 4);
    CHECK(m.t0_s == 0);
    CHECK(m.t_s(3) == Approx(0.0003));
    CHECK(m.fx_N[3] == Approx(1.8f));
    CHECK(m.fy_N[1] == Approx(-2.1f));
    CHECK(m.fz_N[2] == Approx(3.75f));
    REQUIRE(m.ignored_channels.size() == 1);
    CHECK(m.ignored_channels[0] == "Mz");
    CHECK_FALSE(m.tool_machine_axes);
}

TEST_CASE("a European export (semicolons, decimal commas) reads as the same record", "[calib][measurement]") {
    std::string european = kDynoWare;
    for (char& c : european) c = c == ',' ? ';' : c == '.' ? ',' : c;   // "Version 3,2,2,0" stays metadata
    const Measurement m = read_text(european), ref = read_text(kDynoWare);
    CHECK(m.rate_Hz == ref.rate_Hz);
    REQUIRE(m.size() == ref.size());
    for (std::size_t i = 0; i < m.size(); ++i) {
        CHECK(m.t_s(i) == Approx(ref.t_s(i)));
        CHECK(m.fx_N[i] == ref.fx_N[i]);
        CHECK(m.fy_N[i] == ref.fy_N[i]);
        CHECK(m.fz_N[i] == ref.fz_N[i]);
    }
    // Tab-separated works the same way; a thousands point is refused at its line and column.
    std::string tabbed = european;
    for (char& c : tabbed) c = c == ';' ? '\t' : c;
    CHECK(read_text(tabbed).size() == ref.size());
    std::string thousands = european;
    thousands.replace(thousands.find("1,7;"), 4, "1.000,7;");
    const std::string e = error_of(thousands);
    CHECK_THAT(e, Catch::Contains("test.csv:9") && Catch::Contains("(Fx)") && Catch::Contains("1.000,7"));
}

TEST_CASE("plain CSV with units in brackets, milliseconds and kilonewtons", "[calib][measurement]") {
    const Measurement m = read_text("t [ms];fz [kN];fx [N];fy [N]\n0;0.001;1;2\n0.5;0.002;3;4\n1.0;0.003;5;6\n");
    CHECK(m.format == "csv");
    CHECK(m.rate_Hz == Approx(2000));
    REQUIRE(m.size() == 3);
    CHECK(m.fz_N[2] == Approx(3.0f));
    CHECK(m.fx_N[1] == Approx(3.0f));
    CHECK(m.t_s(2) == Approx(0.001));
}

TEST_CASE("plain CSV without units is seconds and newtons, suffix units also work", "[calib][measurement]") {
    const Measurement a = read_text("t,fx,fy,fz\n1.0,1,2,3\n1.5,1,2,3\n2.0,1,2,3\n");
    CHECK(a.rate_Hz == Approx(2));
    CHECK(a.t0_s == Approx(1.0));
    const Measurement b = read_text("t_s,fx_N,fy_N,fz_N\n0,1,2,3\n0.01,1,2,3\n");
    CHECK(b.rate_Hz == Approx(100));
}

TEST_CASE("a window keeps only its samples and sets the start time", "[calib][measurement]") {
    MeasurementWindow w;
    w.t_start_s = 0.00015;
    w.t_end_s = 0.00025;
    const Measurement m = read_text(kDynoWare, w);
    REQUIRE(m.size() == 1);
    CHECK(m.t0_s == Approx(0.0002));
    CHECK(m.fz_N[0] == Approx(3.75f));
    CHECK(m.file_t_end_s == Approx(0.0003));
}

TEST_CASE("without a time column the header's sampling rate gives the times", "[calib][measurement]") {
    const Measurement m = read_text("DynoWare,Version 3\nSampling rate [kHz]:,50\nFx,Fy,Fz\nN,N,N\n1,2,3\n4,5,6\n");
    CHECK(m.rate_Hz == 50000);
    REQUIRE(m.size() == 2);
    CHECK(m.t_s(1) == Approx(2e-5));
}

TEST_CASE("bad files name the line, the column and the reason", "[calib][measurement][errors]") {
    SECTION("wrong header: no Fy column") {
        const std::string e = error_of("Time,Fx,Fz\ns,N,N\n0,1,2\n");
        CHECK_THAT(e, Catch::Contains("test.csv:1:") && Catch::Contains("no Fy column") &&
                          Catch::Contains("found: Time, Fx, Fz"));
    }
    SECTION("wrong header: data before any names row") {
        const std::string e = error_of("DynoWare,Version 3\n0.0,1,2,3\n");
        CHECK_THAT(e, Catch::Contains("test.csv:2:") && Catch::Contains("data row before the column names"));
    }
    SECTION("a data row quoted in the message is cut between characters, never inside one") {
        // Found by the dyno_csv fuzz target: 0x99 is a trade-mark sign in Windows-1252 (3 bytes in
        // UTF-8); the quote was cut at 60 bytes, leaving half a character, and the service's JSON
        // error body threw on it.
        const std::string e = error_of("DynoWare,Version 3\n0.0,00," + std::string(60, '\x99') + "\n");
        CHECK_THAT(e, Catch::Contains("data row before the column names") && Catch::Contains("0.0,00,\u2122\u2122"));
        CHECK_NOTHROW(nlohmann::json(e).dump());
        CHECK(e.find("\u2122`") != std::string::npos);   // the quote ends after a whole character
    }
    SECTION("no names row at all") {
        CHECK_THAT(error_of("DynoWare,Version 3\nSampling rate [Hz]:,1000\n"), Catch::Contains("no column names row"));
    }
    SECTION("missing units row in a DynoWare export") {
        const std::string e = error_of("DynoWare,Version 3\nSampling rate [Hz]:,10000\nTime,Fx,Fy,Fz\n0,1,2,3\n");
        CHECK_THAT(e, Catch::Contains("test.csv:4:") && Catch::Contains("missing units row") &&
                          Catch::Contains("line 3"));
    }
    SECTION("missing unit for one column") {
        const std::string e = error_of("DynoWare,Version 3\nTime,Fx,Fy,Fz\ns,N,,N\n0,1,2,3\n0.1,1,2,3\n");
        CHECK_THAT(e, Catch::Contains("test.csv:3:5: column 3 (Fy): missing unit"));
    }
    SECTION("unknown unit") {
        CHECK_THAT(error_of("t,fx [lbf],fy,fz\n0,1,2,3\n"),
                   Catch::Contains("column 2 (fx [lbf]): unknown force unit `lbf`"));
    }
    SECTION("unequal sampling: a missing sample") {
        const std::string e = error_of("t,fx,fy,fz\n0,1,2,3\n0.001,1,2,3\n0.002,1,2,3\n0.004,1,2,3\n");
        CHECK_THAT(e, Catch::Contains("test.csv:5:") && Catch::Contains("unequal sampling") &&
                          Catch::Contains("0.002"));
    }
    SECTION("unequal sampling: time going back") {
        CHECK_THAT(error_of("t,fx,fy,fz\n0,1,2,3\n0.001,1,2,3\n0.0005,1,2,3\n"),
                   Catch::Contains("test.csv:4:") && Catch::Contains("unequal sampling"));
    }
    SECTION("unequal sampling: the header rate contradicts the time column") {
        const std::string e = error_of(
            "DynoWare,Version 3\nSampling rate [Hz]:,1000\nTime,Fx,Fy,Fz\ns,N,N,N\n0,1,2,3\n0.002,1,2,3\n");
        CHECK_THAT(e, Catch::Contains("test.csv:6:") && Catch::Contains("sampling interval is 0.001"));
    }
    SECTION("non-numeric value") {
        const std::string e = error_of("t,fx,fy,fz\n0,1,2,3\n0.001,1,abc,3\n");
        CHECK_THAT(e, Catch::Contains("test.csv:3:9: column 3 (fy): 'abc' is not a number"));
    }
    SECTION("a force past any dynamometer's range (found by the dyno_csv fuzz target: 1e39 overflowed the float channel)") {
        CHECK_THAT(error_of("t,fx,fy,fz\n0,1,2,3\n0.001,1,1e39,3\n"),
                   Catch::Contains("test.csv:3:9: column 3 (fy): force 1e+39 N is beyond \u00b11e+06 N"));
        CHECK_THAT(error_of("t,fx [kN],fy,fz\n0,-2000,2,3\n0.001,1,2,3\n"),
                   Catch::Contains("test.csv:2:3: column 2 (fx [kN]): force -2e+06 N"));
        CHECK_NOTHROW(read_text("t,fx [kN],fy,fz\n0,-999,2,3\n0.001,1,2,3\n"));
    }
    SECTION("times past any record's span, or more samples a second than an instrument gives") {
        CHECK_THAT(error_of("t,fx,fy,fz\n0,1,2,3\n2e9,1,2,3\n"),
                   Catch::Contains("test.csv:3:1: column 1 (t): time 2e+09 s is beyond"));
        CHECK_THAT(error_of("t [us],fx,fy,fz\n0,1,2,3\n1e-5,1,2,3\n2e-5,1,2,3\n"),
                   Catch::Contains("1e+11 samples a second") && Catch::Contains("wrong time unit"));
    }
    SECTION("short row") {
        CHECK_THAT(error_of("t,fx,fy,fz\n0,1,2,3\n0.001,1,2\n"),
                   Catch::Contains("test.csv:3: 3 columns where the names row has 4"));
    }
    SECTION("no data rows") {
        CHECK_THAT(error_of("t,fx,fy,fz\ns,N,N,N\n"), Catch::Contains("no data rows"));
    }
    SECTION("empty window") {
        MeasurementWindow w;
        w.t_start_s = 5;
        w.t_end_s = 6;
        const std::string e = error_of(kDynoWare, w);
        CHECK_THAT(e, Catch::Contains("no samples in the window [5, 6] s") &&
                          Catch::Contains("the file covers [0, 0.0003] s"));
    }
    SECTION("reversed window") {
        MeasurementWindow w;
        w.t_start_s = 2;
        w.t_end_s = 1;
        CHECK_THAT(error_of(kDynoWare, w), Catch::Contains("empty window [2, 1] s"));
    }
    SECTION("missing file") {
        CHECK_THROWS_WITH(read_measurement("/nonexistent/dyno.csv"), Catch::Contains("/nonexistent/dyno.csv") &&
                                                                         Catch::Contains("cannot open"));
    }
}

TEST_CASE("axis matrices parse, reject bad input and map workpiece forces to the tool",
          "[calib][measurement]") {
    const AxisMatrix seed = parse_axis_matrix("0,-1,0, -1,0,0, 0,0,1");
    CHECK(seed == AxisMatrix{0, -1, 0, -1, 0, 0, 0, 0, 1});
    CHECK_THROWS_WITH(parse_axis_matrix("1,0,0,0,1,0,0,0"), Catch::Contains("8 numbers where nine"));
    CHECK_THROWS_WITH(parse_axis_matrix("1,0,0,0,x,0,0,0,1"), Catch::Contains("element 5 (row 2, column 2)"));
    CHECK_THROWS_WITH(parse_axis_matrix("1,0,0,1,0,0,0,0,1"), Catch::Contains("singular"));

    Measurement m = read_text(kDynoWare);
    map_to_tool_machine_axes(m, seed);
    // Row 0: X = -Fy_dyn; row 1: Y = -Fx_dyn; Z = Fz_dyn; then the sign flip to the tool.
    CHECK(m.fx_N[0] == Approx(-2.0f));
    CHECK(m.fy_N[0] == Approx(1.5f));
    CHECK(m.fz_N[0] == Approx(-3.25f));
    CHECK(m.tool_machine_axes);
    CHECK_THROWS_AS(map_to_tool_machine_axes(m, seed), MeasurementError);
}

TEST_CASE("measurement: text as exports write it: Latin-1 headers, quoted names, no-break spaces", "[measurement][text]") {
    // A German export: ';' separated, decimal commas, a Latin-1 degree sign in a channel name and
    // its unit, names in quotes (RFC 4180), and a no-break space (0xA0) after one value.
    const std::string text =
        "\"Time\";\"Fx\";\"Fy\";\"Fz\";\"Temperatur [\xB0" "C]\"\n"
        "s;N;N;N;\xB0" "C\n"
        "0,0000;1,5;-2,0;3,25;21,5\n"
        "0,0001;1,6\xA0;-2,1;3,5;21,5\n"
        "0,0002;1,7;-2,2;3,75;21,5\n";
    const Measurement m = read_text(text);
    REQUIRE(m.size() == 3);
    CHECK(m.fx_N[1] == Approx(1.6f));
    CHECK(m.rate_Hz == Approx(10000));
    REQUIRE(m.ignored_channels.size() == 1);
    CHECK(m.ignored_channels[0] == "Temperatur [°C]");
    // A no-break space inside a value is a digit group: refused at its line and column.
    std::string grouped = text;
    grouped.replace(grouped.find("3,75"), 4, "3\xA0" "750");
    const std::string e = error_of(grouped);
    CHECK_THAT(e, Catch::Contains("test.csv:5:17:") && Catch::Contains("(Fz)") && Catch::Contains("no-break space inside it"));
    // A byte that is not text: refused with its place.
    std::string bad = text;
    bad.replace(bad.find("21,5"), 1, "\x81");
    CHECK_THAT(error_of(bad), Catch::Contains("test.csv:3:22:") && Catch::Contains("0x81"));
}
