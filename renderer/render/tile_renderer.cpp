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

// One sample of the tile pass: its pixel and its sampler (one draw made: the film position).
struct TileSample {
    PixelSampler sampler;
    Vec2f u_film{0.0f};
    int x = 0, y = 0;
};

// Per-thread working memory of the wavefront route (grows to the largest tile pass).
struct TileScratch {
    std::vector<TileSample> samples;
    std::vector<Ray> rays;
    std::vector<Hit> hits;
    std::vector<PixelSampler> samplers;
    std::vector<Vec3f> radiance;
    WavefrontScratch wavefront;
};

// Samples a wavefront takes at most: 16 samples per pass of a 16x16 tile. Larger passes
// are traced in chunks of this many, in order, so memory stays bounded.
constexpr size_t kMaxWavefront = 4096;

// Traces the samples s.samples (their samplers have made no draw yet) as one wavefront and
// hands them to the film in order.
void trace_wavefront(const TileTarget& t, TileScratch& s, PathCounters& counters) {
    const TraceScene& scene = *t.scene;
    const TraceParams& trace = *t.trace;
    const size_t n = s.samples.size();
    if (s.rays.size() < n) {
        s.rays.resize(n);
        s.hits.resize(n);
        s.samplers.resize(n);
        s.radiance.resize(n);
    }
    for (size_t i = 0; i < n; ++i) s.samples[i].u_film = s.samples[i].sampler.next_2d();
    for (size_t i = 0; i < n; ++i) {
        const TileSample& c = s.samples[i];
        s.rays[i] = camera_ray(*t.camera, trace, c.x, c.y, c.u_film);
        s.samplers[i] = c.sampler;
    }
    // Camera rays row by row to the batch query (8-ray packets of neighbouring samples).
    TraversalCounters tc;
    for (size_t i = 0; i < n;) {
        size_t e = i + 1;
        while (e < n && s.samples[e].y == s.samples[i].y) ++e;
        scene.tree->intersect(s.rays.data() + i, e - i, s.hits.data() + i,
                              trace.count_traversal ? &tc : nullptr);
        i = e;
    }
    counters.nodes_visited += tc.nodes_visited;
    counters.triangles_tested += tc.triangles_tested;
    trace_camera_hits(scene, trace, s.rays.data(), s.hits.data(), s.samplers.data(), n,
                      s.radiance.data(), counters, s.wavefront);
    for (size_t i = 0; i < n; ++i)
        add_sample(t, s.samples[i].x, s.samples[i].y, s.rays[i], s.hits[i], s.radiance[i],
                   counters);
    s.samples.clear();
}

// render_tile() through the wavefront (TraceParams::wavefront): the samples of the tile
// pass are made in pixel and sample order, their paths traced together (up to
// kMaxWavefront at a time), and the film takes them in that order. Without heat maps.
size_t render_tile_wavefront(const TileTarget& t, const FilmRect& tile, PathCounters& counters) {
    const TraceParams& trace = *t.trace;
    const Film& film = *t.film;
    const int spp = std::max(trace.samples_per_pass, 1);
    thread_local TileScratch s;
    s.samples.clear();
    size_t pixels_done = 0;
    for (int y = tile.y0; y < tile.y1; ++y) {
        for (int x = tile.x0; x < tile.x1; ++x) {
            if (!film.active(x, y)) continue;
            // Read once: a chunk traced in the middle of the pixel adds to its count.
            const uint32_t first_index = film.next_sample_index(x, y);
            const uint64_t key = PixelSampler::pixel_key(trace.seed, uint32_t(x), uint32_t(y));
            int k = 0;
            for (; k < spp && first_index + uint32_t(k) < t.max_spp; ++k) {
                TileSample& c = s.samples.emplace_back();
                c.sampler = PixelSampler(key, first_index + uint32_t(k));
                c.x = x;
                c.y = y;
                if (s.samples.size() == kMaxWavefront) trace_wavefront(t, s, counters);
            }
            pixels_done += k > 0;
        }
    }
    if (!s.samples.empty()) trace_wavefront(t, s, counters);
    return pixels_done;
}

}  // namespace

size_t render_tile(const TileTarget& t, const FilmRect& tile, PathCounters& counters) {
    if (t.trace->wavefront && t.heat_nodes == nullptr)
        return render_tile_wavefront(t, tile, counters);
    const TraceScene& scene = *t.scene;
    const Camera& camera = *t.camera;
    const TraceParams& trace = *t.trace;
    Film& film = *t.film;
    const int width = film.width();
    const int spp = std::max(trace.samples_per_pass, 1);
    const bool heat = t.heat_nodes != nullptr;
    size_t pixels_done = 0;
    // Camera rays are made for up to kBatch samples of a tile row (in pixel and sample
    // order) before they are traced, in separate loops for the sampler's first draw and
    // for the rays: the draws (and the rays) of different samples are short independent
    // chains the CPU overlaps, instead of one long latency-bound chain in front of every
    // traversal. Each sample stays a pure function of its key, and the film sees the
    // samples in the same order as one at a time.
    constexpr int kBatch = 16;
    struct CameraSample {
        PixelSampler sampler;
        Vec2f u_film{0.0f};
        int x = 0;
    };
    CameraSample batch[kBatch];
    Ray rays[kBatch];
    Hit hits[kBatch];
    for (int y = tile.y0; y < tile.y1; ++y) {
        int x = tile.x0, s = 0;  // the next sample to make: sample s of this pass at pixel x
        uint32_t first_index = 0;
        uint64_t key = 0;
        while (x < tile.x1) {
            int n = 0;
            while (n < kBatch && x < tile.x1) {
                if (s == 0) {
                    if (!film.active(x, y)) {
                        ++x;
                        continue;
                    }
                    first_index = film.next_sample_index(x, y);
                    key = PixelSampler::pixel_key(trace.seed, uint32_t(x), uint32_t(y));
                }
                // Every sample made is traced and advances the pixel's index by one.
                const uint32_t index = first_index + uint32_t(s);
                if (s == spp || index >= t.max_spp) {
                    pixels_done += s > 0;
                    ++x;
                    s = 0;
                    continue;
                }
                CameraSample& c = batch[n++];
                c.x = x;
                c.sampler = PixelSampler(key, index);
                ++s;
            }
            for (int i = 0; i < n; ++i) batch[i].u_film = batch[i].sampler.next_2d();
            for (int i = 0; i < n; ++i) {
                // Field by field: a whole-Ray copy from a temporary makes GCC reload
                // just-stored floats as 16-byte vectors (a store-forwarding stall).
                const Ray r = camera_ray(camera, trace, batch[i].x, y, batch[i].u_film);
                rays[i].origin = r.origin;
                rays[i].tmin = r.tmin;
                rays[i].dir = r.dir;
                rays[i].tmax = r.tmax;
            }
            // Without a heat map (which needs each ray's own counts), the camera rays go
            // to the kd-tree's batch query: neighbouring samples' rays are coherent and
            // traced as 8-ray packets, with exactly the hits of one query per ray.
            if (!heat) {
                TraversalCounters tc;
                scene.tree->intersect(rays, size_t(n), hits, trace.count_traversal ? &tc : nullptr);
                counters.nodes_visited += tc.nodes_visited;
                counters.triangles_tested += tc.triangles_tested;
                // Shading reads each hit's vertex indices from the mesh, likely a cache miss
                // (the traversal reads its own copy): start those loads for the whole batch
                // before the first path needs one.
                for (int i = 0; i < n; ++i)
                    if (hits[i].valid()) __builtin_prefetch(&scene.mesh->triangles[hits[i].prim]);
            }
            for (int i = 0; i < n; ++i) {
                CameraSample& c = batch[i];
                const uint64_t nodes0 = counters.nodes_visited, tris0 = counters.triangles_tested;
                // With a heat map each camera ray is traced on its own, its counts kept (as
                // trace_camera_ray() does); its hit then serves the path, coverage and AOVs.
                Hit own;
                if (heat) {
                    TraversalCounters tc;
                    scene.tree->intersect(rays[i], own, trace.count_traversal ? &tc : nullptr);
                    counters.nodes_visited += tc.nodes_visited;
                    counters.triangles_tested += tc.triangles_tested;
                }
                const Hit& hit = heat ? own : hits[i];
                const Vec3f L = trace_camera_hit(scene, trace, rays[i], hit, c.sampler, counters);
                if (heat) {
                    const size_t pi = size_t(y) * size_t(width) + size_t(c.x);
                    t.heat_nodes[pi] += counters.nodes_visited - nodes0;
                    t.heat_triangles[pi] += counters.triangles_tested - tris0;
                }
                add_sample(t, c.x, y, rays[i], hit, L, counters);
            }
        }
    }
    return pixels_done;
}

}  // namespace kdt
