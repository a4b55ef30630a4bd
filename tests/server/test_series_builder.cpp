// The forces series is built while the engine runs (SeriesBuilder), one chunk and one group per
// level in memory. Its chunks are checked here against the pyramid worked out directly from all
// the rows: level L element i is the minimum and maximum of rows [i 8^L, (i + 1) 8^L), chunks hold
// kChunkElems elements but the last, and the levels end with the first one (1 or above) of at most
// kFanout elements. A builder told to start at level 2 stores exactly those levels from 2 up.
#include "server/results.hpp"
#include "server/series.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>
#include <map>
#include <random>
#include <vector>

using namespace cutload::server;

namespace {

struct Stored {
    std::map<int, std::map<std::int64_t, std::vector<unsigned char>>> blobs;   // level -> chunk -> bytes
    std::map<int, std::map<std::int64_t, cutload::db::SeriesChunkInfo>> info;
};

Stored build(const std::vector<double>& t, const std::vector<float>& v, std::size_t k, int first_level) {
    Stored s;
    SeriesBuilder b(SeriesId::Forces,
                    [&](const cutload::db::SeriesChunkInfo& info, std::span<const unsigned char> blob) {
                        REQUIRE(s.blobs[info.level].count(info.chunk) == 0);
                        s.blobs[info.level][info.chunk].assign(blob.begin(), blob.end());
                        s.info[info.level][info.chunk] = info;
                    },
                    first_level);
    for (std::size_t i = 0; i < t.size(); ++i) b.add(t[i], &v[i * k]);
    b.finish();
    CHECK(b.rows() == t.size());
    return s;
}

}  // namespace

TEST_CASE("series builder: every level's envelopes and chunks as worked out from all the rows") {
    const std::size_t k = series_channels(SeriesId::Forces).size();
    for (const std::size_t n : {std::size_t(1), std::size_t(8), std::size_t(9), std::size_t(4096 * 8 + 5), std::size_t(300001)}) {
        INFO("rows: " << n);
        std::mt19937 rng(20261123 + unsigned(n));
        std::normal_distribution<float> noise(0, 100);
        std::vector<double> t(n);
        std::vector<float> v(n * k);
        for (std::size_t i = 0; i < n; ++i) {
            t[i] = 0.5 + 1e-4 * double(i) + 1e-6 * std::sin(double(i));   // uneven steps
            for (std::size_t j = 0; j < k; ++j) v[i * k + j] = noise(rng);
        }
        const Stored all = build(t, v, k, 0);

        // Levels expected: 0, then 1, 2, ... up to the first of at most kFanout elements.
        std::vector<std::size_t> counts{n};
        do counts.push_back((counts.back() + kFanout - 1) / kFanout);
        while (counts.back() > kFanout);
        REQUIRE(all.blobs.size() == counts.size());
        for (std::size_t level = 0; level < counts.size(); ++level) {
            const std::size_t span = std::size_t(std::pow(double(kFanout), double(level)));
            const std::size_t stride = level == 0 ? sizeof(double) + k * sizeof(float) : 2 * sizeof(double) + 2 * k * sizeof(float);
            const auto& chunks = all.blobs.at(int(level));
            REQUIRE(chunks.size() == (counts[level] + kChunkElems - 1) / kChunkElems);
            std::size_t e = 0, bad = 0;
            for (const auto& [c, blob] : chunks) {
                const auto& info = all.info.at(int(level)).at(c);
                const std::size_t m = std::size_t(info.n);
                CHECK(blob.size() == m * stride);
                CHECK((m == kChunkElems || e + m == counts[level]));
                for (std::size_t i = 0; i < m; ++i, ++e) {
                    const unsigned char* p = blob.data() + i * stride;
                    double t0 = 0, t1 = 0;
                    std::memcpy(&t0, p, sizeof t0);
                    const std::size_t r0 = e * span, r1 = std::min(n, r0 + span);
                    bad += t0 != t[r0];
                    if (i == 0) bad += info.t0_s != t0;
                    if (level > 0) {
                        std::memcpy(&t1, p + sizeof(double), sizeof t1);
                        bad += t1 != t[r1 - 1];
                    }
                    for (std::size_t j = 0; j < k; ++j) {
                        float lo = INFINITY, hi = -INFINITY;
                        for (std::size_t r = r0; r < r1; ++r) {
                            lo = std::min(lo, v[r * k + j]);
                            hi = std::max(hi, v[r * k + j]);
                        }
                        float got_lo = 0, got_hi = 0;
                        const std::size_t at = level == 0 ? sizeof(double) : 2 * sizeof(double);
                        std::memcpy(&got_lo, p + at + j * sizeof(float), sizeof(float));
                        if (level > 0) std::memcpy(&got_hi, p + at + (k + j) * sizeof(float), sizeof(float));
                        else got_hi = got_lo;
                        bad += got_lo != lo || got_hi != hi;
                    }
                }
            }
            CHECK(e == counts[level]);
            CHECK(bad == 0);
        }

        // Envelopes only from level 2: the same chunks from there up, none below.
        const Stored from2 = build(t, v, k, 2);
        for (std::size_t level = 0; level < counts.size(); ++level) {
            if (level < 2) {
                CHECK(from2.blobs.count(int(level)) == 0);
                continue;
            }
            REQUIRE(from2.blobs.count(int(level)) == 1);
            CHECK(from2.blobs.at(int(level)) == all.blobs.at(int(level)));
        }
    }
}

TEST_CASE("series builder: the first stored level keeps a run's expected rows within the raw-row limit") {
    CHECK(force_series_first_level(1e6, 4e6) == 0);
    CHECK(force_series_first_level(4e6, 4e6) == 0);
    CHECK(force_series_first_level(4.1e6, 4e6) == 1);
    CHECK(force_series_first_level(1.08e8, 4e6) == 2);   // an hour at 10000 rpm, 2 deg steps
    CHECK(force_series_first_level(1e12, 0) == 0);       // 0: no limit
}
