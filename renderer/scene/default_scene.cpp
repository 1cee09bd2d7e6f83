// The built-in default scene: generated in code so the first README command needs no download.
#include <cmath>
#include <unordered_map>

#include "renderer/scene/scene.h"

namespace kdt {
namespace {

/// Smooth, deterministic displacement over the unit sphere: a few octaves of products of
/// sines, so the surface has detail at several scales (like a scanned object).
float displacement(const Vec3f& p) {
    float d = 0.0f, amp = 0.06f, freq = 3.0f;
    for (int octave = 0; octave < 4; ++octave) {
        d += amp * std::sin(freq * p.x + 1.3f * octave) * std::sin(freq * p.y + 0.7f) *
             std::sin(freq * p.z + 2.1f * octave);
        amp *= 0.5f;
        freq *= 2.1f;
    }
    return d;
}

}  // namespace

TriangleMesh make_icosphere(int levels) {
    const float t = (1.0f + std::sqrt(5.0f)) / 2.0f;
    TriangleMesh m;
    m.positions = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                   {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
    m.triangles = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                   {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                   {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                   {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
    m = subdivide_mesh(m, levels);
    for (Vec3f& p : m.positions) p = glm::normalize(p);
    return m;
}

TriangleMesh make_displaced_sphere(int levels) {
    TriangleMesh m = make_icosphere(levels);
    for (Vec3f& p : m.positions) p *= 1.0f + displacement(p);
    return m;
}

TriangleMesh make_ground_plane(float half_size, float height) {
    TriangleMesh m;
    m.positions = {{-half_size, height, -half_size},
                   {half_size, height, -half_size},
                   {half_size, height, half_size},
                   {-half_size, height, half_size}};
    m.triangles = {{0, 2, 1}, {0, 3, 2}};
    return m;
}

Scene make_default_scene() {
    Scene scene;
    scene.name = "default";

    MeshInstance sphere;
    sphere.file = "builtin:displaced_sphere";
    // Level 7: 20 * 4^7 = 327,680 triangles.
    sphere.mesh = std::make_shared<const TriangleMesh>(make_displaced_sphere(7));
    sphere.world_from_object = glm::mat4(1.0f);
    sphere.world_from_object[3] = Vec4f(0.0f, 1.0f, 0.0f, 1.0f);
    sphere.material.type = MaterialType::diffuse;
    sphere.material.albedo = Vec3f(0.75f, 0.55f, 0.35f);
    sphere.smooth = true;
    scene.meshes.push_back(sphere);

    MeshInstance ground;
    ground.file = "builtin:ground_plane";
    ground.mesh = std::make_shared<const TriangleMesh>(make_ground_plane(20.0f, 0.0f));
    ground.material.type = MaterialType::diffuse;
    ground.material.albedo = Vec3f(0.5f);
    ground.smooth = false;
    scene.meshes.push_back(ground);

    scene.camera.eye = Vec3f(2.6f, 1.9f, 3.4f);
    scene.camera.target = Vec3f(0.0f, 0.85f, 0.0f);
    scene.camera.up = Vec3f(0.0f, 1.0f, 0.0f);
    scene.camera.vfov_degrees = 40.0f;

    // A bluish sky of constant radiance.
    scene.environment.color = Vec3f(0.75f, 0.85f, 1.0f);
    return scene;
}

}  // namespace kdt
