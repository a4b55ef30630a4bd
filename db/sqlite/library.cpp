// SQLite: the machine, tool and material libraries (one table each, the same columns).
#include "sqlite/store.hpp"

#include <fmt/format.h>

namespace cutload::db::sqlite {
namespace {

const char* table_of(LibraryKind k) {
    switch (k) {
        case LibraryKind::Machine: return "machines";
        case LibraryKind::Tool: return "tools";
        case LibraryKind::Material: return "materials";
    }
    throw std::logic_error("unknown library kind");
}

LibraryItem item_row(const Stmt& st) {
    return LibraryItem{st.i64(0), st.text(1), st.text(2), st.text(3), st.text(4)};
}

}  // namespace

std::vector<LibraryItem> Library::list(LibraryKind k, std::int64_t after_id, const std::optional<std::string>& name,
                                       std::int64_t limit) {
    auto st = c_.prepare(fmt::format(
        "SELECT id, name, body, created_at, updated_at FROM {} WHERE id > ?1 AND (?2 IS NULL OR name = ?2) "
        "ORDER BY id LIMIT ?3",
        table_of(k)));
    st.bind(1, after_id).bind(2, name).bind(3, limit);
    std::vector<LibraryItem> out;
    while (st.step()) out.push_back(item_row(st));
    return out;
}

std::optional<LibraryItem> Library::get(LibraryKind k, std::int64_t id) {
    auto st = c_.prepare(fmt::format("SELECT id, name, body, created_at, updated_at FROM {} WHERE id = ?", table_of(k)));
    st.bind(1, id);
    if (!st.step()) return std::nullopt;
    return item_row(st);
}

std::optional<std::int64_t> Library::find_by_name(LibraryKind k, const std::string& name) {
    auto st = c_.prepare(fmt::format("SELECT id FROM {} WHERE name = ?", table_of(k)));
    st.bind(1, name);
    if (!st.step()) return std::nullopt;
    return st.i64(0);
}

std::optional<std::int64_t> Library::create(LibraryKind k, const std::string& name, const std::string& body_json,
                                            const std::string& now) {
    try {
        c_.prepare(fmt::format("INSERT INTO {}(name, body, created_at, updated_at) VALUES (?,?,?,?)", table_of(k)))
            .bind(1, name)
            .bind(2, body_json)
            .bind(3, now)
            .bind(4, now)
            .run();
    } catch (const Error& e) {
        if (e.is_constraint()) return std::nullopt;   // the only constraint of an insert: the unique name
        throw;
    }
    return c_.last_insert_id();
}

LibraryWrite Library::update(LibraryKind k, std::int64_t id, const std::string& name, const std::string& body_json,
                             const std::string& now) {
    try {
        c_.prepare(fmt::format("UPDATE {} SET name = ?, body = ?, updated_at = ? WHERE id = ?", table_of(k)))
            .bind(1, name)
            .bind(2, body_json)
            .bind(3, now)
            .bind(4, id)
            .run();
    } catch (const Error& e) {
        if (e.is_constraint()) return LibraryWrite::NameTaken;
        throw;
    }
    return c_.changes() > 0 ? LibraryWrite::Done : LibraryWrite::NotFound;
}

bool Library::remove(LibraryKind k, std::int64_t id) {
    c_.prepare(fmt::format("DELETE FROM {} WHERE id = ?", table_of(k))).bind(1, id).run();
    return c_.changes() > 0;
}

}  // namespace cutload::db::sqlite
