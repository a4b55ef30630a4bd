#include "program_cache.hpp"

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sys/stat.h>
#include <unistd.h>

namespace cutload::kernels {

namespace {

constexpr char kEntryMagic[16] = {'C', 'U', 'T', 'L', 'O', 'A', 'D', '-', 'C', 'L', 'B', 'I', 'N', ' ', '1', '\n'};
// Bounds on what an entry may claim, so a damaged length cannot ask for gigabytes.
constexpr std::uint64_t kMaxKeyBytes = 16u << 20;
constexpr std::uint64_t kMaxBinaryBytes = 256u << 20;

std::uint64_t fnv1a(const void* data, std::size_t n, std::uint64_t h = 0xcbf29ce484222325ull) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 0x100000001b3ull;
    return h;
}

void put_u64(std::string& out, std::uint64_t v) {
    for (int i = 0; i < 8; ++i) out += static_cast<char>((v >> (8 * i)) & 0xff);
}

bool get_u64(std::istream& in, std::uint64_t& v) {
    unsigned char b[8];
    if (!in.read(reinterpret_cast<char*>(b), 8)) return false;
    v = 0;
    for (int i = 7; i >= 0; --i) v = v << 8 | b[i];
    return true;
}

// A folder this user owns and no one else may write to (a binary from it is run as native code),
// below folders that only this user or root can change: otherwise another user could rename the
// checked folder away and put their own in its place. A sticky folder such as /tmp is fine as an
// ancestor (no one renames what they do not own there).
bool private_folder(const std::filesystem::path& real_dir) {
    struct stat st {};
    if (::lstat(real_dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) return false;
    if (st.st_uid != ::geteuid() || (st.st_mode & (S_IWGRP | S_IWOTH)) != 0) return false;
    for (std::filesystem::path p = real_dir.parent_path();; p = p.parent_path()) {
        if (::lstat(p.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) return false;
        const bool trusted_owner = st.st_uid == 0 || st.st_uid == ::geteuid();
        const bool others_may_write = (st.st_mode & (S_IWGRP | S_IWOTH)) != 0 && (st.st_mode & S_ISVTX) == 0;
        if (!trusted_owner || others_may_write) return false;
        if (p == p.parent_path()) return true;
    }
}

// Makes the missing folders of `dir` with mode 0700 (mkdir -p, leaving existing ones as they are).
bool make_private_folders(const std::filesystem::path& dir) {
    std::filesystem::path so_far;
    for (const auto& part : dir) {
        so_far /= part;
        struct stat st {};
        if (::stat(so_far.c_str(), &st) == 0) continue;   // some mounts refuse mkdir of what exists
        if (errno != ENOENT || (::mkdir(so_far.c_str(), 0700) != 0 && errno != EEXIST)) return false;
    }
    return true;
}

}  // namespace

std::optional<std::string> program_cache_dir() {
    std::string dir;
    if (const char* set = std::getenv("CUTLOAD_OPENCL_CACHE_DIR"); set && *set) {
        if (std::strcmp(set, "off") == 0) return std::nullopt;
        dir = set;
    } else if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg == '/') {
        dir = std::string(xdg) + "/cutload/opencl";
    } else if (const char* home = std::getenv("HOME"); home && *home == '/') {
        dir = std::string(home) + "/.cache/cutload/opencl";
    } else {
        return std::nullopt;
    }
    if (!make_private_folders(dir)) return std::nullopt;
    // Entries are opened by the folder's real path, the one whose ancestors were checked.
    std::error_code ec;
    const std::filesystem::path real = std::filesystem::canonical(dir, ec);
    if (ec || !private_folder(real)) return std::nullopt;
    return real.string();
}

std::string program_cache_file(const std::string& dir, const std::string& key) {
    char name[32];
    std::snprintf(name, sizeof name, "%016llx.clbin", static_cast<unsigned long long>(fnv1a(key.data(), key.size())));
    return dir + "/" + name;
}

std::optional<std::vector<unsigned char>> load_program_binary(const std::string& dir, const std::string& key) {
    const std::string file = program_cache_file(dir, key);
    std::error_code ec;
    const std::uintmax_t file_bytes = std::filesystem::file_size(file, ec);
    // Magic, key, binary and checksum: a size that cannot hold them is not read at all.
    if (ec || file_bytes < sizeof kEntryMagic + 24 + key.size() || file_bytes > sizeof kEntryMagic + 24 + key.size() + kMaxBinaryBytes)
        return std::nullopt;
    std::ifstream in(file, std::ios::binary);
    if (!in) return std::nullopt;
    char magic[sizeof kEntryMagic];
    if (!in.read(magic, sizeof magic) || std::memcmp(magic, kEntryMagic, sizeof magic) != 0) return std::nullopt;
    std::uint64_t key_bytes = 0, binary_bytes = 0, checksum = 0;
    if (!get_u64(in, key_bytes) || key_bytes != key.size() || key_bytes > kMaxKeyBytes) return std::nullopt;
    std::string stored_key(key_bytes, '\0');
    if (!in.read(stored_key.data(), static_cast<std::streamsize>(key_bytes)) || stored_key != key) return std::nullopt;
    if (!get_u64(in, binary_bytes) || binary_bytes == 0 ||
        binary_bytes != file_bytes - sizeof kEntryMagic - 24 - key.size())
        return std::nullopt;
    std::vector<unsigned char> binary(binary_bytes);
    if (!in.read(reinterpret_cast<char*>(binary.data()), static_cast<std::streamsize>(binary_bytes))) return std::nullopt;
    if (!get_u64(in, checksum) || checksum != fnv1a(binary.data(), binary.size(), fnv1a(key.data(), key.size())))
        return std::nullopt;
    if (in.peek() != std::char_traits<char>::eof()) return std::nullopt;
    return binary;
}

bool store_program_binary(const std::string& dir, const std::string& key, const std::vector<unsigned char>& binary) {
    if (binary.empty() || binary.size() > kMaxBinaryBytes || key.size() > kMaxKeyBytes) return false;
    std::string entry(kEntryMagic, sizeof kEntryMagic);
    put_u64(entry, key.size());
    entry += key;
    put_u64(entry, binary.size());
    entry.append(reinterpret_cast<const char*>(binary.data()), binary.size());
    put_u64(entry, fnv1a(binary.data(), binary.size(), fnv1a(key.data(), key.size())));

    std::string tmp = dir + "/entry-XXXXXX";
    const int fd = ::mkstemp(tmp.data());
    if (fd < 0) return false;
    std::size_t done = 0;
    while (done < entry.size()) {
        const ssize_t n = ::write(fd, entry.data() + done, entry.size() - done);
        if (n <= 0) break;
        done += static_cast<std::size_t>(n);
    }
    const bool written = ::close(fd) == 0 && done == entry.size();
    if (!written || std::rename(tmp.c_str(), program_cache_file(dir, key).c_str()) != 0) {
        ::unlink(tmp.c_str());
        return false;
    }
    return true;
}

}  // namespace cutload::kernels
