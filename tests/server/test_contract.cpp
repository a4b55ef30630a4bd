// The OpenAPI document matches the routes the server registers, both ways; /healthz and
// /metrics answer in their formats.
#include "harness.hpp"
#include "server/core.hpp"
#include "server/route.hpp"

#include <set>

using namespace cutload::test;

TEST_CASE("openapi: every registered route is documented and every documented route exists") {
    TestServer ts;
    const json doc = json::parse(cutload::server::openapi_json());
    REQUIRE(doc["openapi"].get<std::string>().rfind("3.", 0) == 0);

    std::set<std::pair<std::string, std::string>> registered, documented;
    for (const auto& [method, path] : ts.srv->routes()) registered.emplace(method, path);
    for (const auto& [path, item] : doc["paths"].items())
        for (const auto& [method, op] : item.items()) {
            if (method == "parameters") continue;
            std::string upper = method;
            for (auto& ch : upper) ch = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
            documented.emplace(upper, path);
            INFO(upper << " " << path);
            REQUIRE(op.contains("responses"));
            REQUIRE(op.contains("operationId"));
        }
    for (const auto& r : registered) {
        INFO("registered but not documented: " << r.first << " " << r.second);
        REQUIRE(documented.count(r) == 1);
    }
    for (const auto& d : documented) {
        INFO("documented but not registered: " << d.first << " " << d.second);
        REQUIRE(registered.count(d) == 1);
    }
    // The document served is the one compiled in.
    auto served = ts.client("").Get("/api/v1/openapi.json");
    REQUIRE(json::parse(served->body) == doc);
}

TEST_CASE("metrics and health: Prometheus text with requests and latency and jobs and queue depth") {
    TestServer ts;
    auto c = ts.admin();
    json health = body(c.Get("/healthz"));
    REQUIRE(health["status"] == "ok");
    auto r = upload(c, slot_log_csv(0.4), slot_spec());
    wait_finished(c, body(r)["id"]);
    c.Get("/api/v1/runs/999");
    // The job counter and the running gauge move just after the run's commit that wait_finished saw.
    std::string text;
    for (int i = 0; i < 100; ++i) {
        text = c.Get("/metrics")->body;
        if (text.find("cutload_jobs_total{state=\"done\"} 1") != std::string::npos &&
            text.find("cutload_jobs_running 0") != std::string::npos)
            break;
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    for (const char* needle :
         {"cutload_http_requests_total{method=\"POST\",route=\"/api/v1/runs\",status=\"202\"} 1",
          "cutload_http_requests_total{method=\"GET\",route=\"/api/v1/runs/{id}\",status=\"404\"} 1",
          "cutload_http_request_duration_seconds_bucket{route=\"/api/v1/runs\",le=\"+Inf\"} 1",
          "cutload_jobs_total{state=\"done\"} 1", "cutload_jobs_queued 0", "cutload_jobs_running 0",
          "# TYPE cutload_job_compute_seconds_total counter"}) {
        INFO(needle);
        REQUIRE(text.find(needle) != std::string::npos);
    }
}

namespace {

// The routes a server with the default options declares.
std::vector<cutload::server::RouteSpec> declared_routes() {
    cutload::server::Core core{cutload::server::ServerOptions{}};
    cutload::server::add_all_routes(core);
    return core.routes;
}

std::string lower(std::string s) {
    for (auto& ch : s) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    return s;
}

}  // namespace

TEST_CASE("openapi: parameters and key requirements come from the route declarations, bodies match their kind") {
    using cutload::server::Body;
    using cutload::server::ParamIn;
    const json base = json::parse(cutload::server::openapi_base());
    const json doc = json::parse(cutload::server::openapi_json());
    // The hand-kept part says nothing about parameters or keys: they would drift from the code.
    for (const auto& [path, item] : base["paths"].items()) {
        INFO(path);
        REQUIRE_FALSE(item.contains("parameters"));
        for (const auto& [method, op] : item.items()) {
            INFO(method);
            REQUIRE_FALSE(op.contains("parameters"));
            REQUIRE_FALSE(op.contains("security"));
        }
    }
    const auto routes = declared_routes();
    std::size_t with_params = 0;
    for (const auto& r : routes) {
        INFO(r.method << " " << r.path);
        const json& op = doc["paths"][r.path][lower(r.method)];
        // Parameter by parameter, both ways: the served operation lists exactly the declared ones.
        const json served = op.value("parameters", json::array());
        REQUIRE(served.size() == r.params.size());
        for (std::size_t i = 0; i < r.params.size(); ++i) {
            const auto& p = r.params[i];
            INFO(p.name);
            REQUIRE(served[i]["name"] == p.name);
            REQUIRE(served[i]["in"] == (p.in == ParamIn::Path ? "path" : "query"));
            REQUIRE(served[i]["required"] == p.required);
            REQUIRE(served[i]["schema"].value("default", json()) == p.fallback.value_or(json()));
            // Every {name} of the template is a declared path parameter.
            if (p.in == ParamIn::Path) REQUIRE(r.path.find("{" + p.name + "}") != std::string::npos);
        }
        with_params += r.params.empty() ? 0 : 1;
        if (r.role)
            REQUIRE(op["x-cutload-role"] == cutload::server::role_name(*r.role));
        else
            REQUIRE(op["security"] == json::array());
        // The body the route reads is the one documented.
        const json& rb = op.value("requestBody", json());
        switch (r.body) {
            case Body::None: REQUIRE(rb.is_null()); break;
            case Body::Multipart:
                REQUIRE(rb["content"].contains("multipart/form-data"));
                REQUIRE(rb.value("required", false));
                break;
            case Body::Json:
            case Body::OptionalJson:
                REQUIRE(rb["content"].contains("application/json"));
                REQUIRE(rb.value("required", false) == (r.body == Body::Json));
                break;
        }
    }
    REQUIRE(with_params > 20);
}

TEST_CASE("openapi: the run spec's schemas are the parser's, not a hand-kept copy") {
    const json base = json::parse(cutload::server::openapi_base());
    const json doc = json::parse(cutload::server::openapi_json());
    for (const char* name : {"RunSpec", "Tool", "NumberedTool"}) {
        INFO(name);
        REQUIRE_FALSE(base["components"]["schemas"].contains(name));
        REQUIRE(doc["components"]["schemas"].contains(name));
    }
    const json& schemas = doc["components"]["schemas"];
    // Every shape the parser takes, with the keys only some shapes read.
    CHECK(schemas["Tool"]["properties"]["shape"]["enum"] == json({"flat", "ball", "bull", "drill", "chamfer", "barrel"}));
    CHECK(schemas["Tool"]["properties"]["point_angle_deg"]["x-tool-shapes"] == json({"chamfer", "drill"}));
    CHECK(schemas["NumberedTool"]["properties"]["number"]["type"] == "integer");
    CHECK(schemas["RunSpec"]["properties"]["tool"] == schemas["Tool"]);
    CHECK(schemas["RunSpec"]["properties"]["limits"]["properties"]["force_N"]["x-unit"] == "N");
}
