#include "force_model/force_model.hpp"
#include "stock.hpp"

#include <nlohmann/json.hpp>

#include <bit>
#include <cstring>
#include <string>
#include <vector>

namespace cutload::force_model {

namespace {

// Bumped whenever what a checkpoint holds, or how a walk resumes from one, changes. 2: the motion
// is hashed channel by channel as it streams (CheckpointKey), not vector after vector.
constexpr std::uint64_t kCheckpointRules = 2;
constexpr std::uint64_t kOffset = 0xcbf29ce484222325ull;

// FNV-1a over 64-bit words (the byte-wise form costs a multiply a byte: 0.3 s for an hour's motion
// model); a cache key, not a security boundary.
std::uint64_t mix(std::uint64_t h, std::uint64_t w) {
    h ^= w;
    h *= 0x100000001b3ull;
    return h ^ (h >> 29);
}

std::uint64_t mix_bytes(std::uint64_t h, const void* data, std::size_t bytes) {
    const auto* p = static_cast<const unsigned char*>(data);
    std::size_t k = 0;
    for (; k + 8 <= bytes; k += 8) {
        std::uint64_t w;
        std::memcpy(&w, p + k, 8);
        h = mix(h, w);
    }
    std::uint64_t tail = 0;
    std::memcpy(&tail, p + k, bytes - k);
    return mix(h, tail ^ (std::uint64_t(bytes) << 56));
}

}  // namespace

void CheckpointKey::add(const motion_io::MotionModel& m, std::size_t first_sample) {
    if (!started_) hash_.fill(kOffset), started_ = true;
    const std::size_t n = m.size();
    std::size_t c = 0;
    for (const auto* v : {&m.t_s, &m.x_mm, &m.y_mm, &m.z_mm, &m.vx_mm_s, &m.vy_mm_s, &m.vz_mm_s, &m.spindle_rpm,
                          &m.spindle_angle_deg}) {
        // Doubles are whole words: pieces hash as the whole does.
        for (const double x : *v) hash_[c] = mix(hash_[c], std::bit_cast<std::uint64_t>(x));
        count_[c++] += v->size();
    }
    for (std::size_t i = 0; i < n; ++i) {
        hash_[9] = mix(hash_[9], std::uint64_t(std::uint32_t(i < m.block.size() ? m.block[i] : -1)));
        hash_[10] = mix(hash_[10], std::uint64_t(std::uint32_t(i < m.tool.size() ? m.tool[i] : -1)));
    }
    count_[9] += n, count_[10] += n;
    for (const std::size_t s : m.session_start) hash_[11] = mix(hash_[11], first_sample + s);
    count_[11] += m.session_start.size();
}

std::uint64_t CheckpointKey::key(double step_s, const RunSpec& spec, const Stock* base) const {
    std::uint64_t h = mix(kOffset, kCheckpointRules);
    h = mix(h, std::bit_cast<std::uint64_t>(step_s));
    for (std::size_t c = 0; c < hash_.size(); ++c) h = mix(mix(h, count_[c]), started_ ? hash_[c] : kOffset);
    const std::string spec_text = to_json(spec).dump();
    h = mix_bytes(h, spec_text.data(), spec_text.size());
    if (base) {
        h = mix(h, std::uint64_t(base->grid.nx) << 32 | std::uint32_t(base->grid.ny));
        h = mix(h, std::bit_cast<std::uint64_t>(base->grid.cell_mm));
        h = mix_bytes(h, base->codec.base.data(), sizeof base->codec.base);
        h = mix_bytes(h, base->stored(), base->storage.bytes());
        h = mix_bytes(h, base->stored_walls(), base->walls.bytes());
    }
    return h;
}

std::uint64_t checkpoint_key(const motion_io::MotionModel& m, const RunSpec& spec, const Stock* base) {
    CheckpointKey k;
    k.add(m, 0);
    return k.key(m.step_s, spec, base);
}

}  // namespace cutload::force_model
