#include "app/bench/bench_rays.h"

#include <cmath>
#include <cstdlib>

#include "renderer/core/error.h"
#include "renderer/material/material.h"
#include "renderer/render/snapshot.h"

namespace kdt::app {
namespace {

uint64_t splitmix64(uint64_t x) {
    x += 0x9e3779b97f4a7c15ull;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
    return x ^ (x >> 31);
}

}  // namespace

float hash_uniform(uint64_t a, uint64_t b, uint64_t c, uint64_t d) {
    uint64_t h = splitmix64(a);
    h = splitmix64(h ^ b);
    h = splitmix64(h ^ c);
    h = splitmix64(h ^ d);
    // 24 high bits: exactly representable, strictly below 1.
    return float(h >> 40) * 0x1.0p-24f;
}

std::vector<Ray> make_primary_rays(const ViewSet& set, size_t view_index) {
    const int w = set.width, h = set.height, spp = set.samples_per_pixel;
    const Camera camera = make_camera(set.views.at(view_index).camera, w, h);
    constexpr int kTile = 8;
    std::vector<Ray> rays;
    rays.reserve(size_t(w) * size_t(h) * size_t(spp));
    for (int ty = 0; ty < h; ty += kTile) {
        for (int tx = 0; tx < w; tx += kTile) {
            for (int y = ty; y < std::min(h, ty + kTile); ++y) {
                for (int x = tx; x < std::min(w, tx + kTile); ++x) {
                    const uint64_t pixel = uint64_t(y) * uint64_t(w) + uint64_t(x);
                    for (int s = 0; s < spp; ++s) {
                        const float jx = hash_uniform(set.seed, view_index, pixel, 2 * uint64_t(s));
                        const float jy =
                            hash_uniform(set.seed, view_index, pixel, 2 * uint64_t(s) + 1);
                        rays.push_back(camera.generate_ray(Vec2f(float(x) + jx, float(y) + jy)));
                    }
                }
            }
        }
    }
    return rays;
}

std::vector<Ray> make_diffuse_rays(const TriangleMesh& mesh, const std::vector<Ray>& rays,
                                   const std::vector<Hit>& hits, uint64_t seed,
                                   std::vector<uint32_t>* sources) {
    std::vector<Ray> out;
    out.reserve(rays.size());
    if (sources) sources->clear();
    for (size_t i = 0; i < rays.size(); ++i) {
        const Hit& hit = hits[i];
        if (!hit.valid() || hit.prim >= mesh.triangle_count()) continue;
        const Vec3u t = mesh.triangles[hit.prim];
        const Vec3f p0 = mesh.positions[t.x], p1 = mesh.positions[t.y], p2 = mesh.positions[t.z];
        // The hit point from barycentrics is accurate to a few ULPs of the vertices; o + t d
        // would carry the error of t times the ray length.
        const Vec3f p = (1.0f - hit.u - hit.v) * p0 + hit.u * p1 + hit.v * p2;
        Vec3f n = glm::cross(p1 - p0, p2 - p0);
        const float len = glm::length(n);
        if (!(len > 0.0f) || !std::isfinite(len)) continue;
        n /= len;
        if (glm::dot(n, rays[i].dir) > 0.0f) n = -n;
        // Offset by 16 ULPs of the largest coordinate of p: scales with the position, not
        // with the scene (Wächter & Binder 2019 argue the same in integer ULP space).
        const float m = std::max({std::fabs(p.x), std::fabs(p.y), std::fabs(p.z)});
        const float offset = std::max(m, 1e-30f) * 0x1.0p-19f;
        Ray r;
        r.origin = p + offset * n;
        // Cosine-distributed direction about n, with the path tracer's own sampling.
        const Vec3f local = sample_cosine_hemisphere(
            {hash_uniform(seed, 0x5eed, i, 0), hash_uniform(seed, 0x5eed, i, 1)});
        Vec3f b1, b2;
        make_basis(n, b1, b2);
        r.dir = glm::normalize(local.x * b1 + local.y * b2 + local.z * n);
        out.push_back(r);
        if (sources) sources->push_back(uint32_t(i));
    }
    return out;
}

}  // namespace kdt::app
