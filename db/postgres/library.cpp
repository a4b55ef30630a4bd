// PostgreSQL: the machine, tool and material libraries (one table each, the same columns).
#include "postgres/store.hpp"

#include <fmt/format.h>

namespace cutload::db::postgres {
namespace {

const char* table_of(LibraryKind k) {
    switch (k) {
        case LibraryKind::Machine: return "machines";
        case LibraryKind::Tool: return "tools";
        case LibraryKind::Material: return "materials";
    }
    throw std::logic_error("unknown library kind");
}

LibraryItem item_row(const Result& r, int i) {
    return LibraryItem{r.i64(i, 0), r.text(i, 1), r.text(i, 2), r.text(i, 3), r.text(i, 4)};
}

}  // namespace

std::vector<LibraryItem> Library::list(LibraryKind k, std::int64_t after_id, const std::optional<std::string>& name,
                                       std::int64_t limit) {
    auto r = c_.run(fmt::format("SELECT id, name, body, created_at, updated_at FROM {} WHERE id > $1 "
                                "AND ($2::text IS NULL OR name = $2) ORDER BY id LIMIT $3",
                                table_of(k)),
                    Params().add(after_id).add(name).add(limit));
    std::vector<LibraryItem> out;
    for (int i = 0; i < r.rows(); ++i) out.push_back(item_row(r, i));
    return out;
}

std::optional<LibraryItem> Library::get(LibraryKind k, std::int64_t id) {
    auto r = c_.run(fmt::format("SELECT id, name, body, created_at, updated_at FROM {} WHERE id = $1", table_of(k)),
                    Params().add(id));
    if (r.empty()) return std::nullopt;
    return item_row(r, 0);
}

std::optional<std::int64_t> Library::find_by_name(LibraryKind k, const std::string& name) {
    auto r = c_.run(fmt::format("SELECT id FROM {} WHERE name = $1", table_of(k)), Params().add(name));
    if (r.empty()) return std::nullopt;
    return r.i64(0, 0);
}

std::optional<std::int64_t> Library::create(LibraryKind k, const std::string& name, const std::string& body_json,
                                            const std::string& now) {
    // ON CONFLICT on the name: a taken name inserts nothing (and fails no transaction around it).
    auto r = c_.run(fmt::format("INSERT INTO {}(name, body, created_at, updated_at) VALUES ($1,$2,$3,$4) "
                                "ON CONFLICT (name) DO NOTHING RETURNING id",
                                table_of(k)),
                    Params().add(name).add(body_json).add(now).add(now));
    if (r.empty()) return std::nullopt;
    return r.i64(0, 0);
}

LibraryWrite Library::update(LibraryKind k, std::int64_t id, const std::string& name, const std::string& body_json,
                             const std::string& now) {
    try {
        const auto changed = guarded(c_, [&] {
            return c_.run(fmt::format("UPDATE {} SET name = $1, body = $2, updated_at = $3 WHERE id = $4", table_of(k)),
                          Params().add(name).add(body_json).add(now).add(id))
                .affected();
        });
        return changed > 0 ? LibraryWrite::Done : LibraryWrite::NotFound;
    } catch (const Error& e) {
        if (e.is_constraint()) return LibraryWrite::NameTaken;   // the only constraint of an update: the unique name
        throw;
    }
}

bool Library::remove(LibraryKind k, std::int64_t id) {
    return c_.run(fmt::format("DELETE FROM {} WHERE id = $1", table_of(k)), Params().add(id)).affected() > 0;
}

}  // namespace cutload::db::postgres
