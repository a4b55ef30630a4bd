// Measured cutting forces from a dynamometer: Kistler DynoWare CSV exports and plain CSV, read as a
// stream (up to 10^7 rows at 50 kHz) into float channels on a constant sampling grid.
//
// A measurement is kept as recorded (dynamometer axes, force on the workpiece) until
// map_to_tool_machine_axes() turns it into what the engine predicts: force on the tool, machine axes.
#pragma once

#include <array>
#include <cstddef>
#include <istream>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace cutload::force_model {

// A bad measurement file or window: the message names the file, line and column where it applies.
class MeasurementError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// Rows outside [t_start_s, t_end_s] (file time) are checked but not stored.
struct MeasurementWindow {
    double t_start_s = -std::numeric_limits<double>::infinity();
    double t_end_s = std::numeric_limits<double>::infinity();
};

struct Measurement {
    std::string source;          // file name (or the name given for a stream)
    std::string format;          // "dynoware" or "csv"
    double t0_s = 0;             // time of sample 0
    double rate_Hz = 0;          // constant sampling rate
    double file_t_start_s = 0, file_t_end_s = 0;   // span of the whole file, window or not
    std::vector<float> fx_N, fy_N, fz_N;
    std::vector<std::string> ignored_channels;     // e.g. Mz
    // False: dynamometer axes, force on the workpiece (as read). True: after map_to_tool_machine_axes.
    bool tool_machine_axes = false;

    std::size_t size() const { return fx_N.size(); }
    double t_s(std::size_t i) const { return t0_s + static_cast<double>(i) / rate_Hz; }
};

// Layout rules (docs/compare_calibrate.md): metadata lines, then a names row whose first column is the
// time (Time, t, t_s, "t [ms]") with Fx, Fy, Fz somewhere in it, then an optional units row (required
// after DynoWare metadata), then data. Separators: comma, semicolon or tab.
Measurement read_measurement(const std::string& path, const MeasurementWindow& window = {});
Measurement read_measurement(std::istream& in, const std::string& source, const MeasurementWindow& window = {});

// Row-major 3x3 matrix from dynamometer axes to machine axes (seed 001, eq. 4.3 is one example).
using AxisMatrix = std::array<double, 9>;
inline constexpr AxisMatrix kIdentityAxes{1, 0, 0, 0, 1, 0, 0, 0, 1};

// Nine comma-separated numbers, row-major; throws MeasurementError naming the bad element.
AxisMatrix parse_axis_matrix(const std::string& text);

// F_tool_machine = -A F_dyn for a force measured on the workpiece (the dynamometer carries the
// workpiece), +A F_dyn when measured_on_workpiece is false. Throws when already mapped.
void map_to_tool_machine_axes(Measurement& m, const AxisMatrix& dyn_to_machine, bool measured_on_workpiece = true);
// The same conversion for one vector given in the record's own channels (a zero offset read off the
// amplifier, say).
std::array<double, 3> to_tool_machine_axes(const std::array<double, 3>& dyn_N, const AxisMatrix& dyn_to_machine,
                                           bool measured_on_workpiece = true);

// Three comma-separated numbers (Fx, Fy, Fz in the record's channels); throws MeasurementError
// naming the bad element.
std::array<double, 3> parse_force_vector(const std::string& text);

}  // namespace cutload::force_model
