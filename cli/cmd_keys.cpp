// cutload keys create | list | revoke: API keys of the service. A new key is printed once, on the
// last line of output; only its SHA-256 is stored, so listings show the key's prefix, never the key.
#include "commands.hpp"
#include "server/server.hpp"

#include <cstdio>
#include <stdexcept>

namespace cutload::cli {
namespace {

struct KeysArgs {
    std::string role = "read";
    std::string db = "cutload.db";
    std::string name;
    std::string prefix;
};

void print_keys(const std::string& db) {
    std::vector<server::ApiKeyInfo> keys;
    try {
        keys = server::list_api_keys(db);
    } catch (const std::invalid_argument& e) {
        throw UsageError(e.what());
    }
    std::printf("%-10s  %-5s  %-20s  %-24s  %-24s  %s\n", "PREFIX", "ROLE", "NAME", "CREATED", "LAST USED", "REVOKED");
    for (const auto& k : keys)
        std::printf("%-10s  %-5s  %-20s  %-24s  %-24s  %s\n", k.prefix.c_str(), server::role_name(k.role),
                    k.name.empty() ? "-" : k.name.c_str(), k.created_at.c_str(), k.last_used_at.value_or("never").c_str(),
                    k.revoked_at.value_or("-").c_str());
    std::printf("%zu key(s) in %s\n", keys.size(), server::printable_db(db).c_str());
}

void revoke_key(const std::string& db, const std::string& prefix) {
    server::ApiKeyInfo k;
    bool already = false;
    try {
        k = server::revoke_api_key(db, prefix, &already);
    } catch (const std::invalid_argument& e) {
        throw UsageError(e.what());
    }
    std::printf("%s %s key %s%s%s at %s; requests with it get 401\n", already ? "already revoked:" : "revoked",
                server::role_name(k.role), k.prefix.c_str(), k.name.empty() ? "" : ", ", k.name.c_str(),
                k.revoked_at.value_or("?").c_str());
}

void add_keys(CLI::App& app) {
    auto a = std::make_shared<KeysArgs>();
    auto* keys = app.add_subcommand("keys", "Manage API keys of the service");
    keys->require_subcommand(1);
    auto* create = keys->add_subcommand("create", "Create an API key and print it (last line)");
    create->add_option("--role", a->role, "read: GET only; write: also upload, cancel, edit libraries; admin: everything")
        ->check(CLI::IsMember({"read", "write", "admin"}))
        ->capture_default_str();
    create->add_option("--db", a->db, "Store of the service: SQLite file or postgresql:// URL")->capture_default_str();
    create->add_option("--name", a->name, "Label shown in key listings (e.g. who holds it)");
    create->callback([a] {
        const std::string key = server::create_api_key(a->db, server::parse_role(a->role), a->name);
        std::printf("created %s key in %s (only its hash is stored; keep it now):\n%s\n", a->role.c_str(), server::printable_db(a->db).c_str(),
                    key.c_str());
    });

    auto* list = keys->add_subcommand("list", "List keys: prefix, role, name, created, last used, revoked");
    list->add_option("--db", a->db, "Store of the service: SQLite file or postgresql:// URL")->capture_default_str();
    list->callback([a] { print_keys(a->db); });

    auto* revoke = keys->add_subcommand("revoke", "Revoke a key: its requests get 401 from now on");
    revoke->add_option("PREFIX", a->prefix, "The key's prefix as `keys list` shows it (or the whole key)")->required();
    revoke->add_option("--db", a->db, "Store of the service: SQLite file or postgresql:// URL")->capture_default_str();
    revoke->callback([a] { revoke_key(a->db, a->prefix); });
}

const bool registered = register_command("keys", &add_keys);

}  // namespace
}  // namespace cutload::cli
