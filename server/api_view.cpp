// Routes that serve the web page's views of a finished run: /api/v1/runs/{id}/stock (the final
// stock as a height field for the 3-D view).
#include "core.hpp"
#include "jobs.hpp"

#include <cmath>

namespace cutload::server {
namespace {

constexpr std::int64_t kDefaultStockCells = 40000;
constexpr std::int64_t kMaxStockCells = 1000000;

// Millimetres to the micrometre: the stock's float carries no more, and the answer stays small.
json micrometres(double v_mm) { return std::isfinite(v_mm) ? json(std::round(v_mm * 1000.0) / 1000.0) : json(nullptr); }

json height_field_json(std::int64_t run_id, const force_model::StockHeightField& f) {
    json top = json::array();
    for (float v : f.top_mm) top.push_back(micrometres(v));
    const auto& b = f.box;
    return {{"run_id", run_id},
            {"box_mm", {{"min", {b.min_mm[0], b.min_mm[1], b.min_mm[2]}}, {"max", {b.max_mm[0], b.max_mm[1], b.max_mm[2]}}}},
            {"x0_mm", f.x0_mm},
            {"y0_mm", f.y0_mm},
            {"cell_mm", f.cell_mm},
            {"nx", f.nx},
            {"ny", f.ny},
            {"rays_per_cell", f.rays_per_cell},
            {"top_mm", std::move(top)}};
}

}  // namespace

void add_view_routes(Core& core) {
    core.route({"GET", "/api/v1/runs/{id}/stock", Role::Read,
                {path_id(),
                 query_int("max_cells", "at most this many cells: each is the highest material top of the k x k stock rays "
                                        "it covers (k = rays_per_cell)")
                     .range(1, static_cast<double>(kMaxStockCells))
                     .or_else(kDefaultStockCells)}},
               [&core](Ctx& x) {
                   const std::int64_t id = x.id();
                   const auto max_cells = static_cast<std::size_t>(*x.param_int("max_cells"));
                   require_done(*core.session(), id);
                   // The final stock as stored (what a run with base_run starts from).
                   const auto stock = load_base_stock(*core.store, id);
                   x.reply(200, height_field_json(id, force_model::stock_height_field(*stock, max_cells)));
               });
}

}  // namespace cutload::server
