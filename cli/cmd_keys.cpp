// cutload keys create: makes an API key for the service. The key is printed once, on the last
// line of output, and only its SHA-256 is stored.
#include "cli/commands.hpp"
#include "server/server.hpp"

#include <cstdio>

namespace cutload::cli {
namespace {

struct KeysArgs {
    std::string role = "read";
    std::string db = "cutload.db";
    std::string name;
};

void add_keys(CLI::App& app) {
    auto a = std::make_shared<KeysArgs>();
    auto* keys = app.add_subcommand("keys", "Manage API keys of the service");
    keys->require_subcommand(1);
    auto* create = keys->add_subcommand("create", "Create an API key and print it (last line)");
    create->add_option("--role", a->role, "read: GET only; write: also upload, cancel, edit libraries; admin: everything")
        ->check(CLI::IsMember({"read", "write", "admin"}))
        ->capture_default_str();
    create->add_option("--db", a->db, "SQLite database of the service")->capture_default_str();
    create->add_option("--name", a->name, "Label shown in key listings (e.g. who holds it)");
    create->callback([a] {
        const std::string key = server::create_api_key(a->db, server::parse_role(a->role), a->name);
        std::printf("created %s key in %s (only its hash is stored; keep it now):\n%s\n", a->role.c_str(), a->db.c_str(),
                    key.c_str());
    });
}

const bool registered = register_command("keys", &add_keys);

}  // namespace
}  // namespace cutload::cli
