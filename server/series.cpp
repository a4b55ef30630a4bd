#include "server/series.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

namespace cutload::server {
namespace {

// One level of the pyramid in memory, structure of arrays.
struct Level {
    std::vector<double> t0, t1;
    std::vector<float> mins, maxs;   // row-major, K per element
};

std::size_t elem_bytes(std::size_t level, std::size_t k) {
    return level == 0 ? sizeof(double) + k * sizeof(float) : 2 * sizeof(double) + 2 * k * sizeof(float);
}

Level reduce(const std::vector<double>& t0, const std::vector<double>& t1, const std::vector<float>& mins,
             const std::vector<float>& maxs, std::size_t k) {
    Level out;
    const std::size_t n = t0.size();
    for (std::size_t b = 0; b < n; b += kFanout) {
        const std::size_t e = std::min(n, b + kFanout);
        out.t0.push_back(t0[b]);
        out.t1.push_back(t1[e - 1]);
        for (std::size_t j = 0; j < k; ++j) {
            float lo = std::numeric_limits<float>::infinity(), hi = -lo;
            for (std::size_t i = b; i < e; ++i) {
                lo = std::min(lo, mins[i * k + j]);
                hi = std::max(hi, maxs[i * k + j]);
            }
            out.mins.push_back(lo);
            out.maxs.push_back(hi);
        }
    }
    return out;
}

void put_chunk(db::Stmt& ins, std::int64_t run_id, SeriesId s, int level, std::int64_t chunk, double t0, double t1,
               std::size_t n, const std::vector<unsigned char>& blob) {
    ins.reset();
    ins.bind(1, run_id).bind(2, static_cast<int>(s)).bind(3, level).bind(4, chunk);
    ins.bind(5, t0).bind(6, t1).bind(7, static_cast<std::int64_t>(n)).bind_blob(8, blob.data(), blob.size());
    ins.run();
}

}  // namespace

const std::vector<std::string>& series_channels(SeriesId s) {
    static const std::vector<std::string> forces{
        "spindle_angle_deg", "block", "fx_N", "fy_N", "fz_N", "f_N", "torque_Nm", "power_kW",
        "chip_mm", "bending_MPa", "radial_engagement_mm", "axial_engagement_mm"};
    static const std::vector<std::string> motion{"x_mm", "y_mm", "z_mm", "feed_mm_min", "spindle_rpm", "block"};
    return s == SeriesId::Forces ? forces : motion;
}

void write_series(db::Connection& c, std::int64_t run_id, SeriesId s, const SeriesData& d) {
    const std::size_t k = series_channels(s).size();
    const std::size_t n = d.t_s.size();
    auto ins = c.prepare(
        "INSERT INTO series_chunks(run_id, series, level, chunk, t0_s, t1_s, n, data) VALUES (?,?,?,?,?,?,?,?)");
    std::vector<unsigned char> blob;
    for (std::size_t b = 0, chunk = 0; b < n; b += kChunkElems, ++chunk) {
        const std::size_t e = std::min(n, b + kChunkElems);
        blob.resize((e - b) * elem_bytes(0, k));
        unsigned char* p = blob.data();
        for (std::size_t i = b; i < e; ++i) {
            std::memcpy(p, &d.t_s[i], sizeof(double));
            std::memcpy(p + sizeof(double), &d.values[i * k], k * sizeof(float));
            p += elem_bytes(0, k);
        }
        put_chunk(ins, run_id, s, 0, static_cast<std::int64_t>(chunk), d.t_s[b], d.t_s[e - 1], e - b, blob);
    }
    // Envelope levels until one chunk's worth of elements is left.
    Level cur = reduce(d.t_s, d.t_s, d.values, d.values, k);
    for (int level = 1; !cur.t0.empty(); ++level) {
        const std::size_t m = cur.t0.size();
        for (std::size_t b = 0, chunk = 0; b < m; b += kChunkElems, ++chunk) {
            const std::size_t e = std::min(m, b + kChunkElems);
            blob.resize((e - b) * elem_bytes(level, k));
            unsigned char* p = blob.data();
            for (std::size_t i = b; i < e; ++i) {
                std::memcpy(p, &cur.t0[i], sizeof(double));
                std::memcpy(p + sizeof(double), &cur.t1[i], sizeof(double));
                std::memcpy(p + 2 * sizeof(double), &cur.mins[i * k], k * sizeof(float));
                std::memcpy(p + 2 * sizeof(double) + k * sizeof(float), &cur.maxs[i * k], k * sizeof(float));
                p += elem_bytes(level, k);
            }
            put_chunk(ins, run_id, s, level, static_cast<std::int64_t>(chunk), cur.t0[b], cur.t1[e - 1], e - b, blob);
        }
        if (m <= kFanout) break;
        cur = reduce(cur.t0, cur.t1, cur.mins, cur.maxs, k);
    }
}

bool series_extent(db::Connection& c, std::int64_t run_id, SeriesId s, double* t0_s, double* t1_s) {
    auto st = c.prepare(
        "SELECT min(t0_s), max(t1_s) FROM series_chunks WHERE run_id = ? AND series = ? AND level = 0");
    st.bind(1, run_id).bind(2, static_cast<int>(s));
    if (!st.step() || st.is_null(0)) return false;
    *t0_s = st.real(0);
    *t1_s = st.real(1);
    return true;
}

Window query_window(db::Connection& c, std::int64_t run_id, SeriesId s, double from_s, double to_s,
                    std::size_t max_points) {
    const std::size_t k = series_channels(s).size();
    Window w;
    w.channels = k;

    // Estimated raw rows in the window: whole chunks inside, pro rata for the two at the edges.
    auto meta = c.prepare(
        "SELECT t0_s, t1_s, n FROM series_chunks WHERE run_id = ? AND series = ? AND level = ? "
        "AND t1_s >= ? AND t0_s <= ? ORDER BY chunk");
    meta.bind(1, run_id).bind(2, static_cast<int>(s)).bind(3, 0).bind(4, from_s).bind(5, to_s);
    double rows = 0;
    while (meta.step()) {
        const double t0 = meta.real(0), t1 = meta.real(1), n = static_cast<double>(meta.i64(2));
        const double span = t1 - t0;
        const double inside = span > 0 ? (std::min(t1, to_s) - std::max(t0, from_s)) / span : 1.0;
        rows += n * std::clamp(inside, 0.0, 1.0);
    }
    int level = 0;
    if (rows > static_cast<double>(max_points)) {
        // The coarsest level that still gives every output bucket about one element or more.
        while (rows / std::pow(static_cast<double>(kFanout), level + 1) >= static_cast<double>(max_points)) ++level;
    }
    w.level = level;
    w.decimated = rows > static_cast<double>(max_points);

    auto st = c.prepare(
        "SELECT n, data FROM series_chunks WHERE run_id = ? AND series = ? AND level = ? "
        "AND t1_s >= ? AND t0_s <= ? ORDER BY chunk");
    st.bind(1, run_id).bind(2, static_cast<int>(s)).bind(3, level).bind(4, from_s).bind(5, to_s);

    const double bucket_s = (to_s - from_s) / static_cast<double>(std::max<std::size_t>(max_points, 1));
    std::vector<std::int64_t> bucket_of_out;   // decimated: bucket index of each output element
    auto add_to_bucket = [&](double t0, double t1, const float* lo, const float* hi) {
        auto b = static_cast<std::int64_t>(std::floor((t0 - from_s) / bucket_s));
        b = std::clamp<std::int64_t>(b, 0, static_cast<std::int64_t>(max_points) - 1);
        if (bucket_of_out.empty() || bucket_of_out.back() != b) {
            bucket_of_out.push_back(b);
            w.t_s.push_back(t0);
            w.t_end_s.push_back(t1);
            w.mins.insert(w.mins.end(), lo, lo + k);
            w.maxs.insert(w.maxs.end(), hi, hi + k);
            return;
        }
        w.t_end_s.back() = std::max(w.t_end_s.back(), t1);
        float* mn = &w.mins[w.mins.size() - k];
        float* mx = &w.maxs[w.maxs.size() - k];
        for (std::size_t j = 0; j < k; ++j) {
            mn[j] = std::min(mn[j], lo[j]);
            mx[j] = std::max(mx[j], hi[j]);
        }
    };

    std::vector<float> lo(k), hi(k);
    while (st.step()) {
        const auto n = static_cast<std::size_t>(st.i64(0));
        std::size_t bytes = 0;
        const auto* p = static_cast<const unsigned char*>(st.blob(1, &bytes));
        if (bytes != n * elem_bytes(static_cast<std::size_t>(level), k)) continue;   // never written that way
        for (std::size_t i = 0; i < n; ++i, p += elem_bytes(static_cast<std::size_t>(level), k)) {
            double t0 = 0, t1 = 0;
            std::memcpy(&t0, p, sizeof(double));
            if (level == 0) {
                if (t0 < from_s || t0 > to_s) continue;
                std::memcpy(lo.data(), p + sizeof(double), k * sizeof(float));
                if (!w.decimated) {
                    w.t_s.push_back(t0);
                    w.values.insert(w.values.end(), lo.begin(), lo.end());
                } else {
                    add_to_bucket(t0, t0, lo.data(), lo.data());
                }
                continue;
            }
            std::memcpy(&t1, p + sizeof(double), sizeof(double));
            if (t1 < from_s || t0 > to_s) continue;
            std::memcpy(lo.data(), p + 2 * sizeof(double), k * sizeof(float));
            std::memcpy(hi.data(), p + 2 * sizeof(double) + k * sizeof(float), k * sizeof(float));
            add_to_bucket(std::max(t0, from_s), std::min(t1, to_s), lo.data(), hi.data());
        }
    }
    return w;
}

}  // namespace cutload::server
