#include "pipeline.hpp"

#include "textio/text.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace cutload::motion_io::detail {

Diagnostics::Diagnostics(const std::string& file) : file_(textio::printable(file)) {}

void Diagnostics::warn(const std::string& code, std::size_t line, const std::string& what) {
    auto [it, inserted] = entries_.try_emplace(code);
    if (inserted) {
        order_.push_back(code);
        it->second.first_line = line;
        it->second.first_what = what;
    }
    ++it->second.count;
}

void Diagnostics::fail(std::size_t line, const std::string& what) const {
    if (line == 0) throw IngestError(fmt::format("{}: {}", file_, what));
    throw IngestError(fmt::format("{}:{}: {}", file_, line, what));
}

void Diagnostics::fail_at(std::size_t line, std::size_t column, const std::string& what) const {
    if (line == 0) fail(0, what);
    if (column == 0) fail(line, what);
    throw IngestError(fmt::format("{}:{}:{}: {}", file_, line, column, what));
}

std::vector<IngestWarning> Diagnostics::warnings() const {
    std::vector<IngestWarning> out;
    for (const auto& code : order_) {
        const Entry& e = entries_.at(code);
        const std::string where = e.first_line ? fmt::format("{}:{}", file_, e.first_line) : file_;
        out.push_back({code, fmt::format("{} ({} time{}, first at {})", e.first_what, e.count, e.count == 1 ? "" : "s", where),
                       e.count});
    }
    return out;
}

std::int32_t BlockTable::intern(std::string_view name) {
    auto [it, inserted] = ids_.try_emplace(std::string(name), static_cast<std::int32_t>(names_.size()));
    if (inserted) names_.emplace_back(name);
    return it->second;
}

void IntervalHistogram::add(double dt_s) {
    if (bins_.empty()) bins_.assign(static_cast<std::size_t>((kLogMax - kLogMin) * kBinsPerDecade) + 1, 0);
    if (n_ == 0) min_ = max_ = dt_s;
    min_ = std::min(min_, dt_s);
    max_ = std::max(max_, dt_s);
    ++n_;
    const double lg = dt_s > 0 ? std::log10(dt_s) : kLogMin;
    const double pos = std::clamp((lg - kLogMin) * kBinsPerDecade, 0.0, static_cast<double>(bins_.size() - 1));
    ++bins_[static_cast<std::size_t>(pos)];
}

IntervalStats IntervalHistogram::stats() const {
    IntervalStats s;
    if (n_ == 0) return s;
    s.min_s = min_;
    s.max_s = max_;
    const std::size_t half = (n_ + 1) / 2;
    std::size_t acc = 0;
    for (std::size_t i = 0; i < bins_.size(); ++i) {
        acc += bins_[i];
        if (acc >= half) {
            // Bin centre, clamped into the exact range so a constant interval reports itself.
            const double centre = std::pow(10.0, kLogMin + (static_cast<double>(i) + 0.5) / kBinsPerDecade);
            s.median_s = std::clamp(centre, min_, max_);
            break;
        }
    }
    return s;
}

}  // namespace cutload::motion_io::detail
