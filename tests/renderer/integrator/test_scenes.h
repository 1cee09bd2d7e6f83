// Small generated scenes and analytic environments for the integrator and render tests.
#pragma once

#include <cmath>
#include <map>
#include <memory>
#include <utility>
#include <vector>

#include "renderer/integrator/trace_scene.h"
#include "renderer/material/material.h"

namespace kdt::test {

/// Constant radiance from every direction, sampled uniformly over the sphere.
class ConstantEnv : public EnvironmentLight {
public:
    explicit ConstantEnv(Vec3f c) : c_(c) {}
    Vec3f eval(const Vec3f&) const override { return c_; }
    EnvSample sample(const Vec2f& u) const override {
        return {sample_uniform_sphere(u), c_, 0.25f * kInvPi};
    }
    float pdf(const Vec3f&) const override { return 0.25f * kInvPi; }
    bool is_constant() const override { return true; }

private:
    Vec3f c_;
};

/// A smooth, direction-dependent environment (for mirror tests), sampled uniformly.
class GradientEnv : public EnvironmentLight {
public:
    Vec3f eval(const Vec3f& d) const override {
        return {0.5f + 0.5f * d.x, 1.0f + d.y * d.y, 2.0f + std::sin(3.0f * d.z)};
    }
    EnvSample sample(const Vec2f& u) const override {
        const Vec3f d = sample_uniform_sphere(u);
        return {d, eval(d), 0.25f * kInvPi};
    }
    float pdf(const Vec3f&) const override { return 0.25f * kInvPi; }
    bool is_constant() const override { return false; }
};

/// Icosphere: subdivided icosahedron projected to the sphere, counter-clockwise outside.
inline TriangleMesh make_icosphere(Vec3f centre, float radius, int levels) {
    const float t = (1.0f + std::sqrt(5.0f)) / 2.0f;
    std::vector<Vec3f> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
                            {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                            {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    std::vector<Vec3u> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                            {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                            {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                            {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
    TriangleMesh m;
    m.positions = v;
    m.triangles = f;
    m = subdivide_mesh(m, levels);
    for (Vec3f& p : m.positions) p = centre + radius * glm::normalize(p);
    return m;
}

/// Closed axis-aligned box, counter-clockwise seen from outside.
inline TriangleMesh make_box(Vec3f lo, Vec3f hi) {
    TriangleMesh m;
    for (int i = 0; i < 8; ++i) {
        m.positions.push_back(
            {(i & 1) ? hi.x : lo.x, (i & 2) ? hi.y : lo.y, (i & 4) ? hi.z : lo.z});
    }
    const uint32_t q[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                              {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (const auto& f : q) {
        m.triangles.push_back({f[0], f[1], f[2]});
        m.triangles.push_back({f[0], f[2], f[3]});
    }
    return m;
}

/// Quad corner, corner + e1, corner + e1 + e2, corner + e2 (normal e1 x e2).
inline TriangleMesh make_quad(Vec3f corner, Vec3f e1, Vec3f e2) {
    TriangleMesh m;
    m.positions = {corner, corner + e1, corner + e1 + e2, corner + e2};
    m.triangles = {{0, 1, 2}, {0, 2, 3}};
    return m;
}

inline Material diffuse(float albedo, Vec3f emission = Vec3f(0.0f)) {
    Material m;
    m.type = MaterialType::diffuse;
    m.albedo = Vec3f(albedo);
    m.emission = emission;
    return m;
}

inline Material of_type(MaterialType t, Vec3f albedo = Vec3f(1.0f)) {
    Material m;
    m.type = t;
    m.albedo = albedo;
    return m;
}

/// Merges meshes, one instance each; builds the kd-tree.
inline TraceScene make_scene(const std::vector<std::pair<TriangleMesh, ShadingInstance>>& parts,
                             std::shared_ptr<const EnvironmentLight> env) {
    TraceScene s;
    auto merged = std::make_shared<TriangleMesh>();
    for (size_t i = 0; i < parts.size(); ++i) {
        const TriangleMesh& m = parts[i].first;
        s.instances.push_back(parts[i].second);
        const auto base = uint32_t(merged->positions.size());
        merged->positions.insert(merged->positions.end(), m.positions.begin(), m.positions.end());
        std::vector<Vec3f> n =
            m.normals.size() == m.positions.size() ? m.normals : compute_vertex_normals(m);
        s.normals.insert(s.normals.end(), n.begin(), n.end());
        for (const Vec3u& t : m.triangles) merged->triangles.push_back(t + Vec3u(base));
        s.triangle_instance.insert(s.triangle_instance.end(), m.triangles.size(), uint32_t(i));
    }
    s.mesh = merged;
    s.env = std::move(env);
    s.tree = build_kdtree(merged, KdTreeParams{});
    s.runs = build_instance_runs(s);
    return s;
}

inline ShadingInstance flat(const Material& m) { return {m, false}; }
inline ShadingInstance smooth(const Material& m) { return {m, true}; }

/// A smooth diffuse sphere and a glass sphere on a box, an emissive quad above them, with its
/// emitter table: every kind of shadow ray and lobe (wavefront and tile tests).
inline TraceScene make_mixed_scene(std::shared_ptr<const EnvironmentLight> env) {
    Material glass = of_type(MaterialType::dielectric);
    glass.ior = 1.5f;
    TraceScene s = make_scene({{make_icosphere({-0.5f, 0.4f, 0}, 0.4f, 2), smooth(diffuse(0.7f))},
                               {make_icosphere({0.5f, 0.4f, 0.2f}, 0.4f, 2), smooth(glass)},
                               {make_box({-1.5f, -1, -1.5f}, {1.5f, 0, 1.5f}), flat(diffuse(0.5f))},
                               {make_quad({-0.3f, 1.5f, -0.3f}, {0.6f, 0, 0}, {0, 0, 0.6f}),
                                flat(diffuse(0.0f, Vec3f(8.0f, 7.0f, 6.0f)))}},
                              std::move(env));
    s.emitters = build_emitter_table(s);
    return s;
}

}  // namespace kdt::test
