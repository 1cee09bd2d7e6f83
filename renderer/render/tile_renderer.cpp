#include "renderer/render/tile_renderer.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "renderer/integrator/wavefront.h"

namespace kdt {

Vec3f aov_shading_normal(const TraceScene& scene, const Ray& ray, const Hit& hit) {
    const TriangleMesh& mesh = *scene.mesh;
    const Vec3u tri = mesh.triangles[hit.prim];
    const Vec3f ng =
        triangle_normal(mesh.positions[tri.x], mesh.positions[tri.y], mesh.positions[tri.z]);
    Vec3f n = ng;
    if (scene.instances[scene.instance_of(hit.prim)].smooth && !scene.normals.empty()) {
        const float w = 1.0f - hit.u - hit.v;
        const Vec3f s =
            w * scene.normals[tri.x] + hit.u * scene.normals[tri.y] + hit.v * scene.normals[tri.z];
        const float len = glm::length(s);
        if (len > 0.0f && std::isfinite(len)) n = s / len;
    }
    if (n == Vec3f(0.0f)) return -ray.dir;  // a degenerate triangle
    return glm::dot(n, ray.dir) > 0.0f ? -n : n;
}

namespace {

// Hands one finished sample of pixel (x, y) to the film and the AOVs: its radiance L and its
// camera ray's hit. Non-finite or negative radiance is dropped and counted.
void add_sample(const TileTarget& t, int x, int y, const Ray& ray, const Hit& hit, Vec3f L,
                PathCounters& counters) {
    Film& film = *t.film;
    bool covered = true;
    if (t.transparent) {
        covered = hit.valid();
        if (!covered) L = Vec3f(0.0f);
    }
    const size_t pi = size_t(y) * size_t(film.width()) + size_t(x);
    if (t.aov_normal != nullptr && hit.valid()) {
        const Vec3f sn = aov_shading_normal(*t.scene, ray, hit);
        t.aov_normal[3 * pi] += sn.x;
        t.aov_normal[3 * pi + 1] += sn.y;
        t.aov_normal[3 * pi + 2] += sn.z;
        t.aov_depth[pi] += hit.t;
        ++t.aov_hits[pi];
    }
    if (is_finite(L) && L.x >= 0.0f && L.y >= 0.0f && L.z >= 0.0f) {
        film.add_sample(x, y, L);
        if (t.transparent) film.add_coverage(x, y, covered ? 1.0f : 0.0f);
    } else {
        film.skip_sample(x, y);
        ++counters.nonfinite_dropped;
    }
}

// Per-thread working memory of render_tile (grows to the largest chunk): the chunk's
// samples in order, their pixels and samplers, camera rays, hits and radiance.
struct TileScratch {
    std::vector<int> x, y;
    std::vector<PixelSampler> samplers;
    std::vector<Vec2f> u_film;
    std::vector<Ray> rays;
    std::vector<Hit> hits;
    std::vector<Vec3f> radiance;
    WavefrontScratch wavefront;
};

// Samples traced together at most: 16 samples per pass of a 16x16 tile. Larger passes are
// traced in chunks of this many, in order, so memory stays bounded.
constexpr size_t kMaxChunk = 4096;

// Traces the chunk of samples s.samplers (which have made no draw yet) and hands them to
// the film in order. The camera rays go to the kd-tree's batch query (each 8 in a row that
// are coherent, such as samples of one pixel or neighbouring pixels, as one packet, with
// exactly the hits of one query per ray), then the paths advance together through the
// wavefront (TraceParams::wavefront) or one at a time. A heat map needs each sample's own
// traversal counts: then each camera ray is traced on its own and each path one at a time.
void trace_chunk(const TileTarget& t, TileScratch& s, PathCounters& counters) {
    const TraceScene& scene = *t.scene;
    const TraceParams& trace = *t.trace;
    const bool heat = t.heat_nodes != nullptr;
    const size_t n = s.samplers.size();
    s.u_film.resize(n);
    s.rays.resize(n);
    s.hits.resize(n);
    s.radiance.resize(n);
    // The first draws, then the rays, in separate loops: the draws of different samples are
    // short independent chains the CPU overlaps.
    for (size_t i = 0; i < n; ++i) s.u_film[i] = s.samplers[i].next_2d();
    for (size_t i = 0; i < n; ++i)
        s.rays[i] = camera_ray(*t.camera, trace, s.x[i], s.y[i], s.u_film[i]);
    TraversalCounters tc;
    TraversalCounters* tcp = trace.count_traversal ? &tc : nullptr;
    if (!heat) scene.tree->intersect(s.rays.data(), n, s.hits.data(), tcp);
    counters.nodes_visited += tc.nodes_visited;
    counters.triangles_tested += tc.triangles_tested;
    if (!heat && trace.wavefront) {
        trace_camera_hits(scene, trace, s.rays.data(), s.hits.data(), s.samplers.data(), n,
                          s.radiance.data(), counters, s.wavefront);
    } else {
        for (size_t i = 0; i < n; ++i) {
            const uint64_t nodes0 = counters.nodes_visited, tris0 = counters.triangles_tested;
            if (heat) {
                TraversalCounters own;
                s.hits[i] = Hit{};
                scene.tree->intersect(s.rays[i], s.hits[i], trace.count_traversal ? &own : nullptr);
                counters.nodes_visited += own.nodes_visited;
                counters.triangles_tested += own.triangles_tested;
            }
            s.radiance[i] =
                trace_camera_hit(scene, trace, s.rays[i], s.hits[i], s.samplers[i], counters);
            if (heat) {
                const size_t pi = size_t(s.y[i]) * size_t(t.film->width()) + size_t(s.x[i]);
                t.heat_nodes[pi] += counters.nodes_visited - nodes0;
                t.heat_triangles[pi] += counters.triangles_tested - tris0;
            }
        }
    }
    for (size_t i = 0; i < n; ++i)
        add_sample(t, s.x[i], s.y[i], s.rays[i], s.hits[i], s.radiance[i], counters);
    s.x.clear();
    s.y.clear();
    s.samplers.clear();
}

}  // namespace

size_t render_tile(const TileTarget& t, const FilmRect& tile, PathCounters& counters) {
    const TraceParams& trace = *t.trace;
    const Film& film = *t.film;
    const int spp = std::max(trace.samples_per_pass, 1);
    thread_local TileScratch s;
    s.x.clear();
    s.y.clear();
    s.samplers.clear();
    size_t pixels_done = 0;
    for (int y = tile.y0; y < tile.y1; ++y) {
        for (int x = tile.x0; x < tile.x1; ++x) {
            if (!film.active(x, y)) continue;
            // Read once: a chunk traced in the middle of the pixel adds to its count.
            const uint32_t first_index = film.next_sample_index(x, y);
            const uint32_t end = std::min(t.max_spp, film.pass_end(x, y));
            const uint64_t key = PixelSampler::pixel_key(trace.seed, uint32_t(x), uint32_t(y));
            int k = 0;
            for (; k < spp && first_index + uint32_t(k) < end; ++k) {
                s.x.push_back(x);
                s.y.push_back(y);
                s.samplers.emplace_back(key, first_index + uint32_t(k));
                if (s.samplers.size() == kMaxChunk) trace_chunk(t, s, counters);
            }
            pixels_done += k > 0;
        }
    }
    if (!s.samplers.empty()) trace_chunk(t, s, counters);
    return pixels_done;
}

}  // namespace kdt
