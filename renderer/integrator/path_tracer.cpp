#include "renderer/integrator/path_tracer.h"

#include <bit>
#include <cmath>

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

// first_hit: when set, the closest hit of camera_ray, already found (and counted) by the
// caller.
template <class Recorder>
Vec3f trace_path_impl(const TraceScene& scene, const TraceParams& params, const Ray& camera_ray,
                      PixelSampler& sampler, PathCounters& counters, Recorder& recorder,
                      const Hit* first_hit = nullptr) {
    const KdTree& tree = *scene.tree;
    TraversalCounters tc;
    const EnvironmentLight& env = *scene.env;
    TraversalCounters* tcp = params.count_traversal ? &tc : nullptr;
    const bool use_nee = params.light_sampling != LightSampling::bsdf;
    const bool use_mis = params.light_sampling == LightSampling::mis;
    const bool sample_emitters = use_nee && params.sample_emitters && !scene.emitters.empty();
    // Under mis a constant environment is left to BSDF sampling alone: its integrand at a
    // vertex is f cos times a constant times visibility, which BSDF sampling follows and a
    // uniform sphere sample does not, so an environment sample would add a shadow ray and
    // variance and nothing else (Cycles likewise drops its background light when the world
    // shader is constant). Escaping rays then count fully. Emitter sampling is unaffected.
    const bool env_nee = use_nee && !(use_mis && env.is_constant());

    Vec3f radiance(0.0f), beta(1.0f);
    Ray ray = camera_ray;
    bool specular_bounce = true;  // camera rays and delta bounces see the env unweighted
    float prev_bsdf_pdf = 0.0f;
    for (int depth = 0;; ++depth) {
        // A pointer, not a copy of *first_hit: reloading the caller's fresh scalar stores as
        // one vector would stall store forwarding.
        Hit found;
        const Hit* hitp = &found;
        recorder.closest(ray);
        if (depth == 0 && first_hit) {
            hitp = first_hit;
        } else if (!tree.intersect(ray, found, tcp)) {
            if (specular_bounce || !env_nee) {
                radiance += beta * env.eval(ray.dir);
            } else if (use_mis) {
                const float light_pdf = params.env_importance ? env.pdf_mis(ray.dir) : kInv4Pi;
                radiance += beta * env.eval(ray.dir) * power_heuristic(prev_bsdf_pdf, light_pdf);
            }
            break;
        }
        const Hit& hit = *hitp;
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
            if (specular_bounce || !sample_emitters) {
                radiance += beta * mat.emission;
            } else if (use_mis) {
                const float cos_l = std::fabs(glm::dot(sp.ng, ray.dir));
                const auto light_pdf = float(double(mean_component(mat.emission)) /
                                             scene.emitters.total * double(hit.t) * hit.t / cos_l);
                radiance += beta * mat.emission * power_heuristic(prev_bsdf_pdf, light_pdf);
            }
        }
        if (depth + 1 > params.max_depth || is_black(mat)) break;

        const Vec3f wo_world = -ray.dir;
        const Vec3f wo = sp.frame.to_local(wo_world);

        // Next-event estimation of the environment.
        if (env_nee && !is_delta(mat)) {
            EnvSample ls;
            if (params.env_importance) {
                ls = use_mis ? env.sample_mis(u_light) : env.sample(u_light);
            } else {
                ls.dir = sample_uniform_sphere(u_light);
                ls.radiance = env.eval(ls.dir);
                ls.pdf_solid_angle = kInv4Pi;
            }
            if (ls.pdf_solid_angle > 0.0f && max_component(ls.radiance) > 0.0f &&
                glm::dot(ls.dir, sp.ng) > 0.0f) {
                const Vec3f wi = sp.frame.to_local(ls.dir);
                const Vec3f f = bsdf_eval(mat, wo, wi, params.diffuse_sampling);
                if (max_component(f) > 0.0f) {
                    Ray shadow;
                    shadow.origin = offset_ray_origin(sp.p, sp.ng, sp.offset_scale);
                    shadow.dir = ls.dir;
                    ++counters.shadow_rays;
                    recorder.any(shadow);
                    if (!tree.occluded(shadow, tcp)) {
                        const float w =
                            use_mis
                                ? power_heuristic(ls.pdf_solid_angle,
                                                  bsdf_pdf(mat, wo, wi, params.diffuse_sampling))
                                : 1.0f;
                        radiance += beta * f * ls.radiance * (w / ls.pdf_solid_angle);
                    }
                }
            }
        }

        // Next-event estimation of the emissive triangles: a uniform point on a triangle
        // picked by power; the shadow ray ends a few ULPs before the emitter's surface.
        if (sample_emitters && !is_delta(mat)) {
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
            if (dist2 > 0.0 && cos_l > 0.0f && std::isfinite(pdf) && pdf > 0.0f &&
                glm::dot(wi_l, sp.ng) > 0.0f) {
                const Vec3f wi = sp.frame.to_local(wi_l);
                const Vec3f f = bsdf_eval(mat, wo, wi, params.diffuse_sampling);
                if (max_component(f) > 0.0f) {
                    Ray shadow;
                    shadow.origin = offset_ray_origin(sp.p, sp.ng, sp.offset_scale);
                    const Vec3f end = offset_ray_origin(pl, glm::dot(nl, wi_l) < 0.0f ? nl : -nl,
                                                        offset_scale(pl, p0, p1, p2));
                    shadow.dir = end - shadow.origin;
                    shadow.tmax = 1.0f;
                    ++counters.shadow_rays;
                    recorder.any(shadow);
                    if (!tree.occluded(shadow, tcp)) {
                        const float w =
                            use_mis ? power_heuristic(
                                          pdf, bsdf_pdf(mat, wo, wi, params.diffuse_sampling))
                                    : 1.0f;
                        radiance += beta * f * lm.emission * (w / pdf);
                    }
                }
            }
        }

        // x picks a dielectric's lobe, y decides Russian roulette.
        const bool roulette = params.russian_roulette && depth + 1 >= params.rr_min_depth;
        const Vec2f u_lobe_rr =
            roulette || mat.type == MaterialType::dielectric ? sampler.next_2d() : Vec2f(0.0f);
        // Continue the path by sampling the BSDF.
        BsdfSample bs;
        if (!bsdf_sample(mat, wo, u_bsdf, u_lobe_rr.x, bs, params.diffuse_sampling)) break;
        const Vec3f wi_world = glm::normalize(sp.frame.to_world(bs.wi));
        const float cos_g_in = glm::dot(wi_world, sp.ng);
        // Reject directions on the wrong side of the geometric surface (light leaks from
        // shading normals): reflection must leave on wo's side, transmission on the other.
        const bool transmit = bs.wi.z * wo.z < 0.0f;
        const float cos_g_out = glm::dot(wo_world, sp.ng);
        if (transmit ? cos_g_in * cos_g_out >= 0.0f : cos_g_in * cos_g_out <= 0.0f) break;
        beta *= bs.weight;
        specular_bounce = bs.delta;
        prev_bsdf_pdf = bs.pdf_solid_angle;
        if (!(max_component(beta) > 0.0f)) break;

        // Russian roulette: survive with probability min(1, max throughput) and reweight.
        if (roulette) {
            const float survive = std::min(1.0f, max_component(beta));
            if (u_lobe_rr.y >= survive) break;
            beta /= survive;
        }
        ray = Ray{};
        ray.origin = offset_ray_origin(sp.p, cos_g_in > 0.0f ? sp.ng : -sp.ng, sp.offset_scale);
        ray.dir = wi_world;
        ++counters.bounce_rays;
    }
    counters.nodes_visited += tc.nodes_visited;
    counters.triangles_tested += tc.triangles_tested;
    return radiance;
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
