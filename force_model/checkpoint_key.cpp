#include "force_model/force_model.hpp"
#include "stock.hpp"

#include <nlohmann/json.hpp>

#include <bit>
#include <cstring>
#include <string>
#include <vector>

namespace cutload::force_model {

namespace {

// Bumped whenever what a checkpoint holds, or how a walk resumes from one, changes.
constexpr std::uint64_t kCheckpointRules = 1;

// FNV-1a over 64-bit words (the byte-wise form costs a multiply a byte: 0.3 s for an hour's motion
// model); a cache key, not a security boundary.
class Hash {
public:
    void words(const void* data, std::size_t bytes) {
        const auto* p = static_cast<const unsigned char*>(data);
        std::size_t k = 0;
        for (; k + 8 <= bytes; k += 8) {
            std::uint64_t w;
            std::memcpy(&w, p + k, 8);
            mix(w);
        }
        std::uint64_t tail = 0;
        std::memcpy(&tail, p + k, bytes - k);
        mix(tail ^ (std::uint64_t(bytes) << 56));
    }
    template <class T>
    void vec(const std::vector<T>& v) {
        mix(v.size());
        words(v.data(), v.size() * sizeof(T));
    }
    void mix(std::uint64_t w) {
        h_ ^= w;
        h_ *= 0x100000001b3ull;
        h_ ^= h_ >> 29;
    }
    std::uint64_t value() const { return h_; }

private:
    std::uint64_t h_ = 0xcbf29ce484222325ull;
};

}  // namespace

std::uint64_t checkpoint_key(const motion_io::MotionModel& m, const RunSpec& spec, const Stock* base) {
    Hash h;
    h.mix(kCheckpointRules);
    h.mix(std::bit_cast<std::uint64_t>(m.step_s));
    for (const auto* v : {&m.t_s, &m.x_mm, &m.y_mm, &m.z_mm, &m.vx_mm_s, &m.vy_mm_s, &m.vz_mm_s, &m.spindle_rpm,
                          &m.spindle_angle_deg})
        h.vec(*v);
    h.vec(m.block);
    h.vec(m.tool);
    h.vec(m.session_start);
    const std::string spec_text = to_json(spec).dump();
    h.words(spec_text.data(), spec_text.size());
    if (base) {
        h.mix(std::uint64_t(base->grid.nx) << 32 | std::uint32_t(base->grid.ny));
        h.mix(std::bit_cast<std::uint64_t>(base->grid.cell_mm));
        h.words(base->codec.base.data(), sizeof base->codec.base);
        h.words(base->stored(), base->storage.bytes());
        h.words(base->stored_walls(), base->walls.bytes());
    }
    return h.value();
}

}  // namespace cutload::force_model
