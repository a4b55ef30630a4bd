#include "app/checkpoints.hpp"

#include <fmt/format.h>
#include <zlib.h>

#include <array>
#include <bit>
#include <cmath>
#include <cstdio>
#include <istream>
#include <ostream>
#include <random>
#include <stdexcept>
#include <streambuf>

namespace cutload::app {
namespace fs = std::filesystem;

namespace {

constexpr const char* kSuffix = ".stock.gz";
constexpr const char* kTmpSuffix = ".tmp";

// std::streambuf over a gzFile, one direction per instance; errors are the stream's.
class GzBuf : public std::streambuf {
public:
    GzBuf(const fs::path& path, const char* mode) : file_(gzopen(path.c_str(), mode)), writing_(mode[0] == 'w') {
        if (!file_) return;
        gzbuffer(file_, 1 << 18);
        if (writing_) setp(buf_.data(), buf_.data() + buf_.size());
        else setg(buf_.data(), buf_.data(), buf_.data());
    }
    ~GzBuf() override {
        if (file_) gzclose(file_);
    }
    bool is_open() const { return file_ != nullptr; }
    // Flushes and closes; false when anything failed (a full disk shows here).
    bool close() {
        if (!file_) return false;
        const bool flushed = !writing_ || sync() == 0;
        const int rc = gzclose(file_);
        file_ = nullptr;
        return flushed && rc == Z_OK;
    }

protected:
    int_type overflow(int_type c) override {
        if (sync() != 0) return traits_type::eof();
        if (!traits_type::eq_int_type(c, traits_type::eof())) {
            *pptr() = traits_type::to_char_type(c);
            pbump(1);
        }
        return traits_type::not_eof(c);
    }
    int sync() override {
        if (!writing_) return 0;
        const auto n = static_cast<unsigned>(pptr() - pbase());
        if (n > 0 && gzwrite(file_, pbase(), n) != static_cast<int>(n)) return -1;
        setp(buf_.data(), buf_.data() + buf_.size());
        return 0;
    }
    int_type underflow() override {
        const int n = gzread(file_, buf_.data(), static_cast<unsigned>(buf_.size()));
        if (n <= 0) return traits_type::eof();
        setg(buf_.data(), buf_.data(), buf_.data() + n);
        return traits_type::to_int_type(buf_[0]);
    }

private:
    gzFile file_;
    bool writing_;
    std::array<char, 1 << 16> buf_{};
};

std::string file_name(const force_model::StockCheckpoint& at, std::uint64_t key) {
    return fmt::format("at-{}-{:016x}-{:016x}{}", at.sample, std::bit_cast<std::uint64_t>(at.t_s), key, kSuffix);
}

struct Parsed {
    force_model::StockCheckpoint at;
    std::uint64_t key;
};

std::optional<Parsed> parse_name(const std::string& name) {
    unsigned long long sample = 0, bits = 0, key = 0;
    char rest[16] = {};
    if (std::sscanf(name.c_str(), "at-%llu-%16llx-%16llx%15s", &sample, &bits, &key, rest) != 4 ||
        std::string(rest) != kSuffix)
        return std::nullopt;
    const double t_s = std::bit_cast<double>(static_cast<std::uint64_t>(bits));
    const Parsed p{{static_cast<std::size_t>(sample), t_s}, key};
    // Only names this code writes (sscanf would take "0x", "+" or trailing words).
    if (!std::isfinite(t_s) || file_name(p.at, p.key) != name) return std::nullopt;
    return p;
}

}  // namespace

void write_checkpoint(const fs::path& dir, std::uint64_t key, const force_model::StockCheckpoint& at,
                      const force_model::Stock& stock) {
    std::error_code ec;
    fs::create_directory(dir, ec);   // not its parent: a service's run deleted meanwhile stays gone
    if (ec) throw std::runtime_error(fmt::format("cannot make {}: {}", dir.string(), ec.message()));
    const std::string name = file_name(at, key);
    const fs::path tmp = dir / fmt::format(".{}.{:016x}{}", name, std::random_device{}(), kTmpSuffix);
    {
        GzBuf buf(tmp, "wb1");
        if (!buf.is_open()) throw std::runtime_error(fmt::format("cannot write {}", tmp.string()));
        std::ostream out(&buf);
        try {
            force_model::save_stock(stock, out);
        } catch (const std::exception&) {
            fs::remove(tmp, ec);
            throw;
        }
        if (!out.flush() || !buf.close()) {
            fs::remove(tmp, ec);
            throw std::runtime_error(fmt::format("writing {} failed (disk full?)", tmp.string()));
        }
    }
    fs::rename(tmp, dir / name, ec);
    if (ec) {
        fs::remove(tmp, ec);
        throw std::runtime_error(fmt::format("cannot rename {} into place", tmp.string()));
    }
}

std::optional<CheckpointFile> checkpoint_before(const fs::path& dir, std::uint64_t key, double t_s) {
    std::optional<CheckpointFile> best;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir, ec)) {
        const auto p = parse_name(e.path().filename().string());
        if (!p || p->key != key || p->at.t_s > t_s) continue;
        if (!best || p->at.t_s > best->at.t_s) best = CheckpointFile{e.path(), p->at};
    }
    return best;
}

force_model::StockPtr read_checkpoint(const CheckpointFile& file) {
    GzBuf buf(file.path, "rb");
    if (!buf.is_open()) throw std::runtime_error(fmt::format("cannot open {}", file.path.string()));
    std::istream in(&buf);
    return force_model::load_stock(in, file.path.filename().string());
}

void remove_unfinished_checkpoints(const fs::path& dir) {
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir, ec)) {
        const std::string name = e.path().filename().string();
        if (name.starts_with('.') && name.ends_with(kTmpSuffix)) fs::remove(e.path(), ec);
    }
}

void remove_checkpoints(const fs::path& dir) {
    std::error_code ec;
    fs::remove_all(dir, ec);
}

}  // namespace cutload::app
