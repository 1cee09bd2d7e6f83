// The path tracer's per-path logic as a state and a step: a step consumes the closest hit of
// the path's ray and emits its shadow rays and next ray. The one-path loop (trace_path) and
// the wavefront (wavefront.h) both drive it, so there is one integrator. Depends on
// integrator/path_tracer.h.
#pragma once

#include <cmath>
#include <cstdint>

#include "renderer/integrator/path_tracer.h"

namespace kdt {

/// What the scene and TraceParams decide for every path (path_rules()).
struct PathRules {
    bool use_nee = false;          ///< light_sampling nee or mis
    bool use_mis = false;          ///< light_sampling mis
    bool sample_emitters = false;  ///< NEE of emissive triangles
    bool env_nee = false;          ///< NEE of the environment (see trace_path)
};

PathRules path_rules(const TraceScene& scene, const TraceParams& params);

/// One path between steps.
struct PathState {
    Vec3f radiance{0.0f}, beta{1.0f};
    Ray ray;  ///< the ray whose closest hit the next step consumes (while alive)
    float prev_bsdf_pdf = 0.0f;
    int depth = 0;                ///< scattering events before ray
    bool specular_bounce = true;  ///< camera rays and delta bounces see the env unweighted
    bool alive = true;            ///< false: no next ray; radiance is final once the
                                  ///< last step's shadow rays are resolved
    /// Shadow rays (any-hit queries) the last step emitted, in the order the one-path loop
    /// traces them. Each must be resolved (path_shadow_result) before the next step.
    uint8_t shadow_count = 0;
    Ray shadow[2];
    /// What shadow ray k adds when unoccluded: shadow_color[k] * shadow_scale[k].
    Vec3f shadow_color[2];
    float shadow_scale[2];
};

/// A path starting with a camera ray.
inline PathState start_path(const Ray& camera_ray) {
    PathState st;
    st.ray = camera_ray;
    return st;
}

/// Consumes `hit`, the closest hit of st.ray (hit.prim == Hit::kNoHit for a miss): adds the
/// light found there, draws the vertex's samples from `sampler`, emits the shadow rays of
/// next-event estimation into st.shadow and either the next ray into st.ray or sets
/// st.alive = false. Counts shadow and bounce rays (not traversal work). Never allocates.
void path_step(const TraceScene& scene, const TraceParams& params, const PathRules& rules,
               PathState& st, const Hit& hit, PixelSampler& sampler, PathCounters& counters);

/// The outcome of shadow ray k of the last step. Resolve them in order k = 0, 1, ...
/// The sum is rounded as written (one FMA per channel on FMA builds), not as the compiler
/// would contract it where this is inlined.
inline void path_shadow_result(PathState& st, int k, bool occluded) {
    if (occluded) return;
#ifdef __FMA__
    const Vec3f& c = st.shadow_color[k];
    const float s = st.shadow_scale[k];
    st.radiance = Vec3f(std::fma(c.x, s, st.radiance.x), std::fma(c.y, s, st.radiance.y),
                        std::fma(c.z, s, st.radiance.z));
#else
    st.radiance += st.shadow_color[k] * st.shadow_scale[k];
#endif
}

}  // namespace kdt
