#include "renderer/integrator/path_tracer.h"

#include <bit>
#include <cmath>

#include "renderer/integrator/path_state.h"

namespace kdt {

PathCounters& PathCounters::operator+=(const PathCounters& o) {
    samples += o.samples;
    camera_rays += o.camera_rays;
    bounce_rays += o.bounce_rays;
    shadow_rays += o.shadow_rays;
    nodes_visited += o.nodes_visited;
    triangles_tested += o.triangles_tested;
    nonfinite_dropped += o.nonfinite_dropped;
    return *this;
}

Vec3f offset_ray_origin(const Vec3f& p, const Vec3f& n, float scale) {
    // At least the smallest normal float, so that a point at the very origin moves too.
    return p + (std::max(scale, 0x1p-126f) * 0x1p-16f) * n;
}

EmitterTable build_emitter_table(const TraceScene& scene) {
    EmitterTable table;
    if (!scene.mesh) return table;
    const TriangleMesh& mesh = *scene.mesh;
    std::vector<float> weights;
    for (size_t i = 0; i < mesh.triangles.size() && i < scene.triangle_instance.size(); ++i) {
        const uint32_t inst = scene.triangle_instance[i];
        if (inst >= scene.instances.size()) continue;
        const Vec3f& e = scene.instances[inst].material.emission;
        const float mean = (e.x + e.y + e.z) / 3.0f;
        if (!(mean > 0.0f)) continue;
        const Vec3u& t = mesh.triangles[i];
        const Vec3f& p0 = mesh.positions[t.x];
        const auto area =
            float(0.5 * glm::length(triangle_cross(p0, mesh.positions[t.y], mesh.positions[t.z])));
        const float w = area * mean;
        if (!(area > 0.0f) || !std::isfinite(w)) continue;
        table.triangles.push_back(uint32_t(i));
        weights.push_back(w);
    }
    if (table.triangles.empty()) return table;
    table.dist = Distribution1D(std::move(weights));
    table.total = table.dist.sum();
    return table;
}

InstanceRuns build_instance_runs(const TraceScene& scene) {
    InstanceRuns runs;
    const std::vector<uint32_t>& ti = scene.triangle_instance;
    for (size_t i = 0; i < ti.size(); ++i) {
        if (i > 0 && ti[i] == ti[i - 1]) continue;
        if (runs.first.size() == InstanceRuns::kMaxRuns) return {};
        runs.first.push_back(uint32_t(i));
        runs.instance.push_back(ti[i]);
    }
    return runs;
}

namespace {

constexpr float kInv4Pi = 0.25f * kInvPi;

float mean_component(const Vec3f& v) { return (v.x + v.y + v.z) / 3.0f; }

float max_component(const Vec3f& v) { return std::max(v.x, std::max(v.y, v.z)); }

struct Frame {
    Vec3f t, b, n;
    Vec3f to_local(const Vec3f& v) const {
        return {glm::dot(v, t), glm::dot(v, b), glm::dot(v, n)};
    }
    Vec3f to_world(const Vec3f& v) const { return v.x * t + v.y * b + v.z * n; }
};

// normalize(frame.to_world(wi)) for a sampled direction wi, rounded as written: with FMA
// (-march=native) the compiler may contract products into FMAs, and how it does depends on
// the code around (it vectorised x and y apart from z), so bounce directions, and images,
// would change with unrelated edits. The FMAs below are the ones the images are made with.
Vec3f sampled_direction(const Frame& f, const Vec3f& wi) {
#ifdef __FMA__
    const Vec3f v(std::fma(wi.z, f.n.x, std::fma(wi.x, f.t.x, wi.y * f.b.x)),
                  std::fma(wi.z, f.n.y, std::fma(wi.x, f.t.y, wi.y * f.b.y)),
                  std::fma(wi.z, f.n.z, std::fma(wi.y, f.b.z, wi.x * f.t.z)));
    const float inv_len = 1.0f / std::sqrt(std::fma(v.z, v.z, std::fma(v.y, v.y, v.x * v.x)));
    return v * inv_len;
#else
    return glm::normalize(f.to_world(wi));
#endif
}

// Everything shading needs about a hit.
struct SurfacePoint {
    Vec3f p;
    float offset_scale;  // of rays leaving p (offset_ray_origin)
    Vec3f ng;            // unit geometric normal; two-sided materials: flipped towards wo
    Frame frame;         // shading frame (n = shading normal, same side as ng)
    const Material* material;
};

SurfacePoint make_surface(const TraceScene& scene, const Ray& ray, const Hit& hit) {
    const TriangleMesh& mesh = *scene.mesh;
    const Vec3u tri = mesh.triangles[hit.prim];
    const Vec3f p0 = mesh.positions[tri.x], p1 = mesh.positions[tri.y], p2 = mesh.positions[tri.z];
    const float w = 1.0f - hit.u - hit.v;
    SurfacePoint s;
    // Barycentric interpolation is more accurate than origin + t * dir far from the origin.
    s.p = w * p0 + hit.u * p1 + hit.v * p2;
    s.offset_scale = offset_scale(s.p, p0, p1, p2);
    Vec3f ng = triangle_normal(p0, p1, p2);
    if (ng == Vec3f(0.0f)) ng = -ray.dir;
    const ShadingInstance& inst = scene.instances[scene.instance_of(hit.prim)];
    s.material = &inst.material;
    Vec3f ns = ng;
    if (inst.smooth && !scene.normals.empty()) {
        Vec3f n =
            w * scene.normals[tri.x] + hit.u * scene.normals[tri.y] + hit.v * scene.normals[tri.z];
        const float nl = glm::length(n);
        if (nl > 0.0f && std::isfinite(nl)) ns = n / nl;
        if (glm::dot(ns, ng) < 0.0f) ns = -ns;  // normals disagreeing with the winding
    }
    const Vec3f wo = -ray.dir;
    if (inst.material.type != MaterialType::dielectric && glm::dot(wo, ng) < 0.0f) {
        ng = -ng;  // two-sided: shade the side the ray came from
        ns = -ns;
    }
    // A shading normal facing away from the viewer (silhouettes of smooth meshes) would
    // make the BSDF black; fall back to the geometric normal there.
    if (glm::dot(wo, ns) * glm::dot(wo, ng) <= 0.0f) ns = ng;
    s.ng = ng;
    s.frame.n = ns;
    make_basis(ns, s.frame.t, s.frame.b);
    return s;
}

}  // namespace

PathRules path_rules(const TraceScene& scene, const TraceParams& params) {
    PathRules r;
    r.use_nee = params.light_sampling != LightSampling::bsdf;
    r.use_mis = params.light_sampling == LightSampling::mis;
    r.sample_emitters = r.use_nee && params.sample_emitters && !scene.emitters.empty();
    // Under mis a constant environment is left to BSDF sampling alone: its integrand at a
    // vertex is f cos times a constant times visibility, which BSDF sampling follows and a
    // uniform sphere sample does not, so an environment sample would add a shadow ray and
    // variance and nothing else (Cycles likewise drops its background light when the world
    // shader is constant). Escaping rays then count fully. Emitter sampling is unaffected.
    r.env_nee = r.use_nee && !(r.use_mis && scene.env->is_constant());
    return r;
}

namespace {

// Emits a shadow ray of st's step that adds color * scale when unoccluded.
void emit_shadow(PathState& st, PathCounters& counters, const Ray& shadow, const Vec3f& color,
                 float scale) {
    const int k = st.shadow_count++;
    st.shadow[k] = shadow;
    st.shadow_color[k] = color;
    st.shadow_scale[k] = scale;
    ++counters.shadow_rays;
}

// Next-event estimation of the environment at the non-delta surface point sp (path_step).
void sample_environment(const TraceScene& scene, const TraceParams& params, bool use_mis,
                        const SurfacePoint& sp, const Vec3f& wo, const Vec2f& u_light,
                        PathState& st, PathCounters& counters) {
    const EnvironmentLight& env = *scene.env;
    const Material& mat = *sp.material;
    EnvSample ls;
    if (params.env_importance) {
        ls = use_mis ? env.sample_mis(u_light) : env.sample(u_light);
    } else {
        ls.dir = sample_uniform_sphere(u_light);
        ls.radiance = env.eval(ls.dir);
        ls.pdf_solid_angle = kInv4Pi;
    }
    if (!(ls.pdf_solid_angle > 0.0f && max_component(ls.radiance) > 0.0f &&
          glm::dot(ls.dir, sp.ng) > 0.0f))
        return;
    const Vec3f wi = sp.frame.to_local(ls.dir);
    const Vec3f f = bsdf_eval(mat, wo, wi, params.diffuse_sampling);
    if (!(max_component(f) > 0.0f)) return;
    Ray shadow;
    shadow.origin = offset_ray_origin(sp.p, sp.ng, sp.offset_scale);
    shadow.dir = ls.dir;
    const float w = use_mis ? power_heuristic(ls.pdf_solid_angle,
                                              bsdf_pdf(mat, wo, wi, params.diffuse_sampling))
                            : 1.0f;
    emit_shadow(st, counters, shadow, st.beta * f * ls.radiance, w / ls.pdf_solid_angle);
}

// Next-event estimation of the emissive triangles at the non-delta surface point sp: a
// uniform point on a triangle picked by power; the shadow ray ends a few ULPs before the
// emitter's surface.
void sample_emitter(const TraceScene& scene, const TraceParams& params, bool use_mis,
                    const SurfacePoint& sp, const Vec3f& wo, PixelSampler& sampler, PathState& st,
                    PathCounters& counters) {
    const Material& mat = *sp.material;
    const Vec2f u_pick = sampler.next_2d();
    size_t cell = 0;
    scene.emitters.dist.sample_continuous(u_pick.x, &cell);
    const uint32_t prim = scene.emitters.triangles[cell];
    const Vec3u& tri = scene.mesh->triangles[prim];
    const Vec3f& p0 = scene.mesh->positions[tri.x];
    const Vec3f& p1 = scene.mesh->positions[tri.y];
    const Vec3f& p2 = scene.mesh->positions[tri.z];
    const float su = std::sqrt(u_pick.y);
    const Vec2f u_pt = sampler.next_2d();
    const float b1 = su * (1.0f - u_pt.x), b2 = su * u_pt.x;
    const Vec3f pl = (1.0f - b1 - b2) * p0 + b1 * p1 + b2 * p2;
    const Vec3f nl = triangle_normal(p0, p1, p2);
    // Distances in double: a float squared distance overflows beyond about 1e19.
    const Vec3d d = Vec3d(pl) - Vec3d(sp.p);
    const double dist2 = glm::dot(d, d);
    const Vec3f wi_l(d / std::sqrt(dist2));
    const float cos_l = std::fabs(glm::dot(nl, wi_l));
    const Material& lm = scene.instances[scene.instance_of(prim)].material;
    const auto pdf =
        float(double(mean_component(lm.emission)) / scene.emitters.total * dist2 / cos_l);
    if (!(dist2 > 0.0 && cos_l > 0.0f && std::isfinite(pdf) && pdf > 0.0f &&
          glm::dot(wi_l, sp.ng) > 0.0f))
        return;
    const Vec3f wi = sp.frame.to_local(wi_l);
    const Vec3f f = bsdf_eval(mat, wo, wi, params.diffuse_sampling);
    if (!(max_component(f) > 0.0f)) return;
    Ray shadow;
    shadow.origin = offset_ray_origin(sp.p, sp.ng, sp.offset_scale);
    const Vec3f end =
        offset_ray_origin(pl, glm::dot(nl, wi_l) < 0.0f ? nl : -nl, offset_scale(pl, p0, p1, p2));
    shadow.dir = end - shadow.origin;
    shadow.tmax = 1.0f;
    const float w =
        use_mis ? power_heuristic(pdf, bsdf_pdf(mat, wo, wi, params.diffuse_sampling)) : 1.0f;
    emit_shadow(st, counters, shadow, st.beta * f * lm.emission, w / pdf);
}

}  // namespace

void path_step(const TraceScene& scene, const TraceParams& params, const PathRules& rules,
               PathState& st, const Hit& hit, PixelSampler& sampler, PathCounters& counters) {
    const EnvironmentLight& env = *scene.env;
    const bool use_mis = rules.use_mis, env_nee = rules.env_nee;
    const bool sample_emitters = rules.sample_emitters;
    const Ray& ray = st.ray;  // replaced only at the end
    const int depth = st.depth;
    st.shadow_count = 0;
    if (!hit.valid()) {
        if (st.specular_bounce || !env_nee) {
            st.radiance += st.beta * env.eval(ray.dir);
        } else if (use_mis) {
            const float light_pdf = params.env_importance ? env.pdf_mis(ray.dir) : kInv4Pi;
            st.radiance +=
                st.beta * env.eval(ray.dir) * power_heuristic(st.prev_bsdf_pdf, light_pdf);
        }
        st.alive = false;
        return;
    }
    // The traversal has just read the hit triangle's positions, but its shading normals
    // (and its instance, without runs) are likely cache misses: start those loads, then
    // draw this vertex's samples, which do not depend on them, while they are in flight.
    // A path that ends here draws samples it does not use, which changes nothing.
    // (Written out here: GCC deletes calls to a function that only prefetches, which it
    // finds free of side effects.)
    if (!scene.normals.empty()) {
        const Vec3u& tri = scene.mesh->triangles[hit.prim];
        __builtin_prefetch(&scene.normals[tri.x]);
        __builtin_prefetch(&scene.normals[tri.y]);
        __builtin_prefetch(&scene.normals[tri.z]);
    }
    if (scene.runs.first.empty()) __builtin_prefetch(&scene.triangle_instance[hit.prim]);
    // Draws are made only where they are used, BSDF direction first, so that under BSDF
    // sampling alone (a constant sky) bounce k's direction is draw k: all Sobol, and the
    // first one stratified jointly with the film position (PixelSampler). The lobe /
    // roulette draw waits until the material is known.
    const Vec2f u_bsdf = sampler.next_2d();
    const Vec2f u_light = env_nee ? sampler.next_2d() : Vec2f(0.0f);

    // Surface hit after `depth` scattering events; scattering here makes depth + 1.
    const SurfacePoint sp = make_surface(scene, ray, hit);
    const Material& mat = *sp.material;
    // Emission found by a BSDF ray: counts fully unless emitter NEE also estimates it
    // (then weighted by MIS, or left to NEE alone without MIS). Bounce rays have unit
    // directions, so hit.t is the distance.
    if (mat.emission != Vec3f(0.0f)) {
        if (st.specular_bounce || !sample_emitters) {
            st.radiance += st.beta * mat.emission;
        } else if (use_mis) {
            const float cos_l = std::fabs(glm::dot(sp.ng, ray.dir));
            const auto light_pdf = float(double(mean_component(mat.emission)) /
                                         scene.emitters.total * double(hit.t) * hit.t / cos_l);
            st.radiance += st.beta * mat.emission * power_heuristic(st.prev_bsdf_pdf, light_pdf);
        }
    }
    st.alive = false;  // until the next ray is set
    if (depth + 1 > params.max_depth || is_black(mat)) return;

    const Vec3f wo_world = -ray.dir;
    const Vec3f wo = sp.frame.to_local(wo_world);
    if (env_nee && !is_delta(mat)) {
        sample_environment(scene, params, use_mis, sp, wo, u_light, st, counters);
    }
    if (sample_emitters && !is_delta(mat)) {
        sample_emitter(scene, params, use_mis, sp, wo, sampler, st, counters);
    }

    // x picks a dielectric's lobe, y decides Russian roulette.
    const bool roulette = params.russian_roulette && depth + 1 >= params.rr_min_depth;
    const Vec2f u_lobe_rr =
        roulette || mat.type == MaterialType::dielectric ? sampler.next_2d() : Vec2f(0.0f);
    // Continue the path by sampling the BSDF.
    BsdfSample bs;
    if (!bsdf_sample(mat, wo, u_bsdf, u_lobe_rr.x, bs, params.diffuse_sampling)) return;
    const Vec3f wi_world = sampled_direction(sp.frame, bs.wi);
    const float cos_g_in = glm::dot(wi_world, sp.ng);
    // Reject directions on the wrong side of the geometric surface (light leaks from
    // shading normals): reflection must leave on wo's side, transmission on the other.
    const bool transmit = bs.wi.z * wo.z < 0.0f;
    const float cos_g_out = glm::dot(wo_world, sp.ng);
    if (transmit ? cos_g_in * cos_g_out >= 0.0f : cos_g_in * cos_g_out <= 0.0f) return;
    st.beta *= bs.weight;
    st.specular_bounce = bs.delta;
    st.prev_bsdf_pdf = bs.pdf_solid_angle;
    if (!(max_component(st.beta) > 0.0f)) return;

    // Russian roulette: survive with probability min(1, max throughput) and reweight.
    if (roulette) {
        const float survive = std::min(1.0f, max_component(st.beta));
        if (u_lobe_rr.y >= survive) return;
        st.beta /= survive;
    }
    Ray next;
    next.origin = offset_ray_origin(sp.p, cos_g_in > 0.0f ? sp.ng : -sp.ng, sp.offset_scale);
    next.dir = wi_world;
    st.ray = next;
    st.depth = depth + 1;
    st.alive = true;
    ++counters.bounce_rays;
}

namespace {

// Records nothing: the rendering path (compiles away).
struct NoRecorder {
    void closest(const Ray&) {}
    void any(const Ray&) {}
};

struct VectorRecorder {
    RayRecord* out;
    void closest(const Ray& r) { out->closest.push_back(r); }
    void any(const Ray& r) { out->any.push_back(r); }
};

// One path at a time: path_step() on each closest hit, its shadow rays traced at once. The
// step is the one compiled function the wavefront calls too, so both round alike.
// first_hit: when set, the closest hit of camera_ray, already found (and counted) by the
// caller.
template <class Recorder>
Vec3f trace_path_impl(const TraceScene& scene, const TraceParams& params, const Ray& camera_ray,
                      PixelSampler& sampler, PathCounters& counters, Recorder& recorder,
                      const Hit* first_hit = nullptr) {
    const KdTree& tree = *scene.tree;
    TraversalCounters tc;
    TraversalCounters* tcp = params.count_traversal ? &tc : nullptr;
    const PathRules rules = path_rules(scene, params);
    PathState st = start_path(camera_ray);
    do {
        // A pointer, not a copy of *first_hit: reloading the caller's fresh scalar stores as
        // one vector would stall store forwarding.
        Hit found;
        const Hit* hitp = &found;
        recorder.closest(st.ray);
        if (st.depth == 0 && first_hit)
            hitp = first_hit;
        else
            tree.intersect(st.ray, found, tcp);
        path_step(scene, params, rules, st, *hitp, sampler, counters);
        for (int k = 0; k < st.shadow_count; ++k) {
            recorder.any(st.shadow[k]);
            path_shadow_result(st, k, tree.occluded(st.shadow[k], tcp));
        }
    } while (st.alive);
    counters.nodes_visited += tc.nodes_visited;
    counters.triangles_tested += tc.triangles_tested;
    return st.radiance;
}

}  // namespace

Vec3f trace_path(const TraceScene& scene, const TraceParams& params, const Ray& camera_ray,
                 PixelSampler& sampler, PathCounters& counters) {
    NoRecorder none;
    return trace_path_impl(scene, params, camera_ray, sampler, counters, none);
}

void record_rays(const TraceScene& scene, const Camera& camera, const TraceParams& params, int x,
                 int y, uint32_t sample_index, RayRecord& record) {
    PixelSampler sampler(params.seed, uint32_t(x), uint32_t(y), sample_index);
    const Ray ray = camera_ray(camera, params, x, y, sampler.next_2d());
    PathCounters counters;
    VectorRecorder rec{&record};
    trace_path_impl(scene, params, ray, sampler, counters, rec);
}

Vec3f render_sample(const TraceScene& scene, const Camera& camera, const TraceParams& params, int x,
                    int y, uint32_t sample_index, PathCounters& counters) {
    return render_sample(scene, camera, params, x, y, sample_index,
                         PixelSampler::pixel_key(params.seed, uint32_t(x), uint32_t(y)), counters);
}

Vec3f render_sample(const TraceScene& scene, const Camera& camera, const TraceParams& params, int x,
                    int y, uint32_t sample_index, uint64_t pixel_key, PathCounters& counters) {
    PixelSampler sampler(pixel_key, sample_index);
    const Ray ray = camera_ray(camera, params, x, y, sampler.next_2d());
    return trace_camera_ray(scene, params, ray, sampler, counters);
}

Vec3f trace_camera_ray(const TraceScene& scene, const TraceParams& params, const Ray& ray,
                       PixelSampler& sampler, PathCounters& counters) {
    TraversalCounters tc;
    Hit hit;
    scene.tree->intersect(ray, hit, params.count_traversal ? &tc : nullptr);
    counters.nodes_visited += tc.nodes_visited;
    counters.triangles_tested += tc.triangles_tested;
    return trace_camera_hit(scene, params, ray, hit, sampler, counters);
}

Vec3f trace_camera_hit(const TraceScene& scene, const TraceParams& params, const Ray& ray,
                       const Hit& hit, PixelSampler& sampler, PathCounters& counters) {
    ++counters.camera_rays;
    ++counters.samples;
    // Most camera rays of a framed model miss it: those see the environment unweighted
    // (trace_path_impl's depth-0 miss), without setting up the path loop.
    if (hit.prim == Hit::kNoHit) return scene.env->eval(ray.dir);
    NoRecorder none;
    return trace_path_impl(scene, params, ray, sampler, counters, none, &hit);
}

}  // namespace kdt
