// `kdtrace bench kdtree`, table 6.1: one row per builder configuration (size, build time,
// render time of each view, split counts, Mrays/s, work per ray), every row checked against
// the first row's hits.
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "app/bench/bench_kdtree.h"
#include "app/bench/bench_options.h"
#include "app/bench/bench_rays.h"
#include "renderer/accel/kdtree_cache.h"
#include "renderer/core/error.h"
#include "renderer/core/temp_file.h"
#include "renderer/core/timer.h"

namespace kdt::app::kdtree_bench {
namespace {

namespace fs = std::filesystem;

std::vector<Config> table_configs() {
    auto thesis = [](float q, bool median, bool center) {
        KdTreeParams p;
        p.builder = KdBuilder::thesis;
        p.q = q;
        p.n0 = 5;
        p.max_depth = 20;
        p.use_median_split = median;
        p.use_center_split = center;
        return p;
    };
    std::vector<Config> c = {
        {"1", "first implementation (q = 1, no median split)", thesis(1.00f, false, true)},
        {"2", "no median split", thesis(0.98f, false, true)},
        {"3", "no center split", thesis(0.98f, true, false)},
        {"4", "q = 0.90", thesis(0.90f, true, true)},
        {"5", "q = 0.95", thesis(0.95f, true, true)},
        {"6", "q = 0.98", thesis(0.98f, true, true)},
        {"7", "q = 1.00", thesis(1.00f, true, true)},
    };
    KdTreeParams sah;
    sah.builder = KdBuilder::sah;
    c.push_back({"sah", "our SAH builder (Wald & Havran 2006)", sah});
    return c;
}

WorkPerRay count_work(const KdTree& tree, const std::vector<Ray>& rays,
                      [[maybe_unused]] int threads) {
    uint64_t nodes = 0, tests = 0;
    const int64_t n = int64_t(rays.size());
#pragma omp parallel for schedule(dynamic, 4096) num_threads(threads) reduction(+ : nodes, tests)
    for (int64_t i = 0; i < n; ++i) {
        TraversalCounters c;
        Hit h;
        tree.intersect(rays[size_t(i)], h, &c);
        nodes += c.nodes_visited;
        tests += c.triangles_tested;
    }
    return {quotient(double(nodes), double(n)), quotient(double(tests), double(n))};
}

// A grey-scale picture of a view (first sample per pixel, |cos| between ray and geometric
// normal) to check the framing of the views file by eye.
void save_view_image(const std::string& path, const ViewSet& set, const TriangleMesh& mesh,
                     const std::vector<Ray>& rays, const std::vector<Hit>& hits) {
    const int w = set.width, h = set.height, spp = set.samples_per_pixel;
    std::vector<unsigned char> img(size_t(w) * size_t(h), 0);
    size_t i = 0;
    for (int ty = 0; ty < h; ty += 8) {
        for (int tx = 0; tx < w; tx += 8) {
            for (int y = ty; y < std::min(h, ty + 8); ++y) {
                for (int x = tx; x < std::min(w, tx + 8); ++x, i += size_t(spp)) {
                    const Hit& hit = hits[i];
                    if (!hit.valid()) continue;
                    const Vec3u t = mesh.triangles[hit.prim];
                    Vec3f n = glm::cross(mesh.positions[t.y] - mesh.positions[t.x],
                                         mesh.positions[t.z] - mesh.positions[t.x]);
                    const float c = std::fabs(glm::dot(glm::normalize(n), rays[i].dir));
                    img[size_t(y) * size_t(w) + size_t(x)] = (unsigned char)(40.0f + 215.0f * c);
                }
            }
        }
    }
    const std::string header = "P5\n" + std::to_string(w) + " " + std::to_string(h) + "\n255\n";
    img.insert(img.begin(), header.begin(), header.end());
    write_file_atomically(path, img.data(), img.size());
}

/// The row's parameters with the command line's overrides for its builder.
KdTreeParams row_params(const Context& ctx, const Config& cfg) {
    const Options& opt = ctx.opt;
    KdTreeParams params = cfg.params;
    params.threads = ctx.threads;
    if (params.builder == KdBuilder::thesis) {
        if (opt.depth > 0) params.max_depth = opt.depth;
        if (opt.n0 >= 0) params.n0 = opt.n0;
    } else {
        if (opt.sah_traversal_cost > 0.0f) params.traversal_cost = opt.sah_traversal_cost;
        if (opt.sah_intersect_cost > 0.0f) params.intersect_cost = opt.sah_intersect_cost;
        if (opt.sah_empty_bonus >= 0.0f) params.empty_bonus = opt.sah_empty_bonus;
        if (opt.sah_depth > 0) params.max_depth = opt.sah_depth;
    }
    return params;
}

RowResult build_row(const Context& ctx, const Config& cfg) {
    const Options& opt = ctx.opt;
    RowResult r;
    r.config = cfg;
    const KdTreeParams params = row_params(ctx, cfg);
    r.config.params = params;
    std::vector<double> builds;
    if (opt.use_cache) {
        r.tree = get_or_build_kdtree(ctx.model_key, ctx.mesh, params);
        builds.push_back(r.tree->stats().build_seconds);
    } else {
        for (int k = 0; k < ctx.repeat; ++k) {
            r.tree.reset();
            const size_t rss0 = current_rss_bytes();
            reset_peak_rss();
            Timer t;
            r.tree = build_kdtree(ctx.mesh, params);
            builds.push_back(t.seconds());
            const size_t peak = peak_rss_bytes();
            if (k == 0 && peak > rss0) r.rss_build_mb = double(peak - rss0) / (1024.0 * 1024.0);
        }
    }
    r.build_seconds = median(builds);
    if (opt.leaf_vertex_indices != "auto") {
        // The same tree with the leaf data asked for (the build is timed without it).
        const KdTree& t = *r.tree;
        r.tree = std::make_shared<const KdTree>(
            t.mesh_ptr(), t.bounds(), t.nodes(), t.indices(), t.params(), t.stats(),
            opt.leaf_vertex_indices == "on" ? LeafVertexIndices::always : LeafVertexIndices::never);
    }
    std::fprintf(stderr, "row %s: build %.3f s, %.1f bytes/triangle\n", cfg.id.c_str(),
                 r.build_seconds, double(tree_size(*r.tree).bytes) / ctx.triangles);
    return r;
}

/// One row of table 6.1; the first row is the reference the others' hits are compared to.
std::vector<std::string> row_cells(const Context& ctx, const RowResult& r, bool first_row) {
    const KdTreeStats& s = r.tree->stats();
    const KdTreeParams& p = r.config.params;
    const double tris = ctx.triangles;
    std::vector<std::string> row = {r.config.id,
                                    kKdBuilderNames[size_t(p.builder)],
                                    p.builder == KdBuilder::thesis ? fmt("%.2f", p.q) : "-",
                                    p.builder == KdBuilder::thesis ? std::to_string(p.n0) : "-",
                                    std::to_string(s.max_depth_reached) + "/" +
                                        (p.max_depth ? std::to_string(p.max_depth) : "auto"),
                                    fmt("%.0f", double(tree_size(*r.tree).bytes) / 1024.0),
                                    fmt("%.3f", r.build_seconds)};
    for (double sec : r.view_seconds) row.push_back(fmt("%.3f", sec));
    row.push_back(std::to_string(s.median_splits));
    row.push_back(std::to_string(s.center_splits));
    row.push_back(std::to_string(s.cutoff_splits));
    row.push_back(std::to_string(s.sah_splits));
    row.push_back(fmt("%.2f", r.mrays));
    row.push_back(fmt("%.2f", r.primary_work.nodes));
    row.push_back(fmt("%.2f", r.primary_work.tests));
    row.push_back(fmt("%.2f", r.diffuse_mrays));
    row.push_back(fmt("%.2f", r.diffuse_work.nodes));
    row.push_back(fmt("%.2f", r.diffuse_work.tests));
    const TreeSize z = tree_size(*r.tree);
    row.push_back(std::to_string(z.nodes));
    row.push_back(std::to_string(z.leaves));
    row.push_back(fmt("%.2f", double(z.refs) / tris));
    // Stored only within the byte budget; they speed up leaf tests, so rows with and
    // without them differ in time for a reason other than their split choices.
    row.push_back(r.tree->reference_triangles().empty() ? "no" : "yes");
    row.push_back(fmt("%.1f", double(z.bytes) / tris));
    row.push_back(fmt("%.1f", double(s.peak_build_bytes) / (1024.0 * 1024.0)));
    row.push_back(ctx.opt.use_cache ? "-" : fmt("%.1f", r.rss_build_mb));
    row.push_back(first_row ? "-"
                            : std::to_string(r.disagreements) + " / " +
                                  std::to_string(r.diffuse_disagreements));
    std::string remark = r.config.remark;
    if (p.builder == KdBuilder::sah)
        remark += fmt(", costs: traversal %g", p.traversal_cost) +
                  fmt(", intersection %g", p.intersect_cost) +
                  fmt(", empty bonus %g", p.empty_bonus);
    row.push_back(remark);
    return row;
}

}  // namespace

std::vector<Config> select_rows(const std::string& rows) {
    std::vector<Config> configs;
    const std::vector<Config> all = table_configs();
    std::vector<std::string> ids;
    std::stringstream ss(rows);
    std::string id;
    while (std::getline(ss, id, ',')) {
        auto it = std::find_if(all.begin(), all.end(), [&](const Config& c) { return c.id == id; });
        if (it == all.end()) {
            throw Error(ErrorLocation{"--rows"}, "unknown row '" + id + "' (1-7 or sah)");
        }
        configs.push_back(*it);
        ids.push_back(id);
    }
    if (configs.empty()) throw Error(ErrorLocation{"--rows"}, "no rows selected");
    refuse_repeated_entries("--rows", ids);
    return configs;
}

bool same_hit(const Hit& a, const Hit& b) {
    if (a.valid() != b.valid()) return false;
    if (!a.valid()) return true;
    return std::fabs(a.t - b.t) <= 1e-5f * std::max(std::fabs(a.t), std::fabs(b.t));
}

uint64_t count_disagreements(const std::vector<Hit>& a, const std::vector<Hit>& b) {
    uint64_t n = 0;
    for (size_t i = 0; i < a.size(); ++i) n += same_hit(a[i], b[i]) ? 0 : 1;
    return n;
}

TreeSize tree_size(const KdTree& tree) {
    TreeSize z;
    z.nodes = tree.nodes().size();
    for (const KdNode& n : tree.nodes()) z.leaves += n.is_leaf() ? 1 : 0;
    z.refs = tree.indices().size();
    z.bytes = tree.stats().bytes;  // counted by the KdTree from its arrays, for every builder
    return z;
}

std::vector<ViewRays> make_view_rays(const Context& ctx) {
    std::vector<ViewRays> view_rays;
    for (size_t v = 0; v < ctx.views.views.size(); ++v) {
        view_rays.push_back({ctx.views.views[v].name, make_primary_rays(ctx.views, v), {}, 0});
    }
    return view_rays;
}

// Every row's tree is built before any is timed (see time_rows).
std::vector<RowResult> build_rows(const Context& ctx) {
    std::vector<RowResult> results;
    for (const Config& cfg : ctx.configs) results.push_back(build_row(ctx, cfg));
    return results;
}

void trace_references(const Context& ctx, const KdTree& tree, RaySets& rays) {
    uint64_t total_primary = 0;
    for (const auto& vr : rays.views) total_primary += vr.rays.size();
    std::vector<Hit> primary_hits;
    rays.primary.reserve(total_primary);
    for (ViewRays& vr : rays.views) {
        trace_closest(vr.rays, vr.reference, ctx.threads,
                      [&](const Ray& ray, Hit& h) { tree.intersect(ray, h); });
        if (!ctx.opt.save_views.empty()) {
            save_view_image(save_view_path(ctx.opt.save_views, vr.name), ctx.views, *ctx.mesh,
                            vr.rays, vr.reference);
        }
        vr.hits = uint64_t(std::count_if(vr.reference.begin(), vr.reference.end(),
                                         [](const Hit& h) { return h.valid(); }));
        rays.primary.insert(rays.primary.end(), vr.rays.begin(), vr.rays.end());
        primary_hits.insert(primary_hits.end(), vr.reference.begin(), vr.reference.end());
    }
    rays.diffuse = make_diffuse_rays(*ctx.mesh, rays.primary, primary_hits, ctx.views.seed,
                                     &rays.diffuse_sources);
    trace_closest(rays.diffuse, rays.diffuse_reference, ctx.threads,
                  [&](const Ray& ray, Hit& h) { tree.intersect(ray, h); });
}

// Each repeat times every row in turn (rows interleaved, as the engines of the Embree
// table are), so drift on this shared machine hits all rows alike instead of favouring
// whichever row ran in a quiet minute.
void time_rows(const Context& ctx, const RaySets& rays, std::vector<RowResult>& results) {
    const int threads = ctx.threads;
    std::vector<std::vector<std::vector<double>>> view_times(
        results.size(), std::vector<std::vector<double>>(rays.views.size()));
    std::vector<std::vector<double>> diffuse_times(results.size());
    for (int k = 0; k < ctx.repeat; ++k) {
        for (size_t ri = 0; ri < results.size(); ++ri) {
            RowResult& r = results[ri];
            const KdTree& tree = *r.tree;
            auto isect = [&](const Ray& ray, Hit& h) { tree.intersect(ray, h); };
            std::vector<Hit> hits;
            for (size_t v = 0; v < rays.views.size(); ++v) {
                view_times[ri][v].push_back(
                    trace_closest(rays.views[v].rays, hits, threads, isect));
                if (k == 0 && ri > 0)
                    r.disagreements += count_disagreements(rays.views[v].reference, hits);
            }
            diffuse_times[ri].push_back(trace_closest(rays.diffuse, hits, threads, isect));
            if (k == 0 && ri > 0)
                r.diffuse_disagreements = count_disagreements(rays.diffuse_reference, hits);
        }
    }
    for (size_t ri = 0; ri < results.size(); ++ri) {
        RowResult& r = results[ri];
        double total = 0.0;
        for (const std::vector<double>& times : view_times[ri]) {
            r.view_seconds.push_back(median(times));
            total += r.view_seconds.back();
        }
        r.mrays = mega_rate(double(rays.primary.size()), total);
        r.diffuse_mrays = mega_rate(double(rays.diffuse.size()), median(diffuse_times[ri]));
        // The work per ray does not depend on the machine's load: one untimed counted pass.
        r.primary_work = count_work(*r.tree, rays.primary, threads);
        r.diffuse_work = count_work(*r.tree, rays.diffuse, threads);
        std::fprintf(
            stderr,
            "row %s: %s primary / %s diffuse Mrays/s; per diffuse ray %s nodes, %s "
            "triangle tests\n",
            r.config.id.c_str(), fmt("%.2f", r.mrays).c_str(), fmt("%.2f", r.diffuse_mrays).c_str(),
            fmt("%.1f", r.diffuse_work.nodes).c_str(), fmt("%.1f", r.diffuse_work.tests).c_str());
    }
}

Table table_6_1(const Context& ctx, const std::vector<RowResult>& results) {
    const ViewSet& views = ctx.views;
    Table t1;
    t1.name = "kdtree";
    t1.title = "Thesis table 6.1 on " + fs::path(ctx.model).filename().string() + " (" +
               std::to_string(ctx.mesh->triangle_count()) + " triangles), " +
               std::to_string(views.width) + "x" + std::to_string(views.height) + ", " +
               std::to_string(views.samples_per_pixel) + " jittered primary rays per pixel, " +
               std::to_string(ctx.threads) + " threads, medians of " + std::to_string(ctx.repeat);
    t1.header = {"row", "builder", "q", "n0", "depth", "size KB", "build s"};
    for (const auto& v : views.views) t1.header.push_back(v.name + " s");
    for (const std::string& h :
         {std::string("median"), std::string("center"), std::string("cut-off"), std::string("sah"),
          std::string("Mrays/s"), std::string("nodes / ray"), std::string("tests / ray"),
          std::string("diffuse Mrays/s"), std::string("nodes / diffuse ray"),
          std::string("tests / diffuse ray"), std::string("nodes"), std::string("leaves"),
          std::string("refs/tri"), std::string("leaf vertex indices"), std::string("bytes/tri"),
          std::string("peak build MB"), std::string("RSS build MB"),
          "hit diffs vs row " + ctx.configs[0].id + " (primary / diffuse)",
          std::string("remark")}) {
        t1.header.push_back(h);
    }
    for (const RowResult& r : results) t1.rows.push_back(row_cells(ctx, r, &r == &results[0]));
    return t1;
}

}  // namespace kdt::app::kdtree_bench
