// Private to db: libpq, opened on first use rather than linked.
//
// Linked, libpq makes every cutload command map it and the twenty libraries it needs (Kerberos,
// LDAP, GnuTLS, ...) before main: about 480 page faults and 9 ms on the 2-core test machine, a
// fifth of `cutload inspect`'s whole budget, for a library only a postgres:// store uses.
#pragma once

#include <libpq-fe.h>

namespace cutload::db::postgres {

// The libpq calls the store makes, named as libpq names them.
struct LibPq {
    decltype(&::PQconnectdb) PQconnectdb;
    decltype(&::PQstatus) PQstatus;
    decltype(&::PQerrorMessage) PQerrorMessage;
    decltype(&::PQfinish) PQfinish;
    decltype(&::PQreset) PQreset;
    decltype(&::PQsetNoticeProcessor) PQsetNoticeProcessor;
    decltype(&::PQtransactionStatus) PQtransactionStatus;
    decltype(&::PQsocket) PQsocket;
    decltype(&::PQconsumeInput) PQconsumeInput;
    decltype(&::PQnotifies) PQnotifies;
    decltype(&::PQfreemem) PQfreemem;
    decltype(&::PQexec) PQexec;
    decltype(&::PQprepare) PQprepare;
    decltype(&::PQexecPrepared) PQexecPrepared;
    decltype(&::PQresultStatus) PQresultStatus;
    decltype(&::PQresultErrorMessage) PQresultErrorMessage;
    decltype(&::PQresultErrorField) PQresultErrorField;
    decltype(&::PQclear) PQclear;
    decltype(&::PQntuples) PQntuples;
    decltype(&::PQcmdTuples) PQcmdTuples;
    decltype(&::PQgetisnull) PQgetisnull;
    decltype(&::PQgetlength) PQgetlength;
    decltype(&::PQgetvalue) PQgetvalue;
    decltype(&::PQftype) PQftype;
};

// Loaded once per process (thread-safe); throws db::Error (Kind::Other) naming libpq.so.5
// and the loader's reason when it is missing or lacks a call.
const LibPq& libpq();

}  // namespace cutload::db::postgres
