#include "gzip.hpp"

#include <zlib.h>

#include <cstdlib>
#include <sstream>
#include <stdexcept>

namespace cutload::server {

bool accepts_gzip(const httplib::Request& req) {
    std::stringstream offer(req.get_header_value("Accept-Encoding"));
    for (std::string item; std::getline(offer, item, ',');) {
        const auto begin = item.find_first_not_of(" \t");
        if (begin == std::string::npos || item.compare(begin, 4, "gzip") != 0) continue;
        const auto q = item.find("q=");
        return q == std::string::npos || std::strtod(item.c_str() + q + 2, nullptr) > 0;
    }
    return false;
}

std::string gzip_fast(std::string_view data) {
    z_stream zs{};
    // 15 + 16: a gzip wrapper around a 32 KiB window.
    if (deflateInit2(&zs, Z_BEST_SPEED, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK)
        throw std::runtime_error("zlib: deflateInit2 failed");
    std::string out(deflateBound(&zs, static_cast<uLong>(data.size())), '\0');
    zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
    zs.avail_in = static_cast<uInt>(data.size());
    zs.next_out = reinterpret_cast<Bytef*>(out.data());
    zs.avail_out = static_cast<uInt>(out.size());
    const int rc = deflate(&zs, Z_FINISH);
    out.resize(zs.total_out);
    deflateEnd(&zs);
    if (rc != Z_STREAM_END) throw std::runtime_error("zlib: deflate did not finish");
    return out;
}

void compress_answer(const httplib::Request& req, httplib::Response& res) {
    const std::string type = res.get_header_value("Content-Type");
    const bool text = type.rfind("text/", 0) == 0 || type.find("json") != std::string::npos ||
                      type.find("javascript") != std::string::npos;
    if (text && res.body.size() >= 1024 && !res.has_header("Content-Encoding") && accepts_gzip(req)) {
        res.body = gzip_fast(res.body);
        res.set_header("Content-Encoding", "gzip");
    }
    if (text) res.set_header("Vary", "Accept-Encoding");
    // The request object is httplib's own mutable local (as in the pre-routing handler).
    const_cast<httplib::Headers&>(req.headers).erase("Accept-Encoding");
}

}  // namespace cutload::server
