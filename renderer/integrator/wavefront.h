// The wavefront route of the path tracer: many camera samples advance together, bounce by
// bounce, and each bounce's rays and shadow rays are traced as one stream
// (accel/traversal_stream.h) or partition (accel/traversal_partition.h). Each path runs
// path_step() (path_state.h), as one path at a time does, so the radiance is the same bit for
// bit. Depends on integrator, accel.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "renderer/integrator/path_state.h"

namespace kdt {

/// With TraceParams::partition, trace_camera_hits() traces the rays that leave the camera
/// hits (first bounce and its shadow rays) by partition traversal when there are at least
/// this many, else and on later bounces by streams. The partition pays where many rays start
/// close together and share the walk through the tree's top. Replaying the wavefront's own
/// batches on the dragon (docs/performance.md, "Partition traversal of tile batches") it was
/// 1.01-1.18x the streams' speed on first-bounce batches of 1024 rays or more (1.25-1.41x on
/// their shadow rays), 0.82-1.03x below, and 0.72-0.83x on later bounces, whose rays start
/// anywhere on the scene.
inline constexpr size_t kWavefrontPartitionMinBatch = 1024;

/// Working memory of trace_camera_hits(); reused across calls (grows, never shrinks), so
/// that a thread allocates only on its first tiles.
struct WavefrontScratch {
    std::vector<PathState> paths;
    std::vector<uint32_t> active;  ///< paths with a ray to trace, ascending
    std::vector<Ray> rays;
    std::vector<Hit> hits;
    std::vector<Ray> shadows;
    std::vector<uint32_t> shadow_path;  ///< the path of each shadow ray
    std::vector<uint8_t> occluded;
};

/// radiance[i] = trace_camera_hit(scene, params, rays[i], hits[i], samplers[i], counters)
/// for i < n, bit for bit, and the same counts in `counters` (traversal work counted by the
/// stream queries when params.count_traversal). samplers[i] advance as there.
void trace_camera_hits(const TraceScene& scene, const TraceParams& params, const Ray* rays,
                       const Hit* hits, PixelSampler* samplers, size_t n, Vec3f* radiance,
                       PathCounters& counters, WavefrontScratch& scratch);

}  // namespace kdt
