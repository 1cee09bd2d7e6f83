// `kdtrace bench kdtree`: the thesis's table 6.1 on the dragon (one row per builder
// configuration: size, build time, render time of views A-D, split counts, Mrays/s), then
// the best tree against Embree on the same primary and one-bounce diffuse rays, then
// robustness (vertex- and edge-aimed rays, NaN/Inf rays). Markdown to stdout, CSV on request.
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "app/bench/bench_rays.h"
#include "app/bench/peer_embree.h"
#include "app/commands.h"
#include "renderer/accel/brute_force.h"
#include "renderer/accel/kdtree_cache.h"
#include "renderer/accel/traversal_detail.h"
#include "renderer/core/error.h"
#include "renderer/core/timer.h"
#include "renderer/io/mesh_io.h"

namespace kdt::app {
namespace {

namespace fs = std::filesystem;

struct Options {
    std::string model, views, csv, md, save_views, rows = "1,2,3,4,5,6,7,sah";
    int repeat = 5;
    int threads = 0;
    int subdivide = 0;
    int spp = 0;    // 0 = the views file's
    int depth = 0;  // 0 = the thesis's 20
    int n0 = -1;    // -1 = the thesis's 5
    // SAH row: 0 (costs) or < 0 (bonus) keeps KdTreeParams' default.
    float sah_traversal_cost = 0.0f, sah_intersect_cost = 0.0f, sah_empty_bonus = -1.0f;
    int sah_depth = 0;                         // 0 = automatic
    std::string leaf_vertex_indices = "auto";  // auto | on | off, for every row
    bool embree = true;
    bool embree_robust = false;
    bool use_cache = false;
    bool robustness = true;
    int robust_rays = 100000;
};

/// One configuration of table 6.1.
struct Config {
    std::string id, remark;
    KdTreeParams params;
};

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

double median(std::vector<double> v) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    const size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::string fmt(const char* f, double v) {
    char buf[64];
    std::snprintf(buf, sizeof(buf), f, v);
    return buf;
}

/// A table printed as Markdown and appended to the CSV under a table name.
struct Table {
    std::string name, title;
    std::vector<std::string> header;
    std::vector<std::vector<std::string>> rows;

    std::string markdown() const {
        std::ostringstream o;
        o << "### " << title << "\n\n|";
        for (const auto& h : header) o << " " << h << " |";
        o << "\n|";
        for (size_t i = 0; i < header.size(); ++i) o << (i == 0 ? " --- |" : " ---: |");
        o << "\n";
        for (const auto& r : rows) {
            o << "|";
            for (const auto& c : r) o << " " << c << " |";
            o << "\n";
        }
        return o.str();
    }
    void csv(std::ostream& o) const {
        o << "table";
        for (const auto& h : header) o << ",\"" << h << "\"";
        o << "\n";
        for (const auto& r : rows) {
            o << name;
            for (const auto& c : r) o << ",\"" << c << "\"";
            o << "\n";
        }
    }
};

std::string default_model() {
    fs::path cache;
    if (const char* env = std::getenv("KDT_CACHE_DIR"); env && *env) {
        cache = env;
    } else if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg) {
        cache = fs::path(xdg) / "kdtrace";
    } else if (const char* home = std::getenv("HOME")) {
        cache = fs::path(home) / ".cache" / "kdtrace";
    }
    return (cache / "stanford-dragon" / "dragon_vrip.ply").string();
}

/// The rays of one view and the reference hits (first configuration traced).
struct ViewRays {
    std::string name;
    std::vector<Ray> rays;
    std::vector<Hit> reference;
    uint64_t hits = 0;
};

/// Closest hits agree when hit/miss agree and t agrees to 1e-5 relative (the triangle may
/// differ where two triangles meet at the hit point).
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

/// Sizes counted from the arrays themselves (a cache file's statistics are informational:
/// its loader bounds them but does not recount them).
struct TreeSize {
    uint64_t nodes = 0, leaves = 0, refs = 0, bytes = 0;
};

TreeSize tree_size(const KdTree& tree) {
    TreeSize z;
    z.nodes = tree.nodes().size();
    for (const KdNode& n : tree.nodes()) z.leaves += n.is_leaf() ? 1 : 0;
    z.refs = tree.indices().size();
    z.bytes = tree.stats().bytes;  // counted by the KdTree from its arrays, for every builder
    return z;
}

/// Mean traversal work of one ray set, from the compiled-in counters.
struct WorkPerRay {
    double nodes = 0.0, tests = 0.0;
};

WorkPerRay count_work(const KdTree& tree, const std::vector<Ray>& rays, int threads) {
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
    const double count = double(std::max<int64_t>(n, 1));
    return {double(nodes) / count, double(tests) / count};
}

struct RowResult {
    Config config;
    std::shared_ptr<const KdTree> tree;
    double build_seconds = 0.0;
    double rss_build_mb = 0.0;
    std::vector<double> view_seconds;
    double mrays = 0.0, diffuse_mrays = 0.0;
    uint64_t disagreements = 0, diffuse_disagreements = 0;
    WorkPerRay primary_work, diffuse_work;
};

// Vertex- and edge-aimed rays: from random points on a sphere around the model, aimed
// exactly at a vertex (or edge midpoint) of a closed fan of triangles that, seen along the
// ray, surrounds the aimed point (not on the silhouette). Any ray through such a point
// must hit the fan, so a watertight closest-hit query hits at t <= 1; a miss or a hit
// behind it is an escape. Silhouette points are skipped: there a ray passing one rounding
// error beside the point may rightly miss.
struct AimedRays {
    std::vector<Ray> vertex, edge;
};

AimedRays make_aimed_rays(const TriangleMesh& mesh, int count, uint64_t seed) {
    struct EdgeUse {
        uint32_t faces = 0;
        uint32_t opposite[2] = {0, 0};
    };
    std::unordered_map<uint64_t, EdgeUse> edges;
    edges.reserve(mesh.triangle_count() * 2);
    auto key = [](uint32_t a, uint32_t b) {
        return a < b ? (uint64_t(a) << 32 | b) : (uint64_t(b) << 32 | a);
    };
    // Vertex -> incident triangles (CSR).
    std::vector<uint32_t> first(mesh.vertex_count() + 1, 0), incident;
    for (const Vec3u& t : mesh.triangles) {
        if (t.x == t.y || t.y == t.z || t.z == t.x) continue;
        for (int k = 0; k < 3; ++k) {
            ++first[t[k] + 1];
            EdgeUse& e = edges[key(t[k], t[(k + 1) % 3])];
            if (e.faces < 2) e.opposite[e.faces] = t[(k + 2) % 3];
            ++e.faces;
        }
    }
    for (size_t v = 0; v < mesh.vertex_count(); ++v) first[v + 1] += first[v];
    incident.resize(first.back());
    {
        std::vector<uint32_t> fill(first.begin(), first.end() - 1);
        for (uint32_t i = 0; i < mesh.triangle_count(); ++i) {
            const Vec3u& t = mesh.triangles[i];
            if (t.x == t.y || t.y == t.z || t.z == t.x) continue;
            for (int k = 0; k < 3; ++k) incident[fill[t[k]]++] = i;
        }
    }
    std::vector<uint8_t> vertex_ok(mesh.vertex_count(), 0);
    for (size_t v = 0; v < mesh.vertex_count(); ++v) vertex_ok[v] = first[v + 1] > first[v];
    std::vector<uint64_t> interior_edges;
    for (const auto& [e, use] : edges) {
        if (use.faces == 2) {
            interior_edges.push_back(e);
        } else {
            vertex_ok[e >> 32] = 0;
            vertex_ok[e & 0xffffffffu] = 0;
        }
    }
    std::sort(interior_edges.begin(), interior_edges.end());  // hash order is not portable
    std::vector<uint32_t> interior_vertices;
    for (uint32_t v = 0; v < vertex_ok.size(); ++v) {
        if (vertex_ok[v]) interior_vertices.push_back(v);
    }
    AimedRays out;
    if (interior_vertices.empty() || interior_edges.empty()) return out;

    const Bounds3f b = mesh.bounds();
    const Vec3f c = b.center();
    const float radius = glm::length(b.extent());
    auto from_sphere = [&](uint64_t i) {
        const float z = 2.0f * hash_uniform(seed, 0xa1, i, 0) - 1.0f;
        const float phi = 2.0f * kPi * hash_uniform(seed, 0xa1, i, 1);
        const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
        return c + radius * Vec3f(r * std::cos(phi), r * std::sin(phi), z);
    };
    auto dpos = [&](uint32_t v) { return Vec3d(mesh.positions[v]); };
    // Winding number of the fan around v, projected along dir (double precision).
    auto surrounded = [&](uint32_t v, const Vec3d& dir) {
        const Vec3d n = glm::normalize(dir);
        const Vec3d u = glm::normalize(std::fabs(n.x) > 0.5 ? glm::cross(n, Vec3d(0, 1, 0))
                                                            : glm::cross(n, Vec3d(1, 0, 0)));
        const Vec3d w = glm::cross(n, u);
        double angle = 0.0;
        for (uint32_t k = first[v]; k < first[v + 1]; ++k) {
            const Vec3u& t = mesh.triangles[incident[k]];
            const int at = t.x == v ? 0 : (t.y == v ? 1 : 2);
            const Vec3d pa = dpos(t[(at + 1) % 3]) - dpos(v), pb = dpos(t[(at + 2) % 3]) - dpos(v);
            const double ax = glm::dot(pa, u), ay = glm::dot(pa, w);
            const double bx = glm::dot(pb, u), by = glm::dot(pb, w);
            angle += std::atan2(ax * by - ay * bx, ax * bx + ay * by);
        }
        return std::fabs(angle) > kPi;  // winding +-1 (2 pi) versus 0 on the silhouette
    };
    auto edge_crossed = [&](uint64_t e, const Vec3d& dir) {
        const uint32_t a = uint32_t(e >> 32), bb = uint32_t(e & 0xffffffffu);
        const EdgeUse& use = edges.at(e);
        const Vec3d ab = dpos(bb) - dpos(a);
        const double s1 = glm::dot(glm::cross(ab, dpos(use.opposite[0]) - dpos(a)), dir);
        const double s2 = glm::dot(glm::cross(ab, dpos(use.opposite[1]) - dpos(a)), dir);
        return s1 * s2 < 0.0;  // the two triangles lie on both sides of the edge, seen along dir
    };
    const uint64_t max_attempts = uint64_t(count) * 20;
    for (uint64_t i = 0; i < max_attempts && out.vertex.size() < size_t(count); ++i) {
        const float pick = hash_uniform(seed, 0xa2, i, 0);
        const uint32_t v = interior_vertices[std::min(
            interior_vertices.size() - 1, size_t(pick * float(interior_vertices.size())))];
        Ray r;
        r.origin = from_sphere(i);
        r.dir = mesh.positions[v] - r.origin;  // t = 1 at the vertex
        if (surrounded(v, Vec3d(r.dir))) out.vertex.push_back(r);
    }
    for (uint64_t i = 0; i < max_attempts && out.edge.size() < size_t(count); ++i) {
        const float pick = hash_uniform(seed, 0xa3, i, 0);
        const uint64_t e = interior_edges[std::min(interior_edges.size() - 1,
                                                   size_t(pick * float(interior_edges.size())))];
        const Vec3f m = 0.5f * (mesh.positions[e >> 32] + mesh.positions[e & 0xffffffffu]);
        Ray r;
        r.origin = from_sphere(i + 0x100000000ull);
        r.dir = m - r.origin;
        if (edge_crossed(e, Vec3d(r.dir))) out.edge.push_back(r);
    }
    return out;
}

// A ray aimed at a point at t = 1 escapes when it misses or hits behind the point.
bool escaped(const Hit& hit) { return !hit.valid() || hit.t > 1.0f + 1e-4f; }

uint64_t count_escapes(const std::vector<Hit>& hits) {
    return uint64_t(std::count_if(hits.begin(), hits.end(), escaped));
}

// Of the escapes among the first `cap`, how many the same watertight test run on every
// triangle (brute_force_hit) also has: those rays truly pass the aimed point by a rounding
// error (a fan seen almost edge-on), the rest would be holes in the tree. `memo` keeps each
// ray's brute-force verdict (-1 unknown, 0 hits, 1 escapes), so engines that share escapes
// test them once. Returns (escapes checked, escapes brute force shares).
std::pair<uint64_t, uint64_t> brute_force_escapes(const TriangleMesh& mesh,
                                                  const std::vector<Ray>& rays,
                                                  const std::vector<Hit>& hits, size_t cap,
                                                  std::vector<int8_t>& memo) {
    memo.resize(rays.size(), -1);
    std::vector<size_t> todo, checked;
    for (size_t i = 0; i < rays.size() && checked.size() < cap; ++i) {
        if (!escaped(hits[i])) continue;
        checked.push_back(i);
        if (memo[i] < 0) todo.push_back(i);
    }
#pragma omp parallel for schedule(dynamic, 1)
    for (size_t k = 0; k < todo.size(); ++k) {
        memo[todo[k]] = int8_t(escaped(brute_force_hit(mesh, rays[todo[k]])));
    }
    uint64_t shared = 0;
    for (size_t i : checked) shared += uint64_t(memo[i]);
    return {checked.size(), shared};
}

/// NaN/Inf rays: copies of `rays` with one component of origin or direction made NaN or
/// +-infinity (cycling through the kinds).
std::vector<Ray> make_nonfinite_rays(const std::vector<Ray>& rays) {
    const float bad[3] = {std::nanf(""), kInfinity, -kInfinity};
    std::vector<Ray> out(rays);
    for (size_t i = 0; i < out.size(); ++i) {
        const float v = bad[i % 3];
        const int comp = int((i / 3) % 3);
        if ((i / 9) % 2 == 0) {
            out[i].dir[comp] = v;
        } else {
            out[i].origin[comp] = v;
        }
    }
    return out;
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
    std::ofstream out(path, std::ios::binary);
    out << "P5\n" << w << " " << h << "\n255\n";
    out.write(reinterpret_cast<const char*>(img.data()), std::streamsize(img.size()));
    if (!out) throw Error(ErrorLocation{path}, "cannot write image");
}

// Where a ray's traversal work goes: the single-ray query's steps (traversal.cpp's descend,
// leaf test and pop, same decisions and slack), replayed with finer counts. The totals are
// checked against the query's own counters, so the split describes the real traversal.
struct RayAnatomy {
    uint64_t first_descent = 0;  ///< inner nodes visited before the first leaf
    uint64_t first_leaf_tests = 0;
    uint64_t leaves = 0;            ///< leaves entered
    uint64_t empty_skipped = 0;     ///< empty children the descent decided not to enter
    uint64_t nodes = 0, tests = 0;  ///< totals, as TraversalCounters count them
};

void add_anatomy(const KdTree& tree, const Ray& ray, RayAnatomy& a) {
    using detail::lower_slack;
    using detail::upper_slack;
    detail::RayState rs;
    float t0, t1, best_t;
    if (!detail::setup_ray(ray, tree.bounds(), rs, t0, t1, best_t)) return;
    const TriangleMesh& mesh = tree.mesh();
    const std::vector<KdNode>& nodes = tree.nodes();
    struct Item {
        uint32_t node;
        float t0, t1;
    };
    Item stack[detail::kStackSize];
    int sp = 0;
    uint32_t idx = 0;
    bool first = true;
    for (;;) {
        KdNode node = nodes[idx];
        ++a.nodes;
        bool skipped = false;
        while (!node.is_leaf()) {
            if (first) ++a.first_descent;
            const int axis = node.axis();
            const float ts = (node.split - rs.org[axis]) * rs.inv[axis];
            const uint32_t near_child = node.child() + rs.neg(axis);
            const uint32_t far_child = node.child() + 1u - rs.neg(axis);
            const bool visit_near = !(ts < lower_slack(t0));
            const bool visit_far = !(ts > upper_slack(t1));
            // The flags in the node's word, as the descent reads them.
            const bool near_empty = (node.empty_children() >> rs.neg(axis)) & 1u;
            const bool far_empty = (node.empty_children() >> (1u - rs.neg(axis))) & 1u;
            a.empty_skipped +=
                uint64_t(visit_near && near_empty) + uint64_t(visit_far && far_empty);
            const bool go_near = visit_near && !near_empty, go_far = visit_far && !far_empty;
            const float far_t0 = ts > t0 ? ts : t0;
            if (go_near && go_far) stack[sp++] = {far_child, far_t0, t1};
            if (go_near) {
                t1 = ts < t1 ? ts : t1;
                idx = near_child;
            } else if (go_far) {
                t0 = far_t0;
                idx = far_child;
            } else {
                node = KdNode{};  // no child to enter: straight to the stack
                skipped = true;
                break;
            }
            node = nodes[idx];
            ++a.nodes;
        }
        if (!skipped) ++a.leaves;
        for (uint32_t i = 0; i < node.count(); ++i) {
            const Vec3u t = mesh.triangles[tree.indices()[node.first + i]];
            float tt, u, v;
            if (intersect_triangle(rs.wr, mesh.positions[t.x], mesh.positions[t.y],
                                   mesh.positions[t.z], rs.tmin, best_t, tt, u, v))
                best_t = tt;
        }
        a.tests += node.count();
        if (first) a.first_leaf_tests += node.count();
        first = false;
        bool next = false;
        while (sp > 0 && !next) {
            const Item& s = stack[--sp];
            if (lower_slack(s.t0) <= best_t) {
                idx = s.node;
                t0 = s.t0;
                t1 = std::min(s.t1, best_t);
                next = true;
            }
        }
        if (!next) break;
    }
}

void run(const Options& opt) {
    const int threads = opt.threads > 0 ? opt.threads : omp_get_max_threads();
    const int repeat = std::max(1, opt.repeat);
    const std::string model = opt.model.empty() ? default_model() : opt.model;
    const std::string views_path = opt.views.empty() ? find_asset("views/dragon.json") : opt.views;
    ViewSet views = load_views(views_path);
    if (opt.spp > 0) views.samples_per_pixel = opt.spp;

    // Which rows.
    std::vector<Config> configs;
    {
        const std::vector<Config> all = table_configs();
        std::stringstream ss(opt.rows);
        std::string id;
        while (std::getline(ss, id, ',')) {
            auto it =
                std::find_if(all.begin(), all.end(), [&](const Config& c) { return c.id == id; });
            if (it == all.end()) {
                throw Error(ErrorLocation{"--rows"}, "unknown row '" + id + "' (1-7 or sah)");
            }
            configs.push_back(*it);
        }
        if (configs.empty()) throw Error(ErrorLocation{"--rows"}, "no rows selected");
    }

    std::fprintf(stderr, "loading %s\n", model.c_str());
    MeshLoadInfo info;
    auto mesh_rw = std::make_shared<TriangleMesh>(load_mesh(model, {}, &info));
    mesh_rw->normals.clear();
    mesh_rw->colors.clear();
    std::string model_key = model;
    if (opt.subdivide > 0) {
        *mesh_rw = subdivide_mesh(*mesh_rw, opt.subdivide);
        model_key += ".sub" + std::to_string(opt.subdivide);
    }
    // The renderer's spatial triangle order (compile_snapshot), for every engine alike.
    apply_order(*mesh_rw, spatial_order(*mesh_rw));
    std::shared_ptr<const TriangleMesh> mesh = mesh_rw;
    const double tris = double(mesh->triangle_count());
    std::fprintf(stderr, "%zu triangles; %d threads; %d repeats; %zu views of %dx%d x %d spp\n",
                 mesh->triangle_count(), threads, repeat, views.views.size(), views.width,
                 views.height, views.samples_per_pixel);

    std::vector<ViewRays> view_rays;
    for (size_t v = 0; v < views.views.size(); ++v) {
        view_rays.push_back({views.views[v].name, make_primary_rays(views, v), {}, 0});
    }
    uint64_t total_primary = 0;
    for (const auto& vr : view_rays) total_primary += vr.rays.size();

    // ---- table 6.1 ----
    // Every row's tree is built first. Then each repeat times every row in turn (rows
    // interleaved, as the engines of the Embree table are), so drift on this shared machine
    // hits all rows alike instead of favouring whichever row ran in a quiet minute.
    std::vector<RowResult> results;
    for (const Config& cfg : configs) {
        RowResult r;
        r.config = cfg;
        KdTreeParams params = cfg.params;
        params.threads = threads;
        if (params.builder == KdBuilder::thesis) {
            if (opt.depth > 0) params.max_depth = opt.depth;
            if (opt.n0 >= 0) params.n0 = opt.n0;
        } else {
            if (opt.sah_traversal_cost > 0.0f) params.traversal_cost = opt.sah_traversal_cost;
            if (opt.sah_intersect_cost > 0.0f) params.intersect_cost = opt.sah_intersect_cost;
            if (opt.sah_empty_bonus >= 0.0f) params.empty_bonus = opt.sah_empty_bonus;
            if (opt.sah_depth > 0) params.max_depth = opt.sah_depth;
        }
        r.config.params = params;
        std::vector<double> builds;
        if (opt.use_cache) {
            r.tree = get_or_build_kdtree(model_key, mesh, params);
            builds.push_back(r.tree->stats().build_seconds);
        } else {
            for (int k = 0; k < repeat; ++k) {
                r.tree.reset();
                const size_t rss0 = current_rss_bytes();
                reset_peak_rss();
                Timer t;
                r.tree = build_kdtree(mesh, params);
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
                opt.leaf_vertex_indices == "on" ? LeafVertexIndices::always
                                                : LeafVertexIndices::never);
        }
        std::fprintf(stderr, "row %s: build %.3f s, %.1f bytes/triangle\n", cfg.id.c_str(),
                     r.build_seconds, double(tree_size(*r.tree).bytes) / tris);
        results.push_back(std::move(r));
    }

    // The first row's hits are the reference; the one-bounce diffuse rays start from them.
    std::vector<Ray> primary;
    std::vector<Hit> primary_hits;
    primary.reserve(total_primary);
    for (ViewRays& vr : view_rays) {
        const KdTree& tree = *results[0].tree;
        trace_closest(vr.rays, vr.reference, threads,
                      [&](const Ray& ray, Hit& h) { tree.intersect(ray, h); });
        if (!opt.save_views.empty()) {
            save_view_image(opt.save_views + "/view_" + vr.name + ".pgm", views, *mesh, vr.rays,
                            vr.reference);
        }
        vr.hits = uint64_t(std::count_if(vr.reference.begin(), vr.reference.end(),
                                         [](const Hit& h) { return h.valid(); }));
        primary.insert(primary.end(), vr.rays.begin(), vr.rays.end());
        primary_hits.insert(primary_hits.end(), vr.reference.begin(), vr.reference.end());
    }
    std::vector<uint32_t> diffuse_sources;
    const std::vector<Ray> diffuse =
        make_diffuse_rays(*mesh, primary, primary_hits, views.seed, &diffuse_sources);
    std::vector<Hit> diffuse_reference;
    trace_closest(diffuse, diffuse_reference, threads,
                  [&](const Ray& ray, Hit& h) { results[0].tree->intersect(ray, h); });
    primary_hits.clear();
    primary_hits.shrink_to_fit();

    std::vector<std::vector<std::vector<double>>> view_times(
        results.size(), std::vector<std::vector<double>>(view_rays.size()));
    std::vector<std::vector<double>> diffuse_times(results.size());
    for (int k = 0; k < repeat; ++k) {
        for (size_t ri = 0; ri < results.size(); ++ri) {
            RowResult& r = results[ri];
            const KdTree& tree = *r.tree;
            auto isect = [&](const Ray& ray, Hit& h) { tree.intersect(ray, h); };
            std::vector<Hit> hits;
            for (size_t v = 0; v < view_rays.size(); ++v) {
                view_times[ri][v].push_back(trace_closest(view_rays[v].rays, hits, threads, isect));
                if (k == 0 && ri > 0)
                    r.disagreements += count_disagreements(view_rays[v].reference, hits);
            }
            diffuse_times[ri].push_back(trace_closest(diffuse, hits, threads, isect));
            if (k == 0 && ri > 0)
                r.diffuse_disagreements = count_disagreements(diffuse_reference, hits);
        }
    }
    for (size_t ri = 0; ri < results.size(); ++ri) {
        RowResult& r = results[ri];
        double total = 0.0;
        for (const std::vector<double>& times : view_times[ri]) {
            r.view_seconds.push_back(median(times));
            total += r.view_seconds.back();
        }
        r.mrays = double(total_primary) / total * 1e-6;
        r.diffuse_mrays = double(diffuse.size()) / median(diffuse_times[ri]) * 1e-6;
        // The work per ray does not depend on the machine's load: one untimed counted pass.
        r.primary_work = count_work(*r.tree, primary, threads);
        r.diffuse_work = count_work(*r.tree, diffuse, threads);
        std::fprintf(stderr,
                     "row %s: %.2f primary / %.2f diffuse Mrays/s; per diffuse ray %.1f nodes, "
                     "%.1f triangle tests\n",
                     r.config.id.c_str(), r.mrays, r.diffuse_mrays, r.diffuse_work.nodes,
                     r.diffuse_work.tests);
    }

    Table t1;
    t1.name = "kdtree";
    t1.title = "Thesis table 6.1 on " + fs::path(model).filename().string() + " (" +
               std::to_string(mesh->triangle_count()) + " triangles), " +
               std::to_string(views.width) + "x" + std::to_string(views.height) + ", " +
               std::to_string(views.samples_per_pixel) + " jittered primary rays per pixel, " +
               std::to_string(threads) + " threads, medians of " + std::to_string(repeat);
    t1.header = {"row", "builder", "q", "n0", "depth", "size KB", "build s"};
    for (const auto& v : views.views) t1.header.push_back(v.name + " s");
    for (const std::string& h :
         {std::string("median"), std::string("center"), std::string("cut-off"), std::string("sah"),
          std::string("Mrays/s"), std::string("nodes / ray"), std::string("tests / ray"),
          std::string("diffuse Mrays/s"), std::string("nodes / diffuse ray"),
          std::string("tests / diffuse ray"), std::string("nodes"), std::string("leaves"),
          std::string("refs/tri"), std::string("leaf vertex indices"), std::string("bytes/tri"),
          std::string("peak build MB"), std::string("RSS build MB"),
          "hit diffs vs row " + configs[0].id + " (primary / diffuse)", std::string("remark")}) {
        t1.header.push_back(h);
    }
    for (const RowResult& r : results) {
        const KdTreeStats& s = r.tree->stats();
        const KdTreeParams& p = r.config.params;
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
        row.push_back(opt.use_cache ? "-" : fmt("%.1f", r.rss_build_mb));
        row.push_back(&r == &results[0] ? "-"
                                        : std::to_string(r.disagreements) + " / " +
                                              std::to_string(r.diffuse_disagreements));
        std::string remark = r.config.remark;
        const KdTreeParams& rp = r.config.params;
        if (rp.builder == KdBuilder::sah)
            remark += fmt(", costs: traversal %g", rp.traversal_cost) +
                      fmt(", intersection %g", rp.intersect_cost) +
                      fmt(", empty bonus %g", rp.empty_bonus);
        row.push_back(remark);
        t1.rows.push_back(std::move(row));
    }
    std::vector<Table> tables = {t1};

    // ---- our best tree against Embree, same rays, same threads ----
    const RowResult* best = &results[0];
    for (const RowResult& r : results) {
        if (r.mrays > best->mrays) best = &r;
    }
    const KdTree& tree = *best->tree;
    view_rays.clear();
    view_rays.shrink_to_fit();
    diffuse_reference.clear();
    diffuse_reference.shrink_to_fit();

    struct Engine {
        std::string name;
        const KdTree* tree = nullptr;
#ifdef KDT_HAVE_EMBREE
        const EmbreePeer* peer = nullptr;
#endif
        bool batch = false;  ///< batch queries (ours) / rtcIntersect1M streams (Embree)
        /// Ours, with paths: primary rays record the path to their hit's leaf, and each
        /// diffuse ray starts from the path of the primary hit it leaves from.
        bool from_leaf = false;
        double build_seconds = 0.0, bytes_per_triangle = 0.0, peak_mb = 0.0;
        std::vector<double> primary_s, diffuse_s, shadow_s;
        std::vector<Hit> primary_hits, diffuse_hits;
        uint64_t diffuse_occluded = 0;
    };
    std::vector<Engine> engines;
    {
        Engine ours;
        ours.name = "kdtrace row " + best->config.id + " (" +
                    kKdBuilderNames[size_t(best->config.params.builder)] + ")";
        ours.tree = &tree;
        ours.build_seconds = best->build_seconds;
        ours.bytes_per_triangle = double(tree_size(tree).bytes) / tris;
        ours.peak_mb = double(tree.stats().peak_build_bytes) / (1024.0 * 1024.0);
        Engine ours_batch = ours;
        ours_batch.name += ", batch";
        ours_batch.batch = true;
        Engine ours_from_leaf = ours;
        ours_from_leaf.name += ", from the hit's leaf";
        ours_from_leaf.from_leaf = true;
        engines.push_back(std::move(ours));
        engines.push_back(std::move(ours_batch));
        engines.push_back(std::move(ours_from_leaf));
    }
#ifdef KDT_HAVE_EMBREE
    std::vector<std::unique_ptr<EmbreePeer>> peers;
    if (opt.embree) {
        for (bool robust : {false, true}) {
            if (robust && !opt.embree_robust) continue;
            EmbreePeerParams ep;
            ep.threads = threads;
            ep.robust = robust;
            std::vector<double> builds;
            std::unique_ptr<EmbreePeer> peer;
            for (int k = 0; k < repeat; ++k) {
                peer.reset();
                peer = std::make_unique<EmbreePeer>(*mesh, ep);
                builds.push_back(peer->build_seconds());
            }
            const EmbreePeer* p = peer.get();
            Engine e;
            e.name = robust ? "Embree 3 (robust)" : "Embree 3";
            e.peer = p;
            e.build_seconds = median(builds);
            e.bytes_per_triangle = double(p->bvh_bytes()) / tris;
            e.peak_mb = double(p->peak_build_bytes()) / (1024.0 * 1024.0);
            peers.push_back(std::move(peer));
            Engine stream = e;
            stream.name += robust ? ", rtcIntersect1M" : " rtcIntersect1M";
            stream.batch = true;
            engines.push_back(std::move(e));
            engines.push_back(std::move(stream));
        }
    }
#endif
    // Calls body(intersect, occluded) with the engine's queries as concrete (inlinable)
    // lambdas: no std::function between the timing loop and either engine.
    auto with_queries = [](const Engine& e, const auto& body) {
#ifdef KDT_HAVE_EMBREE
        if (e.peer) {
            const EmbreePeer* p = e.peer;
            body([p](const Ray& r, Hit& h) { p->intersect(r, h); },
                 [p](const Ray& r) { return p->occluded(r); });
            return;
        }
#endif
        const KdTree* t = e.tree;
        body([t](const Ray& r, Hit& h) { t->intersect(r, h); },
             [t](const Ray& r) { return t->occluded(r); });
    };
    // Batch queries: (coherent closest, incoherent closest, incoherent any-hit) per chunk.
    auto with_batch_queries = [](const Engine& e, const auto& body) {
#ifdef KDT_HAVE_EMBREE
        if (e.peer) {
            const EmbreePeer* p = e.peer;
            body([p](const Ray* r, size_t n, Hit* h) { p->intersect(r, n, h, true); },
                 [p](const Ray* r, size_t n, Hit* h) { p->intersect(r, n, h, false); },
                 [p](const Ray* r, size_t n, uint8_t* o) { p->occluded(r, n, o, false); });
            return;
        }
#endif
        const KdTree* t = e.tree;
        auto isect = [t](const Ray* r, size_t n, Hit* h) { t->intersect(r, n, h); };
        body(isect, isect, [t](const Ray* r, size_t n, uint8_t* o) { t->occluded(r, n, o); });
    };
    // The path of each diffuse ray's primary hit in our tree, as a path tracer keeps it from
    // one bounce to the next: leaf_paths[leaf_first[i], leaf_first[i + 1]).
    std::vector<uint32_t> leaf_paths;
    std::vector<uint64_t> leaf_first(1, 0);
    leaf_first.reserve(diffuse.size() + 1);
    for (uint32_t src : diffuse_sources) {
        Hit h;
        KdPath path;
        tree.intersect(primary[src], h, path);
        leaf_paths.insert(leaf_paths.end(), path.nodes, path.nodes + path.length);
        leaf_first.push_back(leaf_paths.size());
    }
    diffuse_sources.clear();
    diffuse_sources.shrink_to_fit();
    auto start_of = [&](const Ray& r) {
        const size_t i = size_t(&r - diffuse.data());  // the ray's index in `diffuse`
        return std::make_pair(leaf_paths.data() + leaf_first[i],
                              uint32_t(leaf_first[i + 1] - leaf_first[i]));
    };
    // Interleave engines within each repeat so drift (thermal, other load) hits all alike.
    for (int k = 0; k < repeat; ++k) {
        for (Engine& e : engines) {
            if (e.from_leaf) {
                const KdTree* t = e.tree;
                e.primary_s.push_back(
                    trace_closest(primary, e.primary_hits, threads, [t](const Ray& r, Hit& h) {
                        KdPath path;
                        t->intersect(r, h, path);
                    }));
                e.diffuse_s.push_back(
                    trace_closest(diffuse, e.diffuse_hits, threads, [&](const Ray& r, Hit& h) {
                        const auto [start, length] = start_of(r);
                        t->intersect_from(start, length, r, h);
                    }));
                e.shadow_s.push_back(trace_occluded(
                    diffuse, threads,
                    [&](const Ray& r) {
                        const auto [start, length] = start_of(r);
                        return t->occluded_from(start, length, r);
                    },
                    &e.diffuse_occluded));
                continue;
            }
            if (e.batch) {
                with_batch_queries(
                    e, [&](const auto& coherent, const auto& incoherent, const auto& occ) {
                        e.primary_s.push_back(
                            trace_closest_batch(primary, e.primary_hits, threads, coherent));
                        e.diffuse_s.push_back(
                            trace_closest_batch(diffuse, e.diffuse_hits, threads, incoherent));
                        e.shadow_s.push_back(
                            trace_occluded_batch(diffuse, threads, occ, &e.diffuse_occluded));
                    });
                continue;
            }
            with_queries(e, [&](const auto& isect, const auto& occ) {
                e.primary_s.push_back(trace_closest(primary, e.primary_hits, threads, isect));
                e.diffuse_s.push_back(trace_closest(diffuse, e.diffuse_hits, threads, isect));
                e.shadow_s.push_back(trace_occluded(diffuse, threads, occ, &e.diffuse_occluded));
            });
        }
    }
    Table t2;
    t2.name = "embree";
    t2.title = "Best tree (row " + best->config.id +
               ") against Embree (single rays: rtcIntersect1/rtcOccluded1; batch: "
               "rtcIntersect1M/rtcOccluded1M, ratios against single-ray Embree): " +
               std::to_string(primary.size()) + " primary rays, " + std::to_string(diffuse.size()) +
               " one-bounce diffuse rays, " + std::to_string(threads) + " threads, medians of " +
               std::to_string(repeat);
    t2.header = {"engine",
                 "build s",
                 "bytes/tri",
                 "peak build MB",
                 "primary Mrays/s",
                 "diffuse Mrays/s",
                 "diffuse occluded Mrays/s",
                 "primary x Embree",
                 "diffuse x Embree",
                 "occluded x Embree",
                 "primary hit diffs",
                 "diffuse hit diffs"};
    const Engine* ref = nullptr;
    for (const Engine& e : engines) {
#ifdef KDT_HAVE_EMBREE
        if (e.peer && !e.batch) {
            ref = &e;
            break;
        }
#endif
    }
    auto mr = [](size_t n, double s) { return double(n) / s * 1e-6; };
    for (const Engine& e : engines) {
        const double p = mr(primary.size(), median(e.primary_s));
        const double d = mr(diffuse.size(), median(e.diffuse_s));
        const double o = mr(diffuse.size(), median(e.shadow_s));
        std::vector<std::string> row = {e.name,
                                        fmt("%.3f", e.build_seconds),
                                        fmt("%.1f", e.bytes_per_triangle),
                                        fmt("%.1f", e.peak_mb),
                                        fmt("%.2f", p),
                                        fmt("%.2f", d),
                                        fmt("%.2f", o)};
        if (ref) {
            row.push_back(fmt("%.2f", p / mr(primary.size(), median(ref->primary_s))));
            row.push_back(fmt("%.2f", d / mr(diffuse.size(), median(ref->diffuse_s))));
            row.push_back(fmt("%.2f", o / mr(diffuse.size(), median(ref->shadow_s))));
            row.push_back(std::to_string(count_disagreements(e.primary_hits, ref->primary_hits)));
            row.push_back(std::to_string(count_disagreements(e.diffuse_hits, ref->diffuse_hits)));
        } else {
            row.insert(row.end(), {"-", "-", "-", "-", "-"});
        }
        t2.rows.push_back(std::move(row));
    }
    tables.push_back(t2);

    // ---- where our traversal time goes: work per ray from the compiled-in counters ----
    {
        Table tc;
        tc.name = "cost";
        tc.title = "Work per ray of the best tree (row " + best->config.id +
                   "), from the traversal counters (one extra untimed pass)";
        tc.header = {"rays",
                     "nodes visited / ray",
                     "triangles tested / ray",
                     "hit %",
                     "ns / ray (1 thread equiv.)",
                     "ns / node visited",
                     "inner nodes before the first leaf",
                     "tests in the first leaf",
                     "leaves / ray",
                     "empty leaves skipped / ray"};
        // One counted pass per ray set (the batch queries visit exactly the same nodes per
        // ray, counted per lane, so their rows share it); from the hit's leaf, the walked
        // path's nodes count as visited and there is no first descent to replay.
        struct Counted {
            TraversalCounters c;
            RayAnatomy a;
            uint64_t hits = 0;
            size_t rays = 0;
            bool anatomy = false;
        };
        auto count = [&](const std::vector<Ray>& rays, bool from_leaf) {
            Counted w;
            w.rays = rays.size();
            w.anatomy = !from_leaf;
            for (const Ray& r : rays) {
                Hit h;
                if (from_leaf) {
                    const auto [start, length] = start_of(r);
                    w.hits += tree.intersect_from(start, length, r, h, nullptr, &w.c);
                } else {
                    w.hits += tree.intersect(r, h, &w.c);
                    add_anatomy(tree, r, w.a);
                }
            }
            if (w.anatomy && (w.a.nodes != w.c.nodes_visited || w.a.tests != w.c.triangles_tested))
                throw Error(ErrorLocation{"bench kdtree"},
                            "internal: the ray anatomy replay disagrees with the traversal "
                            "counters (" +
                                std::to_string(w.a.nodes) + " / " + std::to_string(w.a.tests) +
                                " against " + std::to_string(w.c.nodes_visited) + " / " +
                                std::to_string(w.c.triangles_tested) + ")");
            return w;
        };
        auto add = [&](const char* name, const Counted& w, double seconds) {
            const double n = double(std::max<size_t>(w.rays, 1));
            const double ns = seconds * double(threads) / n * 1e9;
            const double nodes = double(w.c.nodes_visited) / n;
            auto per_ray = [&](uint64_t v) { return w.anatomy ? fmt("%.1f", double(v) / n) : "-"; };
            tc.rows.push_back(
                {name, fmt("%.1f", nodes), fmt("%.1f", double(w.c.triangles_tested) / n),
                 fmt("%.1f", 100.0 * double(w.hits) / n), fmt("%.0f", ns),
                 fmt("%.2f", nodes > 0.0 ? ns / nodes : 0.0), per_ray(w.a.first_descent),
                 per_ray(w.a.first_leaf_tests), per_ray(w.a.leaves), per_ray(w.a.empty_skipped)});
        };
        const Counted cp = count(primary, false), cd = count(diffuse, false);
        add("primary", cp, median(engines[0].primary_s));
        add("diffuse", cd, median(engines[0].diffuse_s));
        add("primary, batch", cp, median(engines[1].primary_s));
        add("diffuse, batch", cd, median(engines[1].diffuse_s));
        add("diffuse, from the hit's leaf", count(diffuse, true), median(engines[2].diffuse_s));
        tables.push_back(tc);
    }

    // ---- robustness: aimed rays and NaN/Inf rays ----
    if (opt.robustness) {
        AimedRays aimed = make_aimed_rays(*mesh, opt.robust_rays, views.seed);
        // Normal rays for the NaN/Inf comparison: the first primary rays, same count.
        std::vector<Ray> normal(primary.begin(),
                                primary.begin() + std::min(primary.size(), size_t(1000000)));
        std::vector<Ray> nonfinite = make_nonfinite_rays(normal);
        Table t3;
        t3.name = "robustness";
        t3.title =
            "Robustness: " + std::to_string(aimed.vertex.size()) + " vertex-aimed and " +
            std::to_string(aimed.edge.size()) +
            " edge-aimed rays (closed fans, not on the silhouette; aimed point at t = 1; "
            "escape = miss or hit beyond it), NaN/Inf rays against as many normal primary rays";
        t3.header = {"engine",          "vertex escapes",
                     "vertex escape %", "edge escapes",
                     "edge escape %",   "normal ns/ray",
                     "NaN/Inf ns/ray",  "NaN/Inf slowdown",
                     "NaN/Inf hits",    "escapes brute force also has (vertex / edge)"};
        std::vector<int8_t> vertex_memo, edge_memo;  // brute-force verdicts, across engines
        for (Engine& e : engines) {
            if (e.from_leaf) continue;  // aimed rays leave from no hit
            std::vector<Hit> hv, he, hn;
            std::vector<double> tn, tb;
            // Debian's Embree is built with assertions: a NaN/Inf ray aborts in
            // BVHNIntersector1 (assert ray.valid()), so only kdtrace runs that set.
            const bool nonfinite_ok = e.tree != nullptr;
            if (e.batch) {
                with_batch_queries(
                    e, [&](const auto& coherent, const auto& incoherent, const auto&) {
                        trace_closest_batch(aimed.vertex, hv, threads, incoherent);
                        trace_closest_batch(aimed.edge, he, threads, incoherent);
                        for (int k = 0; k < repeat && nonfinite_ok; ++k) {
                            tn.push_back(trace_closest_batch(normal, hn, threads, coherent));
                            tb.push_back(trace_closest_batch(nonfinite, hn, threads, coherent));
                        }
                    });
            } else {
                with_queries(e, [&](const auto& isect, const auto&) {
                    trace_closest(aimed.vertex, hv, threads, isect);
                    trace_closest(aimed.edge, he, threads, isect);
                    for (int k = 0; k < repeat && nonfinite_ok; ++k) {
                        tn.push_back(trace_closest(normal, hn, threads, isect));
                        tb.push_back(trace_closest(nonfinite, hn, threads, isect));
                    }
                });
            }
            const uint64_t nonfinite_hits = uint64_t(
                std::count_if(hn.begin(), hn.end(), [](const Hit& h) { return h.valid(); }));
            const uint64_t ve = count_escapes(hv), ee = count_escapes(he);
            // Checked for kdtrace only (Embree escapes too many rays to test them all).
            std::string shared = "-";
            if (e.tree) {
                const size_t cap = 1000;
                const auto [vc, vs] =
                    brute_force_escapes(*mesh, aimed.vertex, hv, cap, vertex_memo);
                const auto [ec, es] = brute_force_escapes(*mesh, aimed.edge, he, cap, edge_memo);
                shared = std::to_string(vs) + " of " + std::to_string(vc) + " / " +
                         std::to_string(es) + " of " + std::to_string(ec);
            }
            const double ns_normal = median(tn) * 1e9 * threads / double(normal.size());
            const double ns_bad = median(tb) * 1e9 * threads / double(nonfinite.size());
            t3.rows.push_back(
                {e.name, std::to_string(ve),
                 fmt("%.3f", 100.0 * double(ve) / double(std::max<size_t>(1, aimed.vertex.size()))),
                 std::to_string(ee),
                 fmt("%.3f", 100.0 * double(ee) / double(std::max<size_t>(1, aimed.edge.size()))),
                 nonfinite_ok ? fmt("%.1f", ns_normal) : "-",
                 nonfinite_ok ? fmt("%.1f", ns_bad) : "n/a (asserts)",
                 nonfinite_ok ? fmt("%.2f", ns_bad / ns_normal) : "-",
                 nonfinite_ok ? std::to_string(nonfinite_hits) : "-", shared});
        }
        tables.push_back(t3);
    }

    // ---- output ----
    std::string md = "## kdtrace bench kdtree\n\nmodel " + model + " (" +
                     std::to_string(mesh->triangle_count()) + " triangles" +
                     (opt.subdivide ? ", subdivided " + std::to_string(opt.subdivide) + "x" : "") +
                     "), views " + views_path + "\n\n";
    for (const Table& t : tables) md += t.markdown() + "\n";
    md +=
        "Times are wall seconds to trace all rays of a view (closest hit, no shading); "
        "size KB counts nodes, leaf indices and, when the tree stores them within 32 bytes per "
        "triangle, each reference's vertex indices (the mesh is not included); peak build MB is "
        "the builder's own estimate, RSS build MB the measured growth of the peak RSS.\n";
    if (opt.md.empty()) {
        std::fputs(md.c_str(), stdout);
    } else {
        std::ofstream out(opt.md);
        out << md;
        if (!out) throw Error(ErrorLocation{opt.md}, "cannot write Markdown");
        std::fprintf(stderr, "wrote %s\n", opt.md.c_str());
    }
    if (!opt.csv.empty()) {
        std::ofstream out(opt.csv);
        for (const Table& t : tables) t.csv(out);
        if (!out) throw Error(ErrorLocation{opt.csv}, "cannot write CSV");
        std::fprintf(stderr, "wrote %s\n", opt.csv.c_str());
    }
}

}  // namespace

void add_bench_kdtree_command(CLI::App& bench) {
    auto* cmd = bench.add_subcommand(
        "kdtree", "Thesis table 6.1 on the dragon, the best tree against Embree, robustness");
    static Options opt;
    cmd->add_option("--model", opt.model,
                    "Model file (default: the fetched Stanford dragon, dragon_vrip.ply)");
    cmd->add_option("--views", opt.views, "Views file (default: assets/views/dragon.json)");
    cmd->add_option("--repeat", opt.repeat, "Repeats; medians are reported")
        ->capture_default_str()
        ->check(CLI::Range(1, 1000));
    cmd->add_option("--threads", opt.threads, "Threads for both engines, 0 = all")
        ->capture_default_str()
        ->check(CLI::Range(0, 1024));
    cmd->add_option("--subdivide", opt.subdivide, "Split every triangle into 4^K first")
        ->check(CLI::Range(0, 3));
    cmd->add_option("--rows", opt.rows, "Rows of table 6.1 to run (1-7, sah), comma-separated")
        ->capture_default_str();
    cmd->add_option("--depth", opt.depth,
                    "Thesis rows: maximum depth instead of 20 (the thesis's 10M-triangle table "
                    "uses 24)")
        ->check(CLI::Range(1, 64));
    cmd->add_option("--n0", opt.n0, "Thesis rows: n0 instead of 5 (the 10M table uses 4)")
        ->check(CLI::Range(0, 1000));
    cmd->add_option("--sah-traversal-cost", opt.sah_traversal_cost,
                    "SAH row: cost of an inner node relative to a triangle test (default 4)")
        ->check(CLI::Range(0.01f, 1000.0f));
    cmd->add_option("--sah-intersect-cost", opt.sah_intersect_cost,
                    "SAH row: cost of a triangle test (default 1)")
        ->check(CLI::Range(0.01f, 1000.0f));
    cmd->add_option("--sah-empty-bonus", opt.sah_empty_bonus,
                    "SAH row: cost reduction for cutting off empty space (default 0.2)")
        ->check(CLI::Range(0.0f, 1.0f));
    cmd->add_option("--sah-depth", opt.sah_depth,
                    "SAH row: maximum depth instead of the automatic 8 + 1.3 log2 N")
        ->check(CLI::Range(1, 64));
    cmd->add_option("--leaf-vertex-indices", opt.leaf_vertex_indices,
                    "Every row's trees store each leaf reference's vertex indices (on), or not "
                    "(off), instead of only within 32 bytes per triangle (auto): rows then "
                    "differ in time only by their splits")
        ->capture_default_str()
        ->check(CLI::IsMember({"auto", "on", "off"}));
    cmd->add_option("--spp", opt.spp, "Primary rays per pixel (default: the views file's)")
        ->check(CLI::Range(1, 4096));
    cmd->add_option("--csv", opt.csv, "Also write all tables as CSV");
    cmd->add_option("--md", opt.md, "Write the Markdown here instead of stdout");
    cmd->add_flag("!--no-embree", opt.embree, "Skip the Embree comparison");
    cmd->add_flag("--embree-robust", opt.embree_robust,
                  "Add an Embree row with RTC_SCENE_FLAG_ROBUST");
    cmd->add_flag("--use-cache", opt.use_cache,
                  "Take trees from the cache (build s = the cached build's time) instead of "
                  "building each row --repeat times");
    cmd->add_option("--save-views", opt.save_views,
                    "Write a PGM picture of each view's first-sample hits into this directory");
    cmd->add_flag("!--no-robustness", opt.robustness, "Skip the aimed and NaN/Inf ray table");
    cmd->add_option("--robust-rays", opt.robust_rays, "Vertex- and edge-aimed rays each")
        ->capture_default_str()
        ->check(CLI::Range(1, 100000000));
    cmd->callback([] { run(opt); });
}

}  // namespace kdt::app
