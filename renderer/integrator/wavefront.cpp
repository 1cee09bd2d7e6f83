#include "renderer/integrator/wavefront.h"

#include "renderer/accel/traversal_partition.h"
#include "renderer/accel/traversal_stream.h"

namespace kdt {
namespace {

// Rays in flight per stream query: the most the stream takes (four octets). On the dragon
// under a constant sky (docs/performance.md, "Streams in the renderer") 32 lanes rendered
// 7-13% faster than 16; a bounce's rays are independent, so more of them hide more latency.
constexpr int kWavefrontLanes = 32;

}  // namespace

void trace_camera_hits(const TraceScene& scene, const TraceParams& params, const Ray* rays,
                       const Hit* hits, PixelSampler* samplers, size_t n, Vec3f* radiance,
                       PathCounters& counters, WavefrontScratch& w) {
    const KdTree& tree = *scene.tree;
    TraversalCounters tc;
    TraversalCounters* tcp = params.count_traversal ? &tc : nullptr;
    const PathRules rules = path_rules(scene, params);
    counters.camera_rays += n;
    counters.samples += n;
    if (w.paths.size() < n) {
        w.paths.resize(n);
        w.rays.resize(n);
        w.hits.resize(n);
        w.shadows.resize(2 * n);
        w.shadow_path.resize(2 * n);
        w.occluded.resize(2 * n);
    }
    w.active.clear();
    for (size_t i = 0; i < n; ++i) {
        // A camera ray that misses sees the environment unweighted, as in trace_camera_hit.
        if (!hits[i].valid()) {
            radiance[i] = scene.env->eval(rays[i].dir);
            continue;
        }
        w.paths[i] = start_path(rays[i]);
        w.hits[i] = hits[i];
        w.active.push_back(uint32_t(i));
    }
    // w.hits is indexed by path for the camera hits, then by position in w.active.
    bool camera = true;
    while (!w.active.empty()) {
        // The hit triangles' records first, all of them: path_step reads each one at once,
        // and most are cache misses (the traversal read the tree's copies of the vertex
        // indices, not the mesh's); a prefetch only a few paths ahead comes too late.
        const Vec3u* triangles = scene.mesh->triangles.data();
        for (size_t a = 0; a < w.active.size(); ++a) {
            const Hit& h = w.hits[camera ? w.active[a] : a];
            if (h.valid()) __builtin_prefetch(triangles + h.prim);
        }
        // The partition traversal only for the rays leaving the camera hits (see
        // kWavefrontPartitionMinBatch).
        const bool partition = params.partition && camera;
        size_t shadows = 0;
        for (size_t a = 0; a < w.active.size(); ++a) {
            const uint32_t i = w.active[a];
            PathState& st = w.paths[i];
            path_step(scene, params, rules, st, w.hits[camera ? i : a], samplers[i], counters);
            for (int k = 0; k < st.shadow_count; ++k) {
                w.shadows[shadows] = st.shadow[k];
                w.shadow_path[shadows++] = i;
            }
        }
        camera = false;
        // Each path's shadow rays are resolved in the order it emitted them, before its
        // next step, as the one-path loop does.
        if (shadows > 0) {
            if (partition && shadows >= kWavefrontPartitionMinBatch)
                occluded_partition(tree, w.shadows.data(), shadows, w.occluded.data(), tcp);
            else
                occluded_stream(tree, w.shadows.data(), shadows, w.occluded.data(), kWavefrontLanes,
                                tcp);
            int k = 0;
            for (size_t j = 0; j < shadows; ++j) {
                k = j > 0 && w.shadow_path[j] == w.shadow_path[j - 1] ? k + 1 : 0;
                path_shadow_result(w.paths[w.shadow_path[j]], k, w.occluded[j] != 0);
            }
        }
        size_t alive = 0;
        for (const uint32_t i : w.active) {
            const PathState& st = w.paths[i];
            if (!st.alive) {
                radiance[i] = st.radiance;
                continue;
            }
            w.rays[alive] = st.ray;
            w.active[alive++] = i;
        }
        w.active.resize(alive);
        if (partition && alive >= kWavefrontPartitionMinBatch)
            intersect_partition(tree, w.rays.data(), alive, w.hits.data(), tcp);
        else if (alive > 0)
            intersect_stream(tree, w.rays.data(), alive, w.hits.data(), kWavefrontLanes, tcp);
    }
    counters.nodes_visited += tc.nodes_visited;
    counters.triangles_tested += tc.triangles_tested;
}

}  // namespace kdt
