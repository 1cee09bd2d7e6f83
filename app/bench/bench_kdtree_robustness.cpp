// `kdtrace bench kdtree`: robustness. Rays aimed exactly at vertices and edge midpoints of
// closed fans (a watertight query must hit them), and rays with a NaN or infinite component
// timed against as many normal primary rays.
#include <algorithm>
#include <cmath>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "app/bench/bench_kdtree.h"
#include "app/bench/bench_rays.h"
#include "renderer/accel/brute_force.h"

namespace kdt::app::kdtree_bench {
namespace {

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

/// The rays one robustness row traces, and the brute-force verdicts the rows share.
struct RobustnessRays {
    AimedRays aimed;
    std::vector<Ray> normal, nonfinite;
    std::vector<int8_t> vertex_memo, edge_memo;
};

std::vector<std::string> robustness_row(const Context& ctx, const Engine& e, RobustnessRays& rays) {
    const int threads = ctx.threads;
    const AimedRays& aimed = rays.aimed;
    const std::vector<Ray>& normal = rays.normal;
    const std::vector<Ray>& nonfinite = rays.nonfinite;
    std::vector<Hit> hv, he, hn;
    std::vector<double> tn, tb;
    // Debian's Embree is built with assertions: a NaN/Inf ray aborts in
    // BVHNIntersector1 (assert ray.valid()), so only kdtrace runs that set.
    const bool nonfinite_ok = e.tree != nullptr;
    if (e.batch) {
        with_batch_queries(e, [&](const auto& coherent, const auto& incoherent, const auto&) {
            trace_closest_batch(aimed.vertex, hv, threads, incoherent);
            trace_closest_batch(aimed.edge, he, threads, incoherent);
            for (int k = 0; k < ctx.repeat && nonfinite_ok; ++k) {
                tn.push_back(trace_closest_batch(normal, hn, threads, coherent));
                tb.push_back(trace_closest_batch(nonfinite, hn, threads, coherent));
            }
        });
    } else {
        with_queries(e, [&](const auto& isect, const auto&) {
            trace_closest(aimed.vertex, hv, threads, isect);
            trace_closest(aimed.edge, he, threads, isect);
            for (int k = 0; k < ctx.repeat && nonfinite_ok; ++k) {
                tn.push_back(trace_closest(normal, hn, threads, isect));
                tb.push_back(trace_closest(nonfinite, hn, threads, isect));
            }
        });
    }
    const uint64_t nonfinite_hits =
        uint64_t(std::count_if(hn.begin(), hn.end(), [](const Hit& h) { return h.valid(); }));
    const uint64_t ve = count_escapes(hv), ee = count_escapes(he);
    // Checked for kdtrace only (Embree escapes too many rays to test them all).
    std::string shared = "-";
    if (e.tree) {
        const size_t cap = 1000;
        const TriangleMesh& mesh = *ctx.mesh;
        const auto [vc, vs] = brute_force_escapes(mesh, aimed.vertex, hv, cap, rays.vertex_memo);
        const auto [ec, es] = brute_force_escapes(mesh, aimed.edge, he, cap, rays.edge_memo);
        shared = std::to_string(vs) + " of " + std::to_string(vc) + " / " + std::to_string(es) +
                 " of " + std::to_string(ec);
    }
    const double ns_normal = quotient(median(tn) * 1e9 * threads, double(normal.size()));
    const double ns_bad = quotient(median(tb) * 1e9 * threads, double(nonfinite.size()));
    return {e.name,
            std::to_string(ve),
            fmt("%.3f", quotient(100.0 * double(ve), double(aimed.vertex.size()))),
            std::to_string(ee),
            fmt("%.3f", quotient(100.0 * double(ee), double(aimed.edge.size()))),
            nonfinite_ok ? fmt("%.1f", ns_normal) : "-",
            nonfinite_ok ? fmt("%.1f", ns_bad) : "n/a (asserts)",
            nonfinite_ok ? fmt("%.2f", quotient(ns_bad, ns_normal)) : "-",
            nonfinite_ok ? std::to_string(nonfinite_hits) : "-",
            shared};
}

}  // namespace

Table robustness_table(const Context& ctx, const std::vector<Ray>& primary,
                       const std::vector<Engine>& engines) {
    RobustnessRays rays;
    rays.aimed = make_aimed_rays(*ctx.mesh, ctx.opt.robust_rays, ctx.views.seed);
    // Normal rays for the NaN/Inf comparison: the first primary rays, same count.
    rays.normal.assign(primary.begin(),
                       primary.begin() + std::min(primary.size(), size_t(1000000)));
    rays.nonfinite = make_nonfinite_rays(rays.normal);
    Table t3;
    t3.name = "robustness";
    t3.title = "Robustness: " + std::to_string(rays.aimed.vertex.size()) + " vertex-aimed and " +
               std::to_string(rays.aimed.edge.size()) +
               " edge-aimed rays (closed fans, not on the silhouette; aimed point at t = 1; "
               "escape = miss or hit beyond it), NaN/Inf rays against as many normal primary rays";
    t3.header = {"engine",          "vertex escapes",
                 "vertex escape %", "edge escapes",
                 "edge escape %",   "normal ns/ray",
                 "NaN/Inf ns/ray",  "NaN/Inf slowdown",
                 "NaN/Inf hits",    "escapes brute force also has (vertex / edge)"};
    for (const Engine& e : engines) {
        if (e.from_leaf) continue;     // aimed rays leave from no hit
        if (e.stream_lanes) continue;  // the unit tests check streams on such rays, bitwise
        // Partitions likewise; tile-batch rows differ from their engine only in the diffuse
        // rays' order, which this table does not trace.
        if (e.partition_min_rays || e.tiled) continue;
        t3.rows.push_back(robustness_row(ctx, e, rays));
    }
    return t3;
}

}  // namespace kdt::app::kdtree_bench
