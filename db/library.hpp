// Public interface of db: the libraries run specs may reference (machines, tools, materials).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace cutload::db {

enum class LibraryKind { Machine, Tool, Material };

struct LibraryItem {
    std::int64_t id = 0;
    std::string name;        // unique within its kind
    std::string body_json;   // what the service validated and stored, without the name
    std::string created_at, updated_at;
};

enum class LibraryWrite { Done, NotFound, NameTaken };

class LibraryRepository {
public:
    virtual ~LibraryRepository() = default;

    // By id, from ids above `after_id`, at most `limit`; only the one named `name` when set.
    virtual std::vector<LibraryItem> list(LibraryKind k, std::int64_t after_id, const std::optional<std::string>& name,
                                          std::int64_t limit) = 0;
    virtual std::optional<LibraryItem> get(LibraryKind k, std::int64_t id) = 0;
    virtual std::optional<std::int64_t> find_by_name(LibraryKind k, const std::string& name) = 0;
    // The new id, or nullopt when the name is taken.
    virtual std::optional<std::int64_t> create(LibraryKind k, const std::string& name, const std::string& body_json,
                                               const std::string& now) = 0;
    virtual LibraryWrite update(LibraryKind k, std::int64_t id, const std::string& name, const std::string& body_json,
                                const std::string& now) = 0;
    // Runs keep their resolved spec; thresholds scoped to the item go with it.
    virtual bool remove(LibraryKind k, std::int64_t id) = 0;
};

}  // namespace cutload::db
