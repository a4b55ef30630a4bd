// FORCES.csv and BLOCKS.csv, written to a temporary file and renamed, so a reader never sees a
// half-written file.
#include "force_model/force_model.hpp"

#include "textio/csv.hpp"

#include <charconv>
#include <cstdio>
#include <vector>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <stdexcept>

namespace cutload::force_model {

namespace {

using textio::csv_field;

template <typename Fill>
void write_atomically(const std::string& path, Fill fill) {
    const std::string tmp = path + ".tmp";
    {
        std::ofstream out(tmp, std::ios::trunc);
        if (!out) throw std::runtime_error("cannot write " + tmp);
        fill(out);
        out.flush();
        if (!out) throw std::runtime_error("writing " + tmp + " failed");
    }
    std::error_code ec;
    std::filesystem::rename(tmp, path, ec);
    if (ec) throw std::runtime_error("cannot rename " + tmp + " to " + path + ": " + ec.message());
}

}  // namespace

void write_forces_csv(const Prediction& p, const std::string& path) {
    write_atomically(path, [&](std::ofstream& out) {
        out << "t_s,spindle_angle_deg,block,tool,fx_N,fy_N,fz_N,torque_Nm,power_kW,chip_mm,bending_MPa,"
               "radial_engagement_mm,axial_engagement_mm,removed_mm3,holder_contact\n";
        // std::to_chars: the rows are the bulk of a run's output, and locale-free fixed formatting
        // through it is several times faster than stream or fmt float formatting.
        std::vector<std::string> names;
        for (const auto& n : p.block_names) names.push_back(csv_field(n));
        std::string buf;
        buf.reserve(1 << 20);
        char tmp[64];
        auto num = [&](double v, int digits) {
            const auto r = std::to_chars(tmp, tmp + sizeof tmp, v, std::chars_format::fixed, digits);
            buf.append(tmp, r.ptr);
            buf += ',';
        };
        for (const ForceSample& s : p.samples) {
            num(s.t_s, 6);
            num(s.spindle_angle_deg, 3);
            if (s.block >= 0 && std::size_t(s.block) < names.size()) buf += names[s.block];
            buf += ',';
            if (s.tool >= 0) {
                const auto r = std::to_chars(tmp, tmp + sizeof tmp, s.tool);
                buf.append(tmp, r.ptr);
            }
            buf += ',';
            num(s.fx_N, 3);
            num(s.fy_N, 3);
            num(s.fz_N, 3);
            num(s.torque_Nm, 4);
            num(s.power_kW, 4);
            num(s.chip_mm, 5);
            num(s.bending_MPa, 3);
            num(s.radial_engagement_mm, 3);
            num(s.axial_engagement_mm, 3);
            num(s.removed_mm3, 5);
            buf += s.holder_contact ? "1\n" : "0\n";
            if (buf.size() > (1 << 20) - 512) {
                out << buf;
                buf.clear();
            }
        }
        out << buf;
    });
}

void write_blocks_csv(const Prediction& p, const std::string& path, const BlockCsvExtra& extra) {
    write_atomically(path, [&](std::ofstream& out) {
        out << "block,tool,t_start_s,t_end_s,peak_force_N,mean_force_N,peak_torque_Nm,peak_power_kW,max_chip_mm,"
               "max_bending_MPa,max_radial_engagement_mm,max_axial_engagement_mm,removed_mm3,flags,flag_details"
            << extra.header << '\n';
        for (const BlockSummary& b : p.blocks) {
            std::string flags, details;
            for (const FlagHit& f : b.flags) {
                flags += (flags.empty() ? "" : ";") + f.flag;
                details += fmt::format("{}{}@{:.4f}s={:.4g}", details.empty() ? "" : ";", f.flag, f.t_s, f.value);
                if (f.tool >= 0) details += fmt::format(" T{}", f.tool);
            }
            out << fmt::format("{},{},{:.6f},{:.6f},{:.3f},{:.3f},{:.4f},{:.4f},{:.5f},{:.3f},{:.3f},{:.3f},{:.3f},{},{}",
                               csv_field(b.block), b.tool >= 0 ? std::to_string(b.tool) : std::string(), b.t_start_s, b.t_end_s, b.peak_force_N, b.mean_force_N,
                               b.peak_torque_Nm, b.peak_power_kW, b.max_chip_mm, b.max_bending_MPa,
                               b.max_radial_engagement_mm, b.max_axial_engagement_mm, b.removed_mm3, flags,
                               csv_field(details))
                << (extra.fields ? extra.fields(b) : std::string()) << '\n';
        }
    });
}

}  // namespace cutload::force_model
