#include "postgres/connection.hpp"
#include "postgres/libpq.hpp"

#include <poll.h>

#include <fmt/format.h>

#include <bit>
#include <cstring>

namespace cutload::db::postgres {
namespace {

// Type OIDs of pg_type (stable across releases).
constexpr Oid kBool = 16, kBytea = 17, kInt8 = 20, kInt2 = 21, kInt4 = 23, kText = 25, kFloat4 = 700, kFloat8 = 701,
              kVarchar = 1043;

std::uint64_t to_big_endian(std::uint64_t v) {
    if constexpr (std::endian::native == std::endian::little) return __builtin_bswap64(v);
    return v;
}

std::string big_endian_bytes(std::uint64_t v) {
    v = to_big_endian(v);
    std::string out(8, '\0');
    std::memcpy(out.data(), &v, 8);
    return out;
}

template <class U>
U read_big_endian(const char* p) {
    U v;
    std::memcpy(&v, p, sizeof v);
    if constexpr (std::endian::native == std::endian::little) {
        if constexpr (sizeof(U) == 8) v = __builtin_bswap64(v);
        if constexpr (sizeof(U) == 4) v = __builtin_bswap32(v);
        if constexpr (sizeof(U) == 2) v = __builtin_bswap16(v);
    }
    return v;
}

// SQLSTATE classes (PostgreSQL appendix A): 23 integrity constraint violation; 40001
// serialization failure, 40P01 deadlock, 55P03 lock not available.
Error::Kind kind_of(const char* sqlstate) {
    if (!sqlstate) return Error::Kind::Other;
    const std::string_view s(sqlstate);
    if (s.starts_with("23")) return Error::Kind::Constraint;
    if (s == "40001" || s == "40P01" || s == "55P03") return Error::Kind::Busy;
    return Error::Kind::Other;
}

// libpq's messages span lines ("...failed: Connection refused\n\tIs the server running..."):
// one line for logs and the command line.
std::string one_line(std::string_view msg) {
    std::string out;
    bool space = false;
    for (char ch : msg) {
        if (ch == '\n' || ch == '\r' || ch == '\t' || ch == ' ') {
            space = !out.empty();
            continue;
        }
        if (space) out += ' ';
        space = false;
        out += ch;
    }
    return out;
}

}  // namespace

// ---- parameters ------------------------------------------------------------------------------

Params& Params::push(unsigned type, const char* data, std::size_t bytes) {
    if (bytes > static_cast<std::size_t>(INT32_MAX)) throw Error("postgres: a parameter exceeds 2 GiB", Error::Kind::Other);
    types_.push_back(type);
    values_.push_back(data);
    lengths_.push_back(static_cast<int>(bytes));
    formats_.push_back(1);
    return *this;
}

Params& Params::push_owned(unsigned type, std::string bytes) {
    owned_.push_back(std::move(bytes));
    return push(type, owned_.back().data(), owned_.back().size());
}

Params& Params::add(std::int64_t v) { return push_owned(kInt8, big_endian_bytes(static_cast<std::uint64_t>(v))); }
Params& Params::add(double v) { return push_owned(kFloat8, big_endian_bytes(std::bit_cast<std::uint64_t>(v))); }
Params& Params::add(bool v) { return push_owned(kBool, std::string(1, v ? '\1' : '\0')); }
// An empty string must not be sent as a null pointer (that is SQL NULL).
Params& Params::add(std::string_view v) { return push(kText, v.empty() ? "" : v.data(), v.size()); }
Params& Params::add_blob(std::span<const unsigned char> b) {
    return push(kBytea, b.empty() ? "" : reinterpret_cast<const char*>(b.data()), b.size());
}
Params& Params::add_blob(std::string_view b) { return push(kBytea, b.empty() ? "" : b.data(), b.size()); }
Params& Params::add_null(unsigned type) {
    types_.push_back(type);
    values_.push_back(nullptr);
    lengths_.push_back(0);
    formats_.push_back(1);
    return *this;
}

// ---- results ---------------------------------------------------------------------------------

Result::~Result() { libpq().PQclear(r_); }

int Result::rows() const { return libpq().PQntuples(r_); }

std::int64_t Result::affected() const {
    const char* n = libpq().PQcmdTuples(r_);
    return (n && *n) ? std::strtoll(n, nullptr, 10) : 0;
}

bool Result::is_null(int row, int col) const { return libpq().PQgetisnull(r_, row, col) != 0; }

const char* Result::raw(int row, int col, std::size_t& bytes) const {
    bytes = static_cast<std::size_t>(libpq().PQgetlength(r_, row, col));
    return libpq().PQgetvalue(r_, row, col);
}

std::int64_t Result::i64(int row, int col) const {
    if (is_null(row, col)) return 0;
    std::size_t n = 0;
    const char* p = raw(row, col, n);
    switch (libpq().PQftype(r_, col)) {
        case kInt8: return static_cast<std::int64_t>(read_big_endian<std::uint64_t>(p));
        case kInt4: return static_cast<std::int32_t>(read_big_endian<std::uint32_t>(p));
        case kInt2: return static_cast<std::int16_t>(read_big_endian<std::uint16_t>(p));
        case kBool: return *p != 0;
        default: throw Error(fmt::format("postgres: column {} is not an integer (type {})", col, libpq().PQftype(r_, col)), Error::Kind::Other);
    }
}

double Result::real(int row, int col) const {
    if (is_null(row, col)) return 0;
    std::size_t n = 0;
    const char* p = raw(row, col, n);
    switch (libpq().PQftype(r_, col)) {
        case kFloat8: return std::bit_cast<double>(read_big_endian<std::uint64_t>(p));
        case kFloat4: return std::bit_cast<float>(read_big_endian<std::uint32_t>(p));
        case kInt8:
        case kInt4:
        case kInt2: return static_cast<double>(i64(row, col));
        default: throw Error(fmt::format("postgres: column {} is not a number (type {})", col, libpq().PQftype(r_, col)), Error::Kind::Other);
    }
}

bool Result::boolean(int row, int col) const { return i64(row, col) != 0; }

std::string Result::text(int row, int col) const {
    if (is_null(row, col)) return {};
    const Oid t = libpq().PQftype(r_, col);
    if (t != kText && t != kVarchar && t != kBytea)
        throw Error(fmt::format("postgres: column {} is not text (type {})", col, t), Error::Kind::Other);
    std::size_t n = 0;
    const char* p = raw(row, col, n);
    return std::string(p, n);
}

std::optional<std::string> Result::opt_text(int row, int col) const {
    if (is_null(row, col)) return std::nullopt;
    return text(row, col);
}
std::optional<std::int64_t> Result::opt_i64(int row, int col) const {
    if (is_null(row, col)) return std::nullopt;
    return i64(row, col);
}
std::optional<double> Result::opt_real(int row, int col) const {
    if (is_null(row, col)) return std::nullopt;
    return real(row, col);
}

std::span<const unsigned char> Result::blob(int row, int col) const {
    std::size_t n = 0;
    const char* p = raw(row, col, n);
    return {reinterpret_cast<const unsigned char*>(p), n};
}

// ---- connection ------------------------------------------------------------------------------

Connection::Connection(const std::string& url) : url_(url) {
    conn_ = libpq().PQconnectdb(url.c_str());
    if (!conn_ || libpq().PQstatus(conn_) != CONNECTION_OK) {
        const std::string msg = conn_ ? one_line(libpq().PQerrorMessage(conn_)) : "out of memory";
        libpq().PQfinish(conn_);
        conn_ = nullptr;
        throw Error(fmt::format("cannot open database {}: {}", printable_location(url), msg), Error::Kind::Other);
    }
    // Notices ("relation already exists, skipping") are not errors: keep them off stderr.
    libpq().PQsetNoticeProcessor(conn_, [](void*, const char*) {}, nullptr);
    // Stored times are text; numbers are binary: no setting of the session changes what is read.
    exec("SET client_min_messages = warning");
}

Connection::~Connection() { libpq().PQfinish(conn_); }

void Connection::fail(PGresult* r, std::string_view what) {
    const char* state = r ? libpq().PQresultErrorField(r, PG_DIAG_SQLSTATE) : nullptr;
    const std::string msg = one_line(r ? libpq().PQresultErrorMessage(r) : libpq().PQerrorMessage(conn_));
    const Error::Kind kind = kind_of(state);
    libpq().PQclear(r);
    throw Error(fmt::format("postgres: {}: {}", what, msg), kind);
}

bool Connection::in_transaction() const {
    const auto s = libpq().PQtransactionStatus(conn_);
    return s == PQTRANS_INTRANS || s == PQTRANS_INERROR;
}

bool Connection::transaction_failed() const { return libpq().PQtransactionStatus(conn_) == PQTRANS_INERROR; }

// A server restart (or a dropped connection) leaves the connection bad; outside a transaction
// nothing is lost by connecting again, and its prepared statements are gone with the old one.
void Connection::reconnect_if_lost() {
    if (libpq().PQstatus(conn_) == CONNECTION_OK) return;
    libpq().PQreset(conn_);
    prepared_.clear();
    if (libpq().PQstatus(conn_) != CONNECTION_OK)
        throw Error(fmt::format("lost database {}: {}", printable_location(url_), one_line(libpq().PQerrorMessage(conn_))),
                    Error::Kind::Other);
    libpq().PQsetNoticeProcessor(conn_, [](void*, const char*) {}, nullptr);
}

bool Connection::wait_notification(double timeout_s) {
    const auto lost = [&] {
        return Error(fmt::format("lost database {}: {}", printable_location(url_), one_line(libpq().PQerrorMessage(conn_))),
                     Error::Kind::Other);
    };
    const auto drain = [&] {
        bool any = false;
        while (PGnotify* n = libpq().PQnotifies(conn_)) {
            any = true;
            libpq().PQfreemem(n);
        }
        return any;
    };
    if (libpq().PQstatus(conn_) != CONNECTION_OK || !libpq().PQconsumeInput(conn_)) throw lost();
    if (drain()) return true;
    pollfd p{libpq().PQsocket(conn_), POLLIN, 0};
    const int ready = ::poll(&p, 1, static_cast<int>(timeout_s * 1000));
    if (ready <= 0) return false;
    if (!libpq().PQconsumeInput(conn_)) throw lost();
    return drain();
}

void Connection::exec(std::string_view sql) {
    reconnect_if_lost();
    const std::string s(sql);
    PGresult* r = libpq().PQexec(conn_, s.c_str());
    const auto st = libpq().PQresultStatus(r);
    if (st != PGRES_COMMAND_OK && st != PGRES_TUPLES_OK) fail(r, fmt::format("\"{}\"", one_line(sql.substr(0, 80))));
    libpq().PQclear(r);
}

Result Connection::run(std::string_view sql, const Params& p) {
    if (!in_transaction()) reconnect_if_lost();
    std::string key(sql);
    auto it = prepared_.find(key);
    if (it == prepared_.end()) {
        std::string name = fmt::format("cutload_{}", prepared_.size() + 1);
        PGresult* r = libpq().PQprepare(conn_, name.c_str(), key.c_str(), static_cast<int>(p.size()),
                                reinterpret_cast<const Oid*>(p.types().data()));
        if (libpq().PQresultStatus(r) != PGRES_COMMAND_OK) fail(r, fmt::format("prepare \"{}\"", one_line(sql)));
        libpq().PQclear(r);
        it = prepared_.emplace(std::move(key), std::move(name)).first;
    }
    PGresult* r = libpq().PQexecPrepared(conn_, it->second.c_str(), static_cast<int>(p.size()), p.values(), p.lengths(),
                                 p.formats(), 1);
    const auto st = libpq().PQresultStatus(r);
    if (st != PGRES_COMMAND_OK && st != PGRES_TUPLES_OK) fail(r, fmt::format("\"{}\"", one_line(sql.substr(0, 120))));
    return Result(r);
}

}  // namespace cutload::db::postgres
