// FORCES.bin, the compact export of a prediction's rows (docs/formats.md, "FORCES.bin"): written as
// the rows come, read back for comparisons. Every value is an integer count of the CSV's last digit,
// so the file holds exactly what FORCES.csv prints, and rows differ little from the row before, so
// their differences take one or two bytes.
#include "force_model/compare.hpp"
#include "force_model/force_model.hpp"

#include "staged_file.hpp"
#include "textio/text.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>

namespace cutload::force_model {

namespace {

constexpr char kMagic[8] = {'\x89', 'C', 'L', 'F', '\r', '\n', '\x1a', '\n'};
constexpr std::uint32_t kVersion = 1;
constexpr std::uint32_t kMaxHeaderBytes = 8u << 20;
constexpr std::uint32_t kMaxChunkRows = kForcesBinChunkRows;
constexpr std::size_t kMaxColumns = 64;
constexpr std::size_t kMaxVarintBytes = 10;
// The largest count of quanta kept: exactly representable as a double, far beyond any value a
// prediction prints.
constexpr double kMaxQuanta = 9e15;
constexpr std::int64_t kMaxQuantaInt = 9'000'000'000'000'000;
// Columns of whole numbers: their decimals must be 0 and their values in these ranges (block and
// tool are int32 in a row, -1 for none; holder_contact is 0 or 1).
constexpr std::size_t kBlockColumn = 2, kToolColumn = 3, kHolderColumn = 14;
constexpr std::int64_t kMaxInt32 = 2147483647;

// One column: its name in FORCES.csv, its decimals there, and how it reads and sets a row.
struct Column {
    const char* name;
    int decimals;
    double (*get)(const ForceSample&);
    void (*set)(ForceSample&, double);
};

#define CUTLOAD_FLOAT_COLUMN(field, decimals)                                                     \
    Column {                                                                                      \
        #field, decimals, [](const ForceSample& s) { return double(s.field); },                   \
            [](ForceSample& s, double v) { s.field = static_cast<float>(v); }                     \
    }

// The first kBaseColumns are always written; the machine-axis forces and the tool axis only with
// ForcesColumns::machine_axes (a run with a machine definition).
constexpr std::size_t kBaseColumns = 15;
const std::array<Column, 21> kColumns{{
    {"t_s", 6, [](const ForceSample& s) { return s.t_s; }, [](ForceSample& s, double v) { s.t_s = v; }},
    {"spindle_angle_deg", 3, [](const ForceSample& s) { return s.spindle_angle_deg; },
     [](ForceSample& s, double v) { s.spindle_angle_deg = v; }},
    {"block", 0, [](const ForceSample& s) { return double(s.block); },
     [](ForceSample& s, double v) { s.block = static_cast<std::int32_t>(v); }},
    {"tool", 0, [](const ForceSample& s) { return double(s.tool < -1 ? -1 : s.tool); },
     [](ForceSample& s, double v) { s.tool = static_cast<std::int32_t>(v); }},
    CUTLOAD_FLOAT_COLUMN(fx_N, 3),
    CUTLOAD_FLOAT_COLUMN(fy_N, 3),
    CUTLOAD_FLOAT_COLUMN(fz_N, 3),
    CUTLOAD_FLOAT_COLUMN(torque_Nm, 4),
    CUTLOAD_FLOAT_COLUMN(power_kW, 4),
    CUTLOAD_FLOAT_COLUMN(chip_mm, 5),
    CUTLOAD_FLOAT_COLUMN(bending_MPa, 3),
    CUTLOAD_FLOAT_COLUMN(radial_engagement_mm, 3),
    CUTLOAD_FLOAT_COLUMN(axial_engagement_mm, 3),
    CUTLOAD_FLOAT_COLUMN(removed_mm3, 5),
    {"holder_contact", 0, [](const ForceSample& s) { return s.holder_contact ? 1.0 : 0.0; },
     [](ForceSample& s, double v) { s.holder_contact = v != 0; }},
    CUTLOAD_FLOAT_COLUMN(fx_machine_N, 3),
    CUTLOAD_FLOAT_COLUMN(fy_machine_N, 3),
    CUTLOAD_FLOAT_COLUMN(fz_machine_N, 3),
    CUTLOAD_FLOAT_COLUMN(tool_axis_x, 6),
    CUTLOAD_FLOAT_COLUMN(tool_axis_y, 6),
    CUTLOAD_FLOAT_COLUMN(tool_axis_z, 6),
}};
#undef CUTLOAD_FLOAT_COLUMN

constexpr std::array<double, 10> kPow10{1, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9};

void put_u32(std::string& out, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) out += static_cast<char>((v >> (8 * i)) & 0xff);
}
void put_u64(std::string& out, std::uint64_t v) {
    for (int i = 0; i < 8; ++i) out += static_cast<char>((v >> (8 * i)) & 0xff);
}
void put_varint(std::string& out, std::uint64_t v) {
    while (v >= 0x80) {
        out += static_cast<char>((v & 0x7f) | 0x80);
        v >>= 7;
    }
    out += static_cast<char>(v);
}

// The count of quanta FORCES.csv prints for v with `decimals` digits (std::to_chars rounds the
// double's exact value). The product is exact enough to round directly unless it lies near a half
// or is large; those go through the same formatting the CSV uses.
std::optional<std::int64_t> quanta(double v, int decimals) {
    const double x = v * kPow10[std::size_t(decimals)];
    if (!std::isfinite(x) || std::abs(x) > kMaxQuanta) return std::nullopt;
    const double frac = std::abs(x - std::trunc(x));
    if (std::abs(x) < 1e12 && std::abs(frac - 0.5) > 1e-3) return std::llround(x);
    char buf[64];
    const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed, decimals);
    std::string digits;
    for (const char* p = buf; p != r.ptr; ++p)
        if (*p != '.') digits += *p;
    std::int64_t q = 0;
    std::from_chars(digits.data(), digits.data() + digits.size(), q);
    return q;
}

}  // namespace

namespace {

class ForcesBinWriter final : public ForcesWriter {
public:
    ForcesBinWriter(const std::string& path, const ForcesColumns& columns)
        : file_(path), n_columns_(columns.machine_axes ? kColumns.size() : kBaseColumns) {}

    void set_block_names(const std::vector<std::string>& block_names) override {
        if (header_written_) throw std::logic_error("FORCES.bin: block names set after the first rows");
        block_names_.clear();
        // JSON carries UTF-8 only: a name from a non-UTF-8 program is shown as FORCES.csv's messages show it.
        for (const std::string& n : block_names) block_names_.push_back(textio::printable(n));
    }

    void write(std::span<const ForceSample> rows) override {
        if (!header_written_) write_header();
        const auto names = static_cast<std::int64_t>(block_names_.size());
        for (const ForceSample& s : rows) {
            // The whole row is checked before any of it is kept.
            std::array<std::int64_t, kColumns.size()> q{};
            for (std::size_t c = 0; c < n_columns_; ++c) {
                const auto v = quanta(kColumns[c].get(s), kColumns[c].decimals);
                if (!v)
                    throw std::runtime_error(fmt::format("FORCES.bin: {} = {} at t = {} s cannot be stored (not finite, "
                                                         "or beyond {:g} steps of {:g})",
                                                         kColumns[c].name, kColumns[c].get(s), s.t_s, kMaxQuanta,
                                                         1 / kPow10[std::size_t(kColumns[c].decimals)]));
                q[c] = *v;
            }
            if (q[2] < -1 || q[2] >= names) q[2] = -1;   // as FORCES.csv: a block without a name is none
            for (std::size_t c = 0; c < n_columns_; ++c) {
                const std::int64_t d = q[c] - previous_[c];
                put_varint(column_bytes_[c],
                           (static_cast<std::uint64_t>(d) << 1) ^ static_cast<std::uint64_t>(d >> 63));
                previous_[c] = q[c];
            }
            ++total_rows_;
            if (++chunk_rows_ == kForcesBinChunkRows) flush_chunk();
        }
    }

    void commit() override {
        if (!header_written_) write_header();
        flush_chunk();
        out_.clear();
        put_u32(out_, 0);
        put_u64(out_, total_rows_);
        file_.append(out_);
        file_.commit();
    }

    std::uint64_t bytes_written() const override {
        std::uint64_t pending = 0;
        for (const std::string& b : column_bytes_) pending += b.size();
        return file_.bytes() + pending;
    }

private:
    void write_header() {
        nlohmann::json columns = nlohmann::json::array();
        for (std::size_t c = 0; c < n_columns_; ++c)
            columns.push_back({{"name", kColumns[c].name}, {"decimals", kColumns[c].decimals}});
        const std::string header = nlohmann::json{{"format", "cutload FORCES.bin"},
                                                  {"columns", columns},
                                                  {"chunk_rows", kForcesBinChunkRows},
                                                  {"block_names", block_names_}}
                                       .dump();
        if (header.size() > kMaxHeaderBytes)
            throw std::runtime_error(fmt::format("FORCES.bin: the block names take {} bytes, beyond the header's {} "
                                                 "(write FORCES.csv instead)",
                                                 header.size(), kMaxHeaderBytes));
        out_.assign(kMagic, sizeof kMagic);
        put_u32(out_, kVersion);
        put_u32(out_, static_cast<std::uint32_t>(header.size()));
        out_ += header;
        file_.append(out_);
        header_written_ = true;
    }

    void flush_chunk() {
        if (chunk_rows_ == 0) return;
        out_.clear();
        put_u32(out_, chunk_rows_);
        for (std::size_t c = 0; c < n_columns_; ++c) {
            std::string& bytes = column_bytes_[c];
            put_u32(out_, static_cast<std::uint32_t>(bytes.size()));
            out_ += bytes;
            bytes.clear();
        }
        file_.append(out_);
        previous_.fill(0);
        chunk_rows_ = 0;
    }

    StagedFile file_;
    std::size_t n_columns_;   // the first n of kColumns
    std::vector<std::string> block_names_;
    bool header_written_ = false;
    std::array<std::string, kColumns.size()> column_bytes_;
    std::array<std::int64_t, kColumns.size()> previous_{};
    std::uint32_t chunk_rows_ = 0;
    std::uint64_t total_rows_ = 0;
    std::string out_;
};

}  // namespace

std::unique_ptr<ForcesWriter> make_forces_bin_writer(const std::string& path, const ForcesColumns& columns) {
    return std::make_unique<ForcesBinWriter>(path, columns);
}

// ---- Reading ----

namespace {

class BinReader {
public:
    BinReader(std::istream& in, std::string source) : in_(in), source_(std::move(source)) {}

    PredictedTrace read() {
        read_header();
        PredictedTrace t;
        t.block_names = block_names_;
        t.source = source_;
        // As FORCES.csv's reader: the machine-axis triplet only counts whole.
        t.machine_axes = has_column(kBaseColumns) && has_column(kBaseColumns + 1) && has_column(kBaseColumns + 2);
        std::vector<char> bytes;
        while (true) {
            const std::uint64_t chunk_at = offset_;
            const std::uint32_t n = u32("the row count of a chunk");
            if (n == 0) break;
            if (n > chunk_rows_)
                fail(chunk_at, fmt::format("a chunk of {} rows where the header allows {}", n, chunk_rows_));
            const std::size_t first = t.samples.size();
            t.samples.resize(first + n);
            for (std::size_t c = 0; c < columns_.size(); ++c) read_column(c, n, t.samples.data() + first, bytes);
            check_rows(t, first);
        }
        const std::uint64_t total_at = offset_;
        const std::uint64_t total = u64("the total row count");
        if (total != t.samples.size())
            fail(total_at, fmt::format("the file says {} rows where its chunks hold {}", total, t.samples.size()));
        if (in_.peek() != std::char_traits<char>::eof()) fail(offset_, "bytes after the end of the file's rows");
        if (t.samples.size() < 2) fail(offset_, "fewer than two rows of predicted forces");
        return t;
    }

private:
    [[noreturn]] void fail(std::uint64_t at, const std::string& what) const {
        throw MeasurementError(fmt::format("{}: byte {}: {}", source_, at, what));
    }

    void bytes(void* to, std::size_t n, const char* what) {
        in_.read(static_cast<char*>(to), static_cast<std::streamsize>(n));
        const auto got = static_cast<std::uint64_t>(in_.gcount());
        if (got != n) fail(offset_ + got, fmt::format("the file ends inside {}", what));
        offset_ += n;
    }
    std::uint32_t u32(const char* what) {
        unsigned char b[4];
        bytes(b, 4, what);
        return std::uint32_t(b[0]) | std::uint32_t(b[1]) << 8 | std::uint32_t(b[2]) << 16 | std::uint32_t(b[3]) << 24;
    }
    std::uint64_t u64(const char* what) {
        unsigned char b[8];
        bytes(b, 8, what);
        std::uint64_t v = 0;
        for (int i = 7; i >= 0; --i) v = v << 8 | b[i];
        return v;
    }

    void read_header() {
        char magic[sizeof kMagic];
        bytes(magic, sizeof magic, "the magic bytes");
        if (std::memcmp(magic, kMagic, sizeof kMagic) != 0)
            fail(0, "not a FORCES.bin file (its first bytes are not \\x89CLF\\r\\n\\x1a\\n)");
        const std::uint32_t version = u32("the version");
        if (version != kVersion)
            fail(8, fmt::format("FORCES.bin version {}; this cutload reads version {}", version, kVersion));
        const std::uint32_t size = u32("the header length");
        if (size > kMaxHeaderBytes) fail(12, fmt::format("a header of {} bytes, beyond {}", size, kMaxHeaderBytes));
        std::string text(size, '\0');
        bytes(text.data(), size, "the header");
        nlohmann::json h;
        // The header is three levels deep; a deeper one is refused while parsing, before 8 MiB of
        // `[[[[` becomes millions of nested values.
        bool too_deep = false;
        const nlohmann::json::parser_callback_t depth_limit = [&too_deep](int depth, nlohmann::json::parse_event_t,
                                                                          nlohmann::json&) {
            if (depth > 8) too_deep = true;
            return !too_deep;
        };
        try {
            h = nlohmann::json::parse(text, depth_limit);
        } catch (const nlohmann::json::exception&) {
            // The header's own text is not quoted: it may be anything but UTF-8.
            fail(16, too_deep ? "the header nests deeper than 8 levels" : "the header is not JSON");
        }
        if (too_deep) fail(16, "the header nests deeper than 8 levels");
        const auto* columns = h.is_object() && h.contains("columns") ? &h["columns"] : nullptr;
        if (!columns || !columns->is_array() || columns->empty() || columns->size() > kMaxColumns)
            fail(16, fmt::format("the header's `columns` is not a list of 1 to {} columns", kMaxColumns));
        for (const auto& c : *columns) {
            if (!c.is_object() || !c.contains("name") || !c["name"].is_string() || !c.contains("decimals") ||
                !c["decimals"].is_number_integer() || c["decimals"].get<std::int64_t>() < 0 ||
                c["decimals"].get<std::int64_t>() > 9)
                fail(16, "a header column is not {\"name\": text, \"decimals\": 0 to 9}");
            const std::string name = c["name"].get<std::string>();
            std::optional<std::size_t> known;
            for (std::size_t k = 0; k < kColumns.size(); ++k)
                if (name == kColumns[k].name) known = k;
            for (const auto& [seen, _] : columns_)
                if (seen && known && *seen == *known) fail(16, fmt::format("column `{}` appears twice", name));
            const int decimals = static_cast<int>(c["decimals"].get<std::int64_t>());
            if (known && (*known == kBlockColumn || *known == kToolColumn || *known == kHolderColumn) && decimals != 0)
                fail(16, fmt::format("column `{}` holds whole numbers: its decimals must be 0", name));
            columns_.emplace_back(known, decimals);
        }
        for (std::size_t k : {0, 1, 2, 4, 5, 6}) {
            bool found = false;
            for (const auto& [seen, _] : columns_) found = found || (seen && *seen == k);
            if (!found) fail(16, fmt::format("no `{}` column", kColumns[k].name));
        }
        if (!h.contains("chunk_rows") || !h["chunk_rows"].is_number_integer() || h["chunk_rows"].get<std::int64_t>() < 1 ||
            h["chunk_rows"].get<std::int64_t>() > kMaxChunkRows)
            fail(16, fmt::format("the header's `chunk_rows` is not a whole number from 1 to {}", kMaxChunkRows));
        chunk_rows_ = static_cast<std::uint32_t>(h["chunk_rows"].get<std::int64_t>());
        if (!h.contains("block_names") || !h["block_names"].is_array())
            fail(16, "the header has no `block_names` list");
        for (const auto& n : h["block_names"]) {
            if (!n.is_string()) fail(16, "a block name is not text");
            block_names_.push_back(n.get<std::string>());
        }
    }

    void read_column(std::size_t c, std::uint32_t n, ForceSample* rows, std::vector<char>& buf) {
        const auto [known, decimals] = columns_[c];
        const std::uint64_t at = offset_;
        const std::uint32_t size = u32("a column's length");
        if (size < n || size > n * kMaxVarintBytes)
            fail(at, fmt::format("column {}: {} bytes for {} rows (1 to {} a row)", column_name(c), size, n,
                                 kMaxVarintBytes));
        buf.resize(size);
        bytes(buf.data(), size, "a column's values");
        const auto* p = reinterpret_cast<const unsigned char*>(buf.data());
        const auto* end = p + size;
        std::int64_t q = 0;
        for (std::uint32_t i = 0; i < n; ++i) {
            std::uint64_t z = 0;
            for (int shift = 0;; shift += 7) {
                if (p == end) fail(at, fmt::format("column {}: its bytes end inside row {} of the chunk", column_name(c), i));
                if (shift > 63 || (shift == 63 && *p > 1))
                    fail(at, fmt::format("column {}: a value of more than 64 bits in row {} of the chunk", column_name(c), i));
                z |= std::uint64_t(*p & 0x7f) << shift;
                if (!(*p++ & 0x80)) break;
            }
            const auto d = static_cast<std::int64_t>(z >> 1) ^ -static_cast<std::int64_t>(z & 1);
            if (__builtin_add_overflow(q, d, &q) || q > kMaxQuantaInt || q < -kMaxQuantaInt)
                fail(at, fmt::format("column {}: row {} of the chunk is beyond {:g} steps", column_name(c), i, kMaxQuanta));
            if (!known) continue;
            const std::int64_t lo = *known == kHolderColumn ? 0 : -1;
            const std::int64_t hi = *known == kHolderColumn ? 1 : kMaxInt32;
            if ((*known == kBlockColumn || *known == kToolColumn || *known == kHolderColumn) && (q < lo || q > hi))
                fail(at, fmt::format("column {}: row {} of the chunk holds {}, outside {} to {}", column_name(c), i, q, lo, hi));
            kColumns[*known].set(rows[i], static_cast<double>(q) / kPow10[std::size_t(decimals)]);
        }
        if (p != end) fail(at, fmt::format("column {}: {} bytes left after its {} rows", column_name(c), end - p, n));
    }

    bool has_column(std::size_t known) const {
        return std::any_of(columns_.begin(), columns_.end(), [known](const auto& c) { return c.first == known; });
    }

    std::string column_name(std::size_t c) const {
        return columns_[c].first ? kColumns[*columns_[c].first].name : fmt::format("#{}", c + 1);
    }

    // The same bounds as FORCES.csv read back (compare.cpp).
    void check_rows(const PredictedTrace& t, std::size_t first) const {
        for (std::size_t i = first; i < t.samples.size(); ++i) {
            const ForceSample& s = t.samples[i];
            const std::string row = fmt::format("row {}", i + 1);
            if (!(std::abs(s.t_s) <= 1e9)) fail(offset_, fmt::format("{}: time {:g} s is beyond \u00b11e+09 s", row, s.t_s));
            if (i > 0 && s.t_s < t.samples[i - 1].t_s)
                fail(offset_, fmt::format("{}: time {} s goes back from {} s", row, s.t_s, t.samples[i - 1].t_s));
            for (const float f : {s.fx_N, s.fy_N, s.fz_N, s.fx_machine_N, s.fy_machine_N, s.fz_machine_N})
                if (!(std::abs(f) <= 1e6)) fail(offset_, fmt::format("{}: force {:g} N is beyond \u00b11e+06 N", row, f));
            if (s.block < -1 || s.block >= static_cast<std::int64_t>(block_names_.size()))
                fail(offset_, fmt::format("{}: block {} where the header names {} blocks", row, s.block, block_names_.size()));
            // A unit vector's component, with FORCES.csv's bound. The row holds the float of a value printed
            // to 6 decimals; float(1.001) is above 1.001 itself, so the bound is compared as a float too
            // (rounding is monotonic: 1.001000 passes, 1.001001 does not).
            const float axis[3] = {s.tool_axis_x, s.tool_axis_y, s.tool_axis_z};
            for (std::size_t k = 0; k < 3; ++k)
                if (!(std::abs(axis[k]) <= static_cast<float>(1.001)))
                    fail(offset_, fmt::format("{}: {} {} is not a unit vector's component (beyond \u00b11.001)", row,
                                              kColumns[kBaseColumns + 3 + k].name, axis[k]));
        }
    }

    std::istream& in_;
    std::string source_;
    std::uint64_t offset_ = 0;
    std::vector<std::pair<std::optional<std::size_t>, int>> columns_;   // known column, decimals
    std::uint32_t chunk_rows_ = 0;
    std::vector<std::string> block_names_;
};

}  // namespace

PredictedTrace read_forces_bin(std::istream& in, const std::string& source) {
    return BinReader(in, textio::printable(source)).read();
}

}  // namespace cutload::force_model
