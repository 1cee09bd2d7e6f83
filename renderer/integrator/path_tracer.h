// Unidirectional path tracing with next-event estimation of the environment light and of
// emissive triangles, multiple importance sampling (power heuristic), Russian roulette after a
// minimum depth.
// One sample is a pure function of (scene, camera, params, pixel, sample index); the hot
// path never allocates or throws. Depends on accel, light, material, camera, core.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "renderer/camera/camera.h"
#include "renderer/core/sampler.h"
#include "renderer/integrator/trace_scene.h"

namespace kdt {

/// How direct light from the environment (and from emissive triangles) is estimated.
/// bsdf: BSDF sampling only (paths count the environment when they escape);
/// nee: next-event estimation only at non-delta vertices (escaping rays after them add nothing);
/// mis: both, combined with the power heuristic (Veach 1997), except that a constant
/// environment is left to BSDF sampling (no environment shadow rays; see trace_path).
enum class LightSampling : uint8_t { bsdf, nee, mis };
inline constexpr std::array<const char*, 3> kLightSamplingNames = {"bsdf", "nee", "mis"};

/// Path tracing parameters; defaults documented in docs/conventions.md.
struct TraceParams {
    /// Maximum path depth, counted as scattering events (bounces): a camera ray that hits
    /// the environment or an emitter directly has depth 0, one diffuse bounce to the
    /// environment (by NEE or by a BSDF ray) depth 1. 0 renders only directly visible
    /// environment and emission (pbrt's maxdepth; Mitsuba's max_depth is this + 1).
    int max_depth = 16;
    bool russian_roulette = true;  ///< after rr_min_depth bounces (thesis: adaptive depth)
    int rr_min_depth = 3;          ///< bounces before roulette may end a path
    LightSampling light_sampling = LightSampling::mis;
    bool env_importance = true;  ///< NEE samples the env map's distribution, else uniform sphere
    /// With nee or mis, also sample emissive triangles (scene.emitters) at each non-delta
    /// vertex; false: emitters are found by BSDF rays only.
    bool sample_emitters = true;
    DiffuseSampling diffuse_sampling = DiffuseSampling::cosine;
    PixelFilter filter = PixelFilter::box;
    /// Per active pixel and pass; 0 = automatic: run_render() picks up to
    /// kMaxAutoSamplesPerPass for renders without adaptive sampling, else 1.
    int samples_per_pass = 0;
    uint64_t seed = 0;            ///< keys all randomness with the pixel and sample index
    int threads = 0;              ///< OpenMP threads; 0 = default
    bool count_traversal = true;  ///< count nodes visited and triangles tested
    /// Render a tile pass's paths together, bounce by bounce, each bounce's rays traced as
    /// streams (integrator/wavefront.h), else one path at a time; the image and the counters
    /// are the same bit for bit. Tiles with a heat map take the one-path route.
    bool wavefront = true;
    /// The wavefront traces the rays that leave the camera hits (first bounce and its shadow
    /// rays) with the partition traversal (accel/traversal_partition.h) instead of 32-lane
    /// streams when a tile chunk has enough of them (integrator/wavefront.cpp); later bounces
    /// always take the streams. Same image and counters.
    bool partition = true;
};

/// Per-thread counters, summed at the end of a pass.
struct PathCounters {
    uint64_t samples = 0;
    uint64_t camera_rays = 0, bounce_rays = 0, shadow_rays = 0;
    uint64_t nodes_visited = 0, triangles_tested = 0;
    uint64_t nonfinite_dropped = 0;

    uint64_t rays() const { return camera_rays + bounce_rays + shadow_rays; }
    PathCounters& operator+=(const PathCounters& o);
};

/// Moves a ray origin p off the surface along the geometric normal n (unit, pointing to
/// the side the ray leaves to) by 2^-16 times `scale`, the largest magnitude of any
/// coordinate of p and of the triangle it lies on (offset_scale()). The watertight test's
/// translation and shear round each coordinate to a few ULPs of that magnitude, so a ray
/// leaving a surface by less could find it again: from a point with one coordinate near 0
/// and others large (a ground plane at y = 0 of a scene in millimetres) a per-coordinate
/// offset does. No scene-scale epsilon: a scene scaled by a power of two renders the same.
Vec3f offset_ray_origin(const Vec3f& p, const Vec3f& n, float scale);

/// The `scale` of offset_ray_origin() for a point p on the triangle (a, b, c).
inline float offset_scale(const Vec3f& p, const Vec3f& a, const Vec3f& b, const Vec3f& c) {
    const Vec3f m =
        glm::max(glm::max(glm::abs(p), glm::abs(a)), glm::max(glm::abs(b), glm::abs(c)));
    return std::max(std::max(m.x, m.y), m.z);
}

/// Power heuristic with exponent 2 for one sample of each strategy.
inline float power_heuristic(float pdf_a, float pdf_b) {
    const float a = pdf_a * pdf_a, b = pdf_b * pdf_b;
    return a + b > 0.0f ? a / (a + b) : 0.0f;
}

/// Radiance along `ray` (unit direction). Returns a non-finite value only if the scene
/// produced one; the caller drops and counts those. Counts rays and traversal work.
Vec3f trace_path(const TraceScene& scene, const TraceParams& params, const Ray& ray,
                 PixelSampler& sampler, PathCounters& counters);

/// The primary ray of a sample: u_film, the sample's first draw (sampler.next_2d()), picks
/// the pixel-filter offset; returns the camera ray through pixel (x, y) plus that offset.
inline Ray camera_ray(const Camera& camera, const TraceParams& params, int x, int y,
                      const Vec2f& u_film) {
    const Vec2f offset = sample_pixel_filter(params.filter, u_film);
    return camera.generate_ray(Vec2f(float(x), float(y)) + offset);
}

/// trace_path() of a ray from camera_ray(), counted as one sample and one camera ray.
Vec3f trace_camera_ray(const TraceScene& scene, const TraceParams& params, const Ray& ray,
                       PixelSampler& sampler, PathCounters& counters);

/// trace_camera_ray() when the caller has already found the ray's closest hit (hit.prim ==
/// kNoHit for a miss), for example with KdTree's batch query, and counted its traversal.
/// Gives exactly what trace_camera_ray() gives.
Vec3f trace_camera_hit(const TraceScene& scene, const TraceParams& params, const Ray& ray,
                       const Hit& hit, PixelSampler& sampler, PathCounters& counters);

/// One sample of pixel (x, y) with index sample_index: camera_ray(), then
/// trace_camera_ray(). Non-finite results are returned as-is (see Film / render_tiles).
Vec3f render_sample(const TraceScene& scene, const Camera& camera, const TraceParams& params, int x,
                    int y, uint32_t sample_index, PathCounters& counters);
/// The same with pixel_key = PixelSampler::pixel_key(params.seed, x, y) computed once per
/// pixel by the caller.
Vec3f render_sample(const TraceScene& scene, const Camera& camera, const TraceParams& params, int x,
                    int y, uint32_t sample_index, uint64_t pixel_key, PathCounters& counters);

/// The rays one sample traces, in order: closest-hit queries (camera and bounce rays) and
/// any-hit queries (shadow rays). For benchmarks that replay them as raw traversal.
struct RayRecord {
    std::vector<Ray> closest, any;
};

/// Runs render_sample() and appends its rays to record (allocates; not for rendering).
void record_rays(const TraceScene& scene, const Camera& camera, const TraceParams& params, int x,
                 int y, uint32_t sample_index, RayRecord& record);

}  // namespace kdt
