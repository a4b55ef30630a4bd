// FORCES.csv and BLOCKS.csv (FORCES.bin: forces_bin.cpp), written to a temporary file and renamed, so a reader never sees a
// half-written file.
#include "force_model/force_model.hpp"

#include "staged_file.hpp"
#include "textio/csv.hpp"
#include "textio/number.hpp"

#include <charconv>
#include <cstdio>
#include <cstring>
#include <vector>
#include <filesystem>
#include <fmt/format.h>
#include <sstream>
#include <stdexcept>

namespace cutload::force_model {

namespace {

using textio::csv_field;

// Small files (BLOCKS.csv) are formatted whole, then staged: an error leaves nothing behind.
template <typename Fill>
void write_atomically(const std::string& path, Fill fill) {
    std::ostringstream out;
    fill(out);
    StagedFile file(path);
    file.append(out.view());
    file.commit();
}

}  // namespace

namespace {

class ForcesCsvWriter final : public ForcesWriter {
public:
    ForcesCsvWriter(const std::string& path, const ForcesColumns& columns)
        : file_(path), machine_axes_(columns.machine_axes), buf_(kFlushBytes + kRowBytesMax, '\0') {
        append(machine_axes_ ? "t_s,spindle_angle_deg,block,tool,fx_N,fy_N,fz_N,torque_Nm,power_kW,chip_mm,bending_MPa,"
                               "radial_engagement_mm,axial_engagement_mm,removed_mm3,holder_contact,"
                               "fx_machine_N,fy_machine_N,fz_machine_N,tool_axis_x,tool_axis_y,tool_axis_z\n"
                             : "t_s,spindle_angle_deg,block,tool,fx_N,fy_N,fz_N,torque_Nm,power_kW,chip_mm,bending_MPa,"
                               "radial_engagement_mm,axial_engagement_mm,removed_mm3,holder_contact\n");
    }

    void set_block_names(const std::vector<std::string>& block_names) override {
        names_.clear();
        for (const auto& n : block_names) names_.push_back(csv_field(n));
    }

    void write(std::span<const ForceSample> rows) override {
        // The rows are the bulk of a run's output: each is formatted straight into the buffer,
        // which always has room for the longest row (kRowBytesMax beside its block name).
        for (const ForceSample& s : rows) {
            const std::string_view name =
                s.block >= 0 && std::size_t(s.block) < names_.size() ? std::string_view(names_[std::size_t(s.block)]) : "";
            if (used_ >= kFlushBytes || buf_.size() - used_ < kRowBytesMax + name.size()) {
                flush();
                if (buf_.size() < kRowBytesMax + name.size()) buf_.resize(kFlushBytes + kRowBytesMax + name.size());
            }
            char* p = buf_.data() + used_;
            char* const end = buf_.data() + buf_.size();
            auto num = [&](double v, int digits) {
                p = textio::format_fixed(p, end, v, digits).ptr;
                *p++ = ',';
            };
            num(s.t_s, 6);
            num(s.spindle_angle_deg, 3);
            std::memcpy(p, name.data(), name.size());
            p += name.size();
            *p++ = ',';
            if (s.tool >= 0) p = std::to_chars(p, end, s.tool).ptr;
            *p++ = ',';
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
            *p++ = s.holder_contact ? '1' : '0';
            if (machine_axes_) {
                *p++ = ',';
                num(s.fx_machine_N, 3);
                num(s.fy_machine_N, 3);
                num(s.fz_machine_N, 3);
                num(s.tool_axis_x, 6);
                num(s.tool_axis_y, 6);
                num(s.tool_axis_z, 6);
                --p;
            }
            *p++ = '\n';
            used_ = std::size_t(p - buf_.data());
        }
    }

    void commit() override {
        flush();
        file_.commit();
    }
    std::uint64_t bytes_written() const override { return file_.bytes() + used_; }

private:
    static constexpr std::size_t kFlushBytes = 1 << 20;
    // A row's 21 numbers at their longest (std::to_chars of a double near 1e308: 309 digits, sign,
    // point, 6 decimals), the tool number and the separators; the block name comes on top.
    static constexpr std::size_t kRowBytesMax = 21 * 320 + 32;

    void flush() {
        file_.append(std::string_view(buf_.data(), used_));
        used_ = 0;
    }
    void append(std::string_view text) {
        if (buf_.size() - used_ < text.size()) flush();
        std::memcpy(buf_.data() + used_, text.data(), text.size());
        used_ += text.size();
    }

    StagedFile file_;
    bool machine_axes_ = false;
    std::vector<std::string> names_;   // CSV fields of the block names
    std::string buf_;                  // its whole size is usable; used_ bytes of it are filled
    std::size_t used_ = 0;
};

}  // namespace

std::unique_ptr<ForcesWriter> make_forces_csv_writer(const std::string& path, const ForcesColumns& columns) {
    return std::make_unique<ForcesCsvWriter>(path, columns);
}

void write_forces_csv(const Prediction& p, const std::string& path) {
    const auto w = make_forces_csv_writer(path);
    w->set_block_names(p.block_names);
    w->write(p.samples);
    w->commit();
}

std::unique_ptr<ForcesWriter> open_forces_writer(const std::string& path, const ForcesColumns& columns) {
    if (path.size() >= 4 && path.compare(path.size() - 4, 4, ".bin") == 0) return make_forces_bin_writer(path, columns);
    return make_forces_csv_writer(path, columns);
}

void write_forces_file(const Prediction& p, const std::string& path, const ForcesColumns& columns) {
    const auto w = open_forces_writer(path, columns);
    w->set_block_names(p.block_names);
    w->write(p.samples);
    w->commit();
}

void write_blocks_csv(const Prediction& p, const std::string& path, const BlockCsvExtra& extra) {
    write_atomically(path, [&](std::ostringstream& out) {
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
