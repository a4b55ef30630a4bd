#include "force_model/program_compare.hpp"

#include "textio/csv.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <stdexcept>

namespace cutload::force_model {
namespace {

const BlockSummary* summary_of(const Prediction& p, const std::string& name) {
    const auto it = std::find_if(p.blocks.begin(), p.blocks.end(), [&](const BlockSummary& b) { return b.block == name; });
    return it == p.blocks.end() ? nullptr : &*it;
}

}  // namespace

std::vector<BlockComparison> compare_program(const motion_io::NcProgram& program, const motion_io::MotionModel& actual,
                                             const motion_io::BlockMapping& mapping, const Prediction& commanded_prediction,
                                             const Prediction& actual_prediction, const motion_io::CommandedOptions& commanded) {
    if (mapping.distance_mm.size() != actual.size())
        throw std::invalid_argument("compare_program: the mapping is not of this motion");
    const std::vector<double> durations = motion_io::commanded_durations_s(program, commanded);
    std::vector<BlockComparison> rows;
    std::map<std::string, std::size_t> row_of;
    for (std::size_t i = 0; i < program.blocks.size(); ++i) {
        const motion_io::NcBlock& b = program.blocks[i];
        auto [it, fresh] = row_of.try_emplace(b.name, rows.size());
        if (fresh) {
            BlockComparison r;
            r.block = b.name;
            r.rapid = b.motion == motion_io::NcMotion::Rapid;
            r.programmed_feed_mm_min = r.rapid ? commanded.rapid_mm_min : motion_io::block_moves(b) ? b.feed_mm_min : 0.0;
            rows.push_back(r);
        } else if ((rows[it->second].rapid || rows[it->second].programmed_feed_mm_min == 0) && motion_io::block_moves(b) &&
                   b.motion != motion_io::NcMotion::Rapid) {
            // A canned cycle's pieces share a name: the block is a feed block if any piece feeds.
            // A five-axis block's tip path may start with the tip held while the axes turn: its
            // feed is that of its first piece that moves.
            rows[it->second].rapid = false;
            rows[it->second].programmed_feed_mm_min = b.feed_mm_min;
        }
        rows[it->second].commanded_duration_s += durations[i];
    }
    // Actual samples by their block name.
    std::vector<double> dev_sum(rows.size(), 0.0), feed_sum(rows.size(), 0.0);
    std::vector<std::size_t> dev_n(rows.size(), 0);
    for (std::size_t i = 0; i < actual.size(); ++i) {
        if (actual.block[i] < 0) continue;
        const auto it = row_of.find(actual.block_names[static_cast<std::size_t>(actual.block[i])]);
        if (it == row_of.end()) continue;
        BlockComparison& r = rows[it->second];
        const double feed = 60.0 * std::hypot(actual.vx_mm_s[i], actual.vy_mm_s[i], actual.vz_mm_s[i]);
        r.actual_min_feed_mm_min = r.samples == 0 ? feed : std::min(r.actual_min_feed_mm_min, feed);
        r.actual_max_feed_mm_min = std::max(r.actual_max_feed_mm_min, feed);
        feed_sum[it->second] += feed;
        ++r.samples;
        if (!std::isnan(mapping.distance_mm[i])) {
            r.max_deviation_mm = std::max(r.max_deviation_mm, mapping.distance_mm[i]);
            dev_sum[it->second] += mapping.distance_mm[i];
            ++dev_n[it->second];
        }
    }
    std::vector<BlockComparison> out;
    for (std::size_t k = 0; k < rows.size(); ++k) {
        BlockComparison& r = rows[k];
        if (r.samples == 0 && r.commanded_duration_s <= 0) continue;   // modal-only blocks
        r.actual_duration_s = double(r.samples) * actual.step_s;
        if (r.samples) r.actual_mean_feed_mm_min = feed_sum[k] / double(r.samples);
        if (dev_n[k]) r.mean_deviation_mm = dev_sum[k] / double(dev_n[k]);
        if (r.programmed_feed_mm_min > 0 && r.samples) {
            r.feed_deficit_pct = std::max(0.0, 100.0 * (1.0 - r.actual_min_feed_mm_min / r.programmed_feed_mm_min));
            r.feed_surge_pct = std::max(0.0, 100.0 * (r.actual_max_feed_mm_min / r.programmed_feed_mm_min - 1.0));
        }
        if (const BlockSummary* s = summary_of(commanded_prediction, r.block)) r.commanded_peak_force_N = s->peak_force_N;
        if (const BlockSummary* s = summary_of(actual_prediction, r.block)) r.actual_peak_force_N = s->peak_force_N;
        r.force_difference_N = r.actual_peak_force_N - r.commanded_peak_force_N;
        r.force_difference_pct = r.commanded_peak_force_N > 0 ? 100.0 * r.force_difference_N / r.commanded_peak_force_N : 0.0;
        out.push_back(r);
    }
    return out;
}

const std::vector<std::string>& comparison_columns() {
    static const std::vector<std::string> cols{
        "block", "rapid", "programmed_feed_mm_min", "samples", "max_deviation_mm", "mean_deviation_mm",
        "actual_min_feed_mm_min", "actual_mean_feed_mm_min", "actual_max_feed_mm_min", "feed_deficit_pct",
        "feed_surge_pct", "commanded_duration_s", "actual_duration_s", "commanded_peak_force_N", "actual_peak_force_N",
        "force_difference_N", "force_difference_pct"};
    return cols;
}

void write_comparison_csv(const std::vector<BlockComparison>& rows, const std::string& path) {
    const std::string tmp = path + ".tmp";
    {
        std::ofstream out(tmp, std::ios::trunc);
        if (!out) throw std::runtime_error("cannot write " + tmp);
        for (std::size_t i = 0; i < comparison_columns().size(); ++i) out << (i ? "," : "") << comparison_columns()[i];
        out << '\n';
        for (const BlockComparison& r : rows)
            out << fmt::format("{},{},{:.1f},{},{:.4f},{:.4f},{:.1f},{:.1f},{:.1f},{:.2f},{:.2f},{:.4f},{:.4f},{:.3f},{:.3f},{:.3f},{:.2f}\n",
                               textio::csv_field(r.block), r.rapid ? 1 : 0, r.programmed_feed_mm_min, r.samples, r.max_deviation_mm,
                               r.mean_deviation_mm, r.actual_min_feed_mm_min, r.actual_mean_feed_mm_min,
                               r.actual_max_feed_mm_min, r.feed_deficit_pct, r.feed_surge_pct, r.commanded_duration_s,
                               r.actual_duration_s, r.commanded_peak_force_N, r.actual_peak_force_N, r.force_difference_N,
                               r.force_difference_pct);
        if (!out) throw std::runtime_error("writing " + tmp + " failed");
    }
    std::error_code ec;
    std::filesystem::rename(tmp, path, ec);
    if (ec) throw std::runtime_error("cannot rename " + tmp + " to " + path + ": " + ec.message());
}

BlockCsvExtra comparison_block_columns(const std::vector<BlockComparison>& rows) {
    std::map<std::string, BlockComparison> by_name;
    for (const BlockComparison& r : rows) by_name.emplace(r.block, r);
    BlockCsvExtra extra;
    extra.header = ",commanded_peak_force_N,force_difference_N,force_difference_pct,max_deviation_mm,mean_deviation_mm,"
                   "feed_deficit_pct,feed_surge_pct";
    extra.fields = [by_name = std::move(by_name)](const BlockSummary& b) {
        const auto it = by_name.find(b.block);
        if (it == by_name.end()) return std::string(",,,,,,,");
        const BlockComparison& r = it->second;
        return fmt::format(",{:.3f},{:.3f},{:.2f},{:.4f},{:.4f},{:.2f},{:.2f}", r.commanded_peak_force_N, r.force_difference_N,
                           r.force_difference_pct, r.max_deviation_mm, r.mean_deviation_mm, r.feed_deficit_pct,
                           r.feed_surge_pct);
    };
    return extra;
}

}  // namespace cutload::force_model
