#include "postgres/libpq.hpp"

#include "db/store.hpp"

#include <dlfcn.h>

#include <string>

namespace cutload::db::postgres {
namespace {

constexpr const char* kLibPq = "libpq.so.5";

template <class Fn>
void resolve(void* lib, Fn& fn, const char* name) {
    fn = reinterpret_cast<Fn>(dlsym(lib, name));
    if (!fn) throw Error(std::string("PostgreSQL store: ") + kLibPq + " has no " + name, Error::Kind::Other);
}

LibPq load() {
    // Never closed: connections may live until the process exits.
    void* lib = dlopen(kLibPq, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        const char* why = dlerror();
        throw Error(std::string("PostgreSQL store: cannot load ") + kLibPq + " (install libpq5): " + (why ? why : "unknown"),
                    Error::Kind::Other);
    }
    LibPq pq{};
#define CUTLOAD_RESOLVE(name) resolve(lib, pq.name, #name)
    CUTLOAD_RESOLVE(PQconnectdb);
    CUTLOAD_RESOLVE(PQstatus);
    CUTLOAD_RESOLVE(PQerrorMessage);
    CUTLOAD_RESOLVE(PQfinish);
    CUTLOAD_RESOLVE(PQreset);
    CUTLOAD_RESOLVE(PQsetNoticeProcessor);
    CUTLOAD_RESOLVE(PQtransactionStatus);
    CUTLOAD_RESOLVE(PQsocket);
    CUTLOAD_RESOLVE(PQconsumeInput);
    CUTLOAD_RESOLVE(PQnotifies);
    CUTLOAD_RESOLVE(PQfreemem);
    CUTLOAD_RESOLVE(PQexec);
    CUTLOAD_RESOLVE(PQprepare);
    CUTLOAD_RESOLVE(PQexecPrepared);
    CUTLOAD_RESOLVE(PQresultStatus);
    CUTLOAD_RESOLVE(PQresultErrorMessage);
    CUTLOAD_RESOLVE(PQresultErrorField);
    CUTLOAD_RESOLVE(PQclear);
    CUTLOAD_RESOLVE(PQntuples);
    CUTLOAD_RESOLVE(PQcmdTuples);
    CUTLOAD_RESOLVE(PQgetisnull);
    CUTLOAD_RESOLVE(PQgetlength);
    CUTLOAD_RESOLVE(PQgetvalue);
    CUTLOAD_RESOLVE(PQftype);
#undef CUTLOAD_RESOLVE
    return pq;
}

}  // namespace

const LibPq& libpq() {
    static const LibPq pq = load();
    return pq;
}

}  // namespace cutload::db::postgres
