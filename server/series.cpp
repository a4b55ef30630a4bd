#include "series.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>

namespace cutload::server {
namespace {

std::size_t elem_bytes(std::size_t level, std::size_t k) {
    return level == 0 ? sizeof(double) + k * sizeof(float) : 2 * sizeof(double) + 2 * k * sizeof(float);
}

}  // namespace

const std::vector<std::string>& series_channels(SeriesId s) {
    static const std::vector<std::string> forces{
        "spindle_angle_deg", "block", "fx_N", "fy_N", "fz_N", "f_N", "torque_Nm", "power_kW",
        "chip_mm", "bending_MPa", "radial_engagement_mm", "axial_engagement_mm"};
    static const std::vector<std::string> motion{"x_mm", "y_mm", "z_mm", "feed_mm_min", "spindle_rpm", "block"};
    static const std::vector<std::string> tool_axis{"tool_axis_x", "tool_axis_y", "tool_axis_z"};
    return s == SeriesId::Motion ? motion : s == SeriesId::ToolAxis ? tool_axis : forces;
}

// Level L holds the chunk being filled and the group of up to kFanout elements that becomes one
// element of level L + 1.
struct SeriesBuilder::Level {
    std::vector<unsigned char> chunk;
    std::size_t chunk_n = 0;
    double chunk_t0 = 0, chunk_t1 = 0;
    std::int64_t next_chunk = 0;
    std::size_t total = 0;   // elements so far
    std::size_t group_n = 0;
    double group_t0 = 0, group_t1 = 0;
    std::vector<float> group_lo, group_hi;
};

SeriesBuilder::SeriesBuilder(SeriesId s, ChunkSink sink, int first_level)
    : series_(s), k_(series_channels(s).size()), first_level_(std::max(first_level, 0)), sink_(std::move(sink)) {}

SeriesBuilder::~SeriesBuilder() = default;

void SeriesBuilder::add(double t_s, const float* values) { add_element(0, t_s, t_s, values, values); }

void SeriesBuilder::add_element(std::size_t level, double t0, double t1, const float* lo, const float* hi) {
    if (levels_.size() <= level) levels_.resize(level + 1);
    Level& l = levels_[level];
    ++l.total;
    if (int(level) >= first_level_) {
        if (l.chunk_n == 0) l.chunk_t0 = t0;
        l.chunk_t1 = t1;
        const std::size_t at = l.chunk.size();
        l.chunk.resize(at + elem_bytes(level, k_));
        unsigned char* p = l.chunk.data() + at;
        std::memcpy(p, &t0, sizeof(double));
        if (level == 0) {
            std::memcpy(p + sizeof(double), lo, k_ * sizeof(float));
        } else {
            std::memcpy(p + sizeof(double), &t1, sizeof(double));
            std::memcpy(p + 2 * sizeof(double), lo, k_ * sizeof(float));
            std::memcpy(p + 2 * sizeof(double) + k_ * sizeof(float), hi, k_ * sizeof(float));
        }
        if (++l.chunk_n == kChunkElems) flush_chunk(level);
    }
    if (l.group_n == 0) {
        l.group_t0 = t0;
        l.group_lo.assign(lo, lo + k_);
        l.group_hi.assign(hi, hi + k_);
    } else {
        for (std::size_t j = 0; j < k_; ++j) {
            l.group_lo[j] = std::min(l.group_lo[j], lo[j]);
            l.group_hi[j] = std::max(l.group_hi[j], hi[j]);
        }
    }
    l.group_t1 = t1;
    if (++l.group_n == kFanout) flush_group(level);
}

void SeriesBuilder::flush_group(std::size_t level) {
    Level& l = levels_[level];
    if (l.group_n == 0) return;
    l.group_n = 0;
    // The group's figures are copied: add_element may grow levels_ (and move this one).
    const double t0 = l.group_t0, t1 = l.group_t1;
    const std::vector<float> lo = l.group_lo, hi = l.group_hi;
    add_element(level + 1, t0, t1, lo.data(), hi.data());
}

void SeriesBuilder::flush_chunk(std::size_t level) {
    Level& l = levels_[level];
    if (l.chunk_n == 0) return;
    sink_(db::SeriesChunkInfo{static_cast<int>(series_), static_cast<int>(level), l.next_chunk++, l.chunk_t0, l.chunk_t1,
                              static_cast<std::int64_t>(l.chunk_n)},
          l.chunk);
    l.chunk.clear();
    l.chunk_n = 0;
}

void SeriesBuilder::finish() {
    if (levels_.empty() || levels_[0].total == 0) return;
    // Up to the first level (1 or above) of at most kFanout elements, as one pass over all the rows
    // would build it; its group is not carried further.
    for (std::size_t level = 0; level < levels_.size(); ++level) {
        const bool top = level >= 1 && levels_[level].total <= kFanout;
        if (!top) flush_group(level);
        flush_chunk(level);
        if (top) break;
    }
}

std::size_t SeriesBuilder::rows() const { return levels_.empty() ? 0 : levels_[0].total; }

ChunkSink store_chunks(db::RunRepository& runs, std::int64_t run_id) {
    return [&runs, run_id](const db::SeriesChunkInfo& info, std::span<const unsigned char> blob) {
        runs.add_series_chunk(run_id, info, blob);
    };
}

void write_series(db::RunRepository& runs, std::int64_t run_id, SeriesId s, const SeriesData& d) {
    const std::size_t k = series_channels(s).size();
    SeriesBuilder b(s, store_chunks(runs, run_id));
    for (std::size_t i = 0; i < d.t_s.size(); ++i) b.add(d.t_s[i], &d.values[i * k]);
    b.finish();
}

std::size_t SeriesCache::KeyHash::operator()(const Key& k) const {
    std::size_t h = std::hash<std::int64_t>()(k.run_id);
    for (std::size_t v : {std::hash<std::string>()(k.version), static_cast<std::size_t>(k.kind),
                          static_cast<std::size_t>(k.series), static_cast<std::size_t>(k.level),
                          std::hash<std::int64_t>()(k.chunk)})
        h ^= v + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2);
    return h;
}

SeriesCache::Stats SeriesCache::stats() const {
    std::lock_guard lk(mu_);
    return Stats{bytes_, limit_bytes_, lru_.size(), hits_, misses_, evictions_};
}

std::shared_ptr<const void> SeriesCache::find(const Key& key) {
    std::lock_guard lk(mu_);
    auto it = where_.find(key);
    if (it == where_.end()) {
        ++misses_;
        return nullptr;
    }
    ++hits_;
    lru_.splice(lru_.begin(), lru_, it->second);
    return it->second->value;
}

void SeriesCache::put(const Key& key, std::shared_ptr<const void> value, std::size_t bytes) {
    if (bytes > limit_bytes_) return;
    std::lock_guard lk(mu_);
    if (where_.count(key)) return;   // a concurrent miss stored it first
    lru_.push_front(Entry{key, std::move(value), bytes});
    where_.emplace(key, lru_.begin());
    bytes_ += bytes;
    while (bytes_ > limit_bytes_) {
        bytes_ -= lru_.back().bytes;
        where_.erase(lru_.back().key);
        lru_.pop_back();
        ++evictions_;
    }
}

void SeriesCache::forget_run(std::int64_t run_id) {
    std::lock_guard lk(mu_);
    for (auto it = lru_.begin(); it != lru_.end();) {
        if (it->key.run_id != run_id) {
            ++it;
            continue;
        }
        bytes_ -= it->bytes;
        where_.erase(it->key);
        it = lru_.erase(it);
    }
}

namespace {

// Where each chunk of each level lies in time, from the covering index (no blob is read).
struct ChunkIndex {
    struct Level {
        std::vector<std::int64_t> chunk, n;
        std::vector<double> t0, t1;
    };
    std::vector<Level> levels;
};

// One chunk decoded into channel-major arrays, so a query touches only the channels it answers.
struct Chunk {
    std::size_t n = 0;
    std::vector<double> t0, t1;   // t1 stays empty at level 0: a raw row is a point in time
    std::vector<float> lo, hi;    // lo[j * n + i]; hi stays empty at level 0 (equal to lo)
};

std::shared_ptr<const ChunkIndex> load_index(db::Session& c, SeriesCache& cache, const RunRef& run, SeriesId s) {
    const SeriesCache::Key key{run.id, run.version, SeriesCache::Kind::Index, static_cast<int>(s), 0, 0};
    return cache.get<ChunkIndex>(key, [&] {
        auto idx = std::make_shared<ChunkIndex>();
        std::size_t bytes = sizeof(ChunkIndex);
        for (const db::SeriesChunkInfo& info : c.runs().series_index(run.id, static_cast<int>(s))) {
            const auto level = static_cast<std::size_t>(info.level);
            if (idx->levels.size() <= level) idx->levels.resize(level + 1);
            auto& l = idx->levels[level];
            l.chunk.push_back(info.chunk);
            l.t0.push_back(info.t0_s);
            l.t1.push_back(info.t1_s);
            l.n.push_back(info.n);
            bytes += 2 * sizeof(std::int64_t) + 2 * sizeof(double);
        }
        return std::pair{std::shared_ptr<const ChunkIndex>(std::move(idx)), bytes};
    });
}

std::shared_ptr<const Chunk> load_chunk(db::Session& c, SeriesCache& cache, const RunRef& run, SeriesId s, int level,
                                        std::int64_t chunk) {
    const SeriesCache::Key key{run.id, run.version, SeriesCache::Kind::Chunk, static_cast<int>(s), level, chunk};
    return cache.get<Chunk>(key, [&] {
        const std::size_t k = series_channels(s).size();
        auto out = std::make_shared<Chunk>();
        auto decode = [&](std::int64_t elements, std::span<const unsigned char> data) {
            const auto n = static_cast<std::size_t>(elements);
            const unsigned char* p = data.data();
            const std::size_t stride = elem_bytes(static_cast<std::size_t>(level), k);
            if (data.size() != n * stride)
                throw std::runtime_error(fmt::format("run {}: series chunk {}/{} holds {} bytes, not {} elements", run.id,
                                                     level, chunk, data.size(), n));
            out->n = n;
            out->t0.resize(n);
            out->lo.resize(n * k);
            if (level > 0) {
                out->t1.resize(n);
                out->hi.resize(n * k);
            }
            const std::size_t lo_at = level == 0 ? sizeof(double) : 2 * sizeof(double);
            for (std::size_t i = 0; i < n; ++i, p += stride) {
                std::memcpy(&out->t0[i], p, sizeof(double));
                if (level > 0) std::memcpy(&out->t1[i], p + sizeof(double), sizeof(double));
                for (std::size_t j = 0; j < k; ++j) {
                    std::memcpy(&out->lo[j * n + i], p + lo_at + j * sizeof(float), sizeof(float));
                    if (level > 0) std::memcpy(&out->hi[j * n + i], p + lo_at + (k + j) * sizeof(float), sizeof(float));
                }
            }
        };
        if (!c.runs().read_series_chunk(run.id, static_cast<int>(s), level, chunk, decode))
            throw std::runtime_error(fmt::format("run {}: series chunk {}/{} is missing", run.id, level, chunk));
        const std::size_t size = sizeof(Chunk) + (out->t0.size() + out->t1.size()) * sizeof(double) +
                                 (out->lo.size() + out->hi.size()) * sizeof(float);
        return std::pair{std::shared_ptr<const Chunk>(std::move(out)), size};
    });
}

// Estimated raw rows in the window: whole chunks inside, pro rata for the two at the edges.
double rows_in(const ChunkIndex::Level& l0, double from_s, double to_s) {
    double rows = 0;
    for (std::size_t i = 0; i < l0.t0.size(); ++i) {
        const double t0 = l0.t0[i], t1 = l0.t1[i];
        if (t1 < from_s || t0 > to_s) continue;
        const double span = t1 - t0;
        const double inside = span > 0 ? (std::min(t1, to_s) - std::max(t0, from_s)) / span : 1.0;
        rows += static_cast<double>(l0.n[i]) * std::clamp(inside, 0.0, 1.0);
    }
    return rows;
}

}  // namespace

namespace {

// The finest level stored: 0 unless the run kept envelopes only (SeriesBuilder's first_level).
std::size_t first_stored(const ChunkIndex& idx) {
    for (std::size_t l = 0; l < idx.levels.size(); ++l)
        if (!idx.levels[l].t0.empty()) return l;
    return idx.levels.size();
}

}  // namespace

bool series_extent(db::Session& c, SeriesCache& cache, const RunRef& run, SeriesId s, double* t0_s, double* t1_s) {
    const auto idx = load_index(c, cache, run, s);
    const std::size_t first = first_stored(*idx);
    if (first >= idx->levels.size()) return false;
    const auto& l0 = idx->levels[first];
    *t0_s = *std::min_element(l0.t0.begin(), l0.t0.end());
    *t1_s = *std::max_element(l0.t1.begin(), l0.t1.end());
    return true;
}

Window query_window(db::Session& c, SeriesCache& cache, const RunRef& run, SeriesId s, double from_s, double to_s,
                    std::size_t max_points, const std::vector<bool>& channels) {
    const std::size_t k = series_channels(s).size();
    Window w;
    w.lo.resize(k);
    w.hi.resize(k);
    const auto idx = load_index(c, cache, run, s);
    const std::size_t first = first_stored(*idx);
    if (first >= idx->levels.size()) return w;

    // Raw rows in the window, estimated from the finest level stored (each of its elements covers
    // kFanout^first rows).
    const double rows = rows_in(idx->levels[first], from_s, to_s) * std::pow(static_cast<double>(kFanout), first);
    int level = static_cast<int>(first);
    if (rows > static_cast<double>(max_points)) {
        // The coarsest level that still gives every output bucket about one element or more.
        while (level + 1 < static_cast<int>(idx->levels.size()) &&
               rows / std::pow(static_cast<double>(kFanout), level + 1) >= static_cast<double>(max_points))
            ++level;
    }
    w.level = level;
    // A run that kept envelopes only answers them, however narrow the window.
    w.decimated = rows > static_cast<double>(max_points) || level > 0;

    // Pass 1, times only: which elements of which chunks fall in the window, and the output
    // element (bucket, or row when raw) each one goes to.
    struct Part {
        std::shared_ptr<const Chunk> chunk;
        std::vector<std::uint32_t> elem, out;
    };
    std::vector<Part> parts;
    const auto& lv = idx->levels[static_cast<std::size_t>(level)];
    const double bucket_s = (to_s - from_s) / static_cast<double>(std::max<std::size_t>(max_points, 1));
    std::int64_t last_bucket = -1;
    for (std::size_t ci = 0; ci < lv.chunk.size(); ++ci) {
        if (lv.t1[ci] < from_s || lv.t0[ci] > to_s) continue;
        Part part{load_chunk(c, cache, run, s, level, lv.chunk[ci]), {}, {}};
        const Chunk& ch = *part.chunk;
        part.elem.reserve(ch.n);
        part.out.reserve(ch.n);
        for (std::size_t i = 0; i < ch.n; ++i) {
            const double t0 = ch.t0[i];
            const double t1 = level == 0 ? t0 : ch.t1[i];
            if (t1 < from_s || t0 > to_s) continue;
            if (!w.decimated) {
                w.t_s.push_back(t0);
            } else {
                const double a = std::max(t0, from_s), b = std::min(t1, to_s);
                auto bucket = static_cast<std::int64_t>((a - from_s) / bucket_s);   // a >= from_s: floor
                bucket = std::clamp<std::int64_t>(bucket, 0, static_cast<std::int64_t>(max_points) - 1);
                if (bucket != last_bucket) {
                    last_bucket = bucket;
                    w.t_s.push_back(a);
                    w.t_end_s.push_back(b);
                } else {
                    w.t_end_s.back() = std::max(w.t_end_s.back(), b);
                }
            }
            part.elem.push_back(static_cast<std::uint32_t>(i));
            part.out.push_back(static_cast<std::uint32_t>(w.t_s.size() - 1));
        }
        if (!part.elem.empty()) parts.push_back(std::move(part));
    }

    // Pass 2, per wanted channel.
    const std::size_t n_out = w.t_s.size();
    for (std::size_t j = 0; j < k; ++j) {
        if (!channels[j]) continue;
        auto& lo = w.lo[j];
        if (!w.decimated) {
            lo.reserve(n_out);
            for (const auto& part : parts) {
                const float* v = &part.chunk->lo[j * part.chunk->n];
                for (auto i : part.elem) lo.push_back(v[i]);
            }
            continue;
        }
        auto& hi = w.hi[j];
        lo.assign(n_out, std::numeric_limits<float>::infinity());
        hi.assign(n_out, -std::numeric_limits<float>::infinity());
        for (const auto& part : parts) {
            const Chunk& ch = *part.chunk;
            const float* src_lo = &ch.lo[j * ch.n];
            const float* src_hi = level == 0 ? src_lo : &ch.hi[j * ch.n];
            for (std::size_t e = 0; e < part.elem.size(); ++e) {
                const auto i = part.elem[e], o = part.out[e];
                lo[o] = std::min(lo[o], src_lo[i]);
                hi[o] = std::max(hi[o], src_hi[i]);
            }
        }
    }
    return w;
}

Window window_from_rows(const SeriesData& d, double from_s, double to_s, std::size_t max_points,
                        const std::vector<bool>& channels) {
    const std::size_t k = channels.size();
    Window w;
    w.lo.resize(k);
    w.hi.resize(k);
    std::vector<std::size_t> rows, out;   // rows in the window, and the output element of each
    for (std::size_t i = 0; i < d.t_s.size(); ++i)
        if (d.t_s[i] >= from_s && d.t_s[i] <= to_s) rows.push_back(i);
    w.decimated = rows.size() > max_points;
    // The buckets query_window makes of level 0 (equal widths of the window, empty ones left out).
    const double bucket_s = (to_s - from_s) / static_cast<double>(std::max<std::size_t>(max_points, 1));
    std::int64_t last_bucket = -1;
    for (const std::size_t i : rows) {
        const double t = d.t_s[i];
        if (!w.decimated) {
            w.t_s.push_back(t);
        } else {
            const auto bucket = std::clamp<std::int64_t>(static_cast<std::int64_t>((t - from_s) / bucket_s), 0,
                                                         static_cast<std::int64_t>(max_points) - 1);
            if (bucket != last_bucket) {
                last_bucket = bucket;
                w.t_s.push_back(t);
                w.t_end_s.push_back(t);
            } else {
                w.t_end_s.back() = t;
            }
        }
        out.push_back(w.t_s.size() - 1);
    }
    for (std::size_t j = 0; j < k; ++j) {
        if (!channels[j]) continue;
        auto& lo = w.lo[j];
        if (!w.decimated) {
            for (const std::size_t i : rows) lo.push_back(d.values[i * k + j]);
            continue;
        }
        auto& hi = w.hi[j];
        lo.assign(w.t_s.size(), std::numeric_limits<float>::infinity());
        hi.assign(w.t_s.size(), -std::numeric_limits<float>::infinity());
        for (std::size_t e = 0; e < rows.size(); ++e) {
            const float v = d.values[rows[e] * k + j];
            lo[out[e]] = std::min(lo[out[e]], v);
            hi[out[e]] = std::max(hi[out[e]], v);
        }
    }
    return w;
}

}  // namespace cutload::server
