#include "stock.hpp"


#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <new>
#include <streambuf>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace cutload::force_model {

namespace {

constexpr char kMagic[8] = {'C', 'U', 'T', 'L', 'S', 'T', 'K', '\0'};
// Version 2 adds the sub-cell walls (sparse, after the rays); version 3 a second list with each
// ray's lower wall; version 4 the grid's frame after the header (Frame). Version 1 files load
// without walls, version 2 files without lower walls, versions 1 to 3 in stock coordinates.
constexpr std::uint32_t kVersion = 4;

struct Frame {
    double grid_from_stock[9];
    double source_min[3], source_max[3];
};

struct WallEntry {
    std::uint64_t ray;
    float wall[kernels::kWallFloats];   // decoded: clearance, z_from, nx, ny
};
static_assert(sizeof(WallEntry) == sizeof(std::uint64_t) + kernels::kWallFloats * sizeof(float), "written as is: no padding");

// FNV-1a: catches truncation and bit rot; the file is not a security boundary.
std::uint64_t fnv1a(const void* data, std::size_t n, std::uint64_t h = 1469598103934665603ull) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < n; ++i) {
        h ^= p[i];
        h *= 1099511628211ull;
    }
    return h;
}

struct Header {
    char magic[8];
    std::uint32_t version, intervals;
    std::int32_t nx, ny;
    double cell_mm, x0_mm, y0_mm;
    double box_min[3], box_max[3];
};

}  // namespace

bool Stock::untouched(std::size_t r) const {
    const float* s = stored() + r * kernels::kDexelFloats;
    return std::all_of(s, s + kernels::kDexelFloats, [](float v) { return std::bit_cast<std::uint32_t>(v) == 0; });
}

void StockDeleter::operator()(Stock* s) const { delete s; }

std::size_t stock_bytes_per_cell() {
    return (kernels::kDexelFloats + kernels::kWallSlots * kernels::kWallFloats) * sizeof(float);
}

StockPtr make_stock(const StockBox& box, double grid_mm) {
    if (!(grid_mm > 0)) throw std::invalid_argument("make_stock: grid_mm must be > 0");
    for (int k = 0; k < 3; ++k)
        if (!(box.max_mm[k] > box.min_mm[k])) throw std::invalid_argument("make_stock: box max must exceed min");
    StockPtr s(new Stock());
    s->box = box;
    s->source_box = box;
    s->grid.cell_mm = grid_mm;
    s->grid.x0_mm = box.min_mm[0];
    s->grid.y0_mm = box.min_mm[1];
    // Round to whole cells so that a box that is a multiple of the grid is represented exactly.
    if (stock_cells(box, grid_mm) > kMaxStockRays)
        throw std::invalid_argument("make_stock: grid too fine for the box (over 4e8 rays)");
    s->grid.nx = std::max(1, int(std::lround((box.max_mm[0] - box.min_mm[0]) / grid_mm)));
    s->grid.ny = std::max(1, int(std::lround((box.max_mm[1] - box.min_mm[1]) / grid_mm)));
    const std::size_t rays = std::size_t(s->grid.nx) * s->grid.ny;
    s->codec = kernels::RayCodec::for_column(float(box.min_mm[2]), float(box.max_mm[2]));
    s->storage = ZeroPages(rays * kernels::kDexelFloats * sizeof(float));   // all rays: the full box column
    s->walls = ZeroPages(rays * kernels::kWallSlots * kernels::kWallFloats * sizeof(float));   // no walls
    return s;
}

// A rotation: orthonormal rows, determinant +1 (a mirror would turn the cutter's hand).
bool is_rotation(const Rotation3& r) {
    const auto& G = r.m;
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) {
            const double dot = G[3 * a] * G[3 * b] + G[3 * a + 1] * G[3 * b + 1] + G[3 * a + 2] * G[3 * b + 2];
            if (!(std::abs(dot - (a == b ? 1.0 : 0.0)) < 1e-9)) return false;
        }
    const double det = G[0] * (G[4] * G[8] - G[5] * G[7]) - G[1] * (G[3] * G[8] - G[5] * G[6]) +
                       G[2] * (G[3] * G[7] - G[4] * G[6]);
    return det > 0;
}

StockBox turned_stock_box(const StockBox& box, const Rotation3& grid_from_stock, double grid_mm) {
    const auto& G = grid_from_stock.m;
    StockBox grid_box;
    for (int a = 0; a < 3; ++a) grid_box.min_mm[a] = 1e300, grid_box.max_mm[a] = -1e300;
    for (int c = 0; c < 8; ++c) {
        const double p[3] = {(c & 1) ? box.max_mm[0] : box.min_mm[0], (c & 2) ? box.max_mm[1] : box.min_mm[1],
                             (c & 4) ? box.max_mm[2] : box.min_mm[2]};
        for (int a = 0; a < 3; ++a) {
            const double q = G[3 * a] * p[0] + G[3 * a + 1] * p[1] + G[3 * a + 2] * p[2];
            grid_box.min_mm[a] = std::min(grid_box.min_mm[a], q);
            grid_box.max_mm[a] = std::max(grid_box.max_mm[a], q);
        }
    }
    // Whole cells, outward, so every corner lies on the grid.
    if (grid_mm > 0)
        for (int a = 0; a < 2; ++a)
            grid_box.max_mm[a] = grid_box.min_mm[a] +
                                 std::max(1.0, std::ceil((grid_box.max_mm[a] - grid_box.min_mm[a]) / grid_mm - 1e-9)) * grid_mm;
    return grid_box;
}

StockPtr make_turned_stock(const StockBox& box, const Rotation3& grid_from_stock, double grid_mm) {
    if (!(grid_mm > 0)) throw std::invalid_argument("make_turned_stock: grid_mm must be > 0");
    for (int k = 0; k < 3; ++k)
        if (!(box.max_mm[k] > box.min_mm[k])) throw std::invalid_argument("make_turned_stock: box max must exceed min");
    const auto& G = grid_from_stock.m;
    if (!is_rotation(grid_from_stock)) throw std::invalid_argument("make_turned_stock: grid_from_stock is not a rotation");
    const StockBox grid_box = turned_stock_box(box, grid_from_stock, grid_mm);
    if (stock_cells(grid_box, grid_mm) > kMaxStockRays)
        throw std::invalid_argument("make_turned_stock: grid too fine for the turned box (over 4e8 rays)");
    StockPtr s = make_stock(grid_box, grid_mm);
    s->source_box = box;
    s->grid_from_stock = grid_from_stock;
    // Each ray (grid x, y; along grid z) in stock coordinates is o + t d, o = G^T (x, y, 0) and
    // d = G^T e_z; it crosses the box where all three slabs hold.
    const double d[3] = {G[6], G[7], G[8]};
    const kernels::DexelView v = s->view();
    for (int j = 0; j < s->grid.ny; ++j)
        for (int i = 0; i < s->grid.nx; ++i) {
            const double x = s->grid.x0_mm + (i + 0.5) * grid_mm, y = s->grid.y0_mm + (j + 0.5) * grid_mm;
            const double o[3] = {G[0] * x + G[3] * y, G[1] * x + G[4] * y, G[2] * x + G[5] * y};
            double t0 = -1e300, t1 = 1e300;
            for (int a = 0; a < 3 && t0 < t1; ++a) {
                if (std::abs(d[a]) < 1e-15) {
                    if (o[a] < box.min_mm[a] || o[a] > box.max_mm[a]) t1 = t0;
                    continue;
                }
                double lo = (box.min_mm[a] - o[a]) / d[a], hi = (box.max_mm[a] - o[a]) / d[a];
                if (lo > hi) std::swap(lo, hi);
                t0 = std::max(t0, lo), t1 = std::min(t1, hi);
            }
            kernels::Ray ray = kernels::kNoMaterial;
            if (t1 - t0 > kernels::kSliverMm) ray[0] = float(t0), ray[kernels::kDexelIntervals] = float(t1);
            v.store(std::size_t(j) * std::size_t(s->grid.nx) + std::size_t(i), ray);
        }
    return s;
}

Rotation3 stock_grid_frame(const Stock& s) { return s.grid_from_stock; }
StockBox stock_box(const Stock& s) { return s.source_box; }

StockPtr copy_stock(const Stock& s) { return StockPtr(new Stock(s)); }

double stock_volume_mm3(const Stock& s) {
    double len = 0;
    const double full = kernels::ray_length(s.codec.decode(kernels::Ray{}.data()));
    for (std::size_t r = 0; r < s.rays(); ++r) len += s.untouched(r) ? full : kernels::ray_length(s.ray(r));
    return len * s.grid.cell_mm * s.grid.cell_mm;
}

namespace {

// The format, written to any stream; false when the stream failed.
bool write_stock(const Stock& s, std::ostream& out) {
    Header h{};
    std::memcpy(h.magic, kMagic, sizeof kMagic);
    h.version = kVersion;
    h.intervals = kernels::kDexelIntervals;
    h.nx = s.grid.nx;
    h.ny = s.grid.ny;
    h.cell_mm = s.grid.cell_mm;
    h.x0_mm = s.grid.x0_mm;
    h.y0_mm = s.grid.y0_mm;
    for (int k = 0; k < 3; ++k) {
        h.box_min[k] = s.box.min_mm[k];
        h.box_max[k] = s.box.max_mm[k];
    }
    // The format holds plain (decoded) rays, so it does not depend on the in-memory encoding.
    out.write(reinterpret_cast<const char*>(&h), sizeof h);
    std::uint64_t sum = fnv1a(&h, sizeof h);
    Frame f{};
    std::copy(s.grid_from_stock.m.begin(), s.grid_from_stock.m.end(), f.grid_from_stock);
    for (int k = 0; k < 3; ++k) f.source_min[k] = s.source_box.min_mm[k], f.source_max[k] = s.source_box.max_mm[k];
    out.write(reinterpret_cast<const char*>(&f), sizeof f);
    sum = fnv1a(&f, sizeof f, sum);
    for (std::size_t r = 0; r < s.rays(); ++r) {
        const kernels::Ray ray = s.ray(r);
        out.write(reinterpret_cast<const char*>(ray.data()), sizeof ray);
        sum = fnv1a(ray.data(), sizeof ray, sum);
    }
    const kernels::DexelView v = s.view();
    // Each list counted, then written entry by entry: a list gathered first held up to 48 bytes a
    // walled ray while it grew.
    for (int slot = 0; slot < kernels::kWallSlots; ++slot) {
        std::uint64_t n_walls = 0;
        for (std::size_t r = 0; r < s.rays(); ++r) n_walls += v.wall(r, slot).exists() ? 1 : 0;
        out.write(reinterpret_cast<const char*>(&n_walls), sizeof n_walls);
        sum = fnv1a(&n_walls, sizeof n_walls, sum);
        for (std::size_t r = 0; r < s.rays(); ++r) {
            const kernels::Wall w = v.wall(r, slot);
            if (!w.exists()) continue;
            const WallEntry e{r, {w.clearance_mm, w.z_from_mm, w.nx, w.ny}};
            out.write(reinterpret_cast<const char*>(&e), sizeof e);
            sum = fnv1a(&e, sizeof e, sum);
        }
    }
    out.write(reinterpret_cast<const char*>(&sum), sizeof sum);
    return bool(out);
}

// The format, read from any stream; errors start with `source` (a file's path, or what the bytes are).
StockPtr read_stock(std::istream& in, const std::string& source) {
    Header h{};
    in.read(reinterpret_cast<char*>(&h), sizeof h);
    if (!in || std::memcmp(h.magic, kMagic, sizeof kMagic) != 0)
        throw std::runtime_error(source + ": not a cutload stock file (bad magic)");
    if (h.version < 1 || h.version > kVersion)
        throw std::runtime_error(source + ": stock file version " + std::to_string(h.version) + ", this build reads 1 to " +
                                 std::to_string(kVersion));
    if (h.intervals != std::uint32_t(kernels::kDexelIntervals))
        throw std::runtime_error(source + ": stock file has " + std::to_string(h.intervals) +
                                 " intervals per ray, this build uses " + std::to_string(kernels::kDexelIntervals));
    if (h.nx <= 0 || h.ny <= 0 || std::int64_t(h.nx) * h.ny > 400'000'000 || !(h.cell_mm > 0) ||
        !std::isfinite(h.x0_mm) || !std::isfinite(h.y0_mm))
        throw std::runtime_error(source + ": stock file header is corrupt (grid size or cell)");
    StockPtr s(new Stock());
    s->grid = {h.x0_mm, h.y0_mm, h.cell_mm, h.nx, h.ny};
    for (int k = 0; k < 3; ++k) {
        s->box.min_mm[k] = h.box_min[k];
        s->box.max_mm[k] = h.box_max[k];
    }
    s->source_box = s->box;
    std::uint64_t sum = fnv1a(&h, sizeof h);
    if (h.version >= 4) {
        Frame f{};
        in.read(reinterpret_cast<char*>(&f), sizeof f);
        if (!in) throw std::runtime_error(source + ": stock file is truncated (frame)");
        sum = fnv1a(&f, sizeof f, sum);
        std::copy(std::begin(f.grid_from_stock), std::end(f.grid_from_stock), s->grid_from_stock.m.begin());
        for (int k = 0; k < 3; ++k) s->source_box.min_mm[k] = f.source_min[k], s->source_box.max_mm[k] = f.source_max[k];
        if (!is_rotation(s->grid_from_stock))
            throw std::runtime_error(source + ": stock file header is corrupt (its frame is not a rotation)");
    }
    s->codec = kernels::RayCodec::for_column(float(h.box_min[2]), float(h.box_max[2]));
    s->storage = ZeroPages(s->rays() * kernels::kDexelFloats * sizeof(float));
    s->walls = ZeroPages(s->rays() * kernels::kWallSlots * kernels::kWallFloats * sizeof(float));
    const kernels::Ray full = s->codec.decode(kernels::Ray{}.data());
    std::vector<kernels::Ray> row(std::size_t(h.nx));
    for (std::size_t r = 0; r < s->rays() && in; r += row.size()) {
        in.read(reinterpret_cast<char*>(row.data()), std::streamsize(row.size() * sizeof(kernels::Ray)));
        if (!in) break;
        sum = fnv1a(row.data(), row.size() * sizeof(kernels::Ray), sum);
        for (std::size_t k = 0; k < row.size(); ++k)
            if (row[k] != full) s->codec.encode(row[k], s->stored() + (r + k) * kernels::kDexelFloats);
    }
    const int wall_lists = h.version >= 3 ? 2 : h.version == 2 ? 1 : 0;
    for (int slot = 0; slot < wall_lists && in; ++slot) {
        std::uint64_t n_walls = 0;
        in.read(reinterpret_cast<char*>(&n_walls), sizeof n_walls);
        sum = fnv1a(&n_walls, sizeof n_walls, sum);
        if (in && n_walls > s->rays()) throw std::runtime_error(source + ": stock file is corrupt (wall count)");
        const kernels::DexelView v = s->view();
        for (std::uint64_t k = 0; k < n_walls && in; ++k) {
            WallEntry e{};
            in.read(reinterpret_cast<char*>(&e), sizeof e);
            if (!in) break;
            sum = fnv1a(&e, sizeof e, sum);
            if (e.ray >= s->rays()) throw std::runtime_error(source + ": stock file is corrupt (wall ray index)");
            v.store_wall(e.ray, {e.wall[0], e.wall[1], e.wall[2], e.wall[3]}, slot);
        }
    }
    std::uint64_t stored = 0;
    in.read(reinterpret_cast<char*>(&stored), sizeof stored);
    if (!in) throw std::runtime_error(source + ": stock file is truncated");
    if (in.peek() != std::char_traits<char>::eof()) throw std::runtime_error(source + ": stock file has trailing bytes");
    if (sum != stored) throw std::runtime_error(source + ": stock file checksum mismatch (corrupt)");
    return s;
}

// Reads bytes in place: a stock can be hundreds of MB, so no copy into a string stream.
class ViewBuffer : public std::streambuf {
public:
    explicit ViewBuffer(std::string_view bytes) {
        // The get area is only read (no putback into it), so the const_cast never writes.
        char* p = const_cast<char*>(bytes.data());
        setg(p, p, p + bytes.size());
    }
};

// Writes into a buffer of fixed size; a write past its end fails the stream.
class FixedBuffer : public std::streambuf {
public:
    explicit FixedBuffer(std::string& bytes) { setp(bytes.data(), bytes.data() + bytes.size()); }
    bool full() const { return pptr() == epptr(); }
};

}  // namespace

// The header, the frame, every ray, each wall list with its count, the checksum (write_stock).
std::uint64_t stock_file_bytes(const Stock& s) {
    std::size_t walls = 0;
    const kernels::DexelView v = s.view();
    for (int slot = 0; slot < kernels::kWallSlots; ++slot)
        for (std::size_t r = 0; r < s.rays(); ++r) walls += v.wall(r, slot).exists() ? 1 : 0;
    return sizeof(Header) + sizeof(Frame) + s.rays() * sizeof(kernels::Ray) +
           std::size_t(kernels::kWallSlots) * sizeof(std::uint64_t) + walls * sizeof(WallEntry) + sizeof(std::uint64_t);
}

std::string save_stock_bytes(const Stock& s) {
    // Sized once: a growing string stream held up to twice the stock's bytes while it grew, at the
    // end of every service run (docs/force_model.md, "Memory at the end of a run").
    std::string bytes(stock_file_bytes(s), '\0');
    FixedBuffer buffer(bytes);
    std::ostream out(&buffer);
    if (!write_stock(s, out) || !buffer.full()) throw std::runtime_error("writing the stock into memory failed");
    return bytes;
}

StockPtr load_stock_bytes(std::string_view bytes, const std::string& source) {
    ViewBuffer buffer(bytes);
    std::istream in(&buffer);
    return read_stock(in, source);
}

void save_stock(const Stock& s, const std::string& path) {
    const std::string tmp = path + ".tmp";
    {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        if (!out) throw std::runtime_error("cannot write stock file " + tmp);
        if (!write_stock(s, out)) throw std::runtime_error("writing stock file " + tmp + " failed");
    }
    std::filesystem::rename(tmp, path);
}

void save_stock(const Stock& s, std::ostream& out) {
    if (!write_stock(s, out)) throw std::runtime_error("writing the stock failed");
}

StockPtr load_stock(std::istream& in, const std::string& source) { return read_stock(in, source); }

StockPtr load_stock(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error("cannot open stock file " + path);
    return read_stock(in, path);
}

}  // namespace cutload::force_model
