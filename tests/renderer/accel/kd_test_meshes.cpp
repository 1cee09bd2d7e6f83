#include "tests/renderer/accel/kd_test_meshes.h"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <string>

#include "renderer/core/error.h"
#include "renderer/geometry/intersect.h"
#include "renderer/io/mesh_io.h"
#include "tests/test_util.h"

namespace kdt::test {

TriangleMesh make_blob(int levels, float radius, uint32_t seed) {
    TriangleMesh octa;
    octa.positions = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    octa.triangles = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                      {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
    TriangleMesh m = subdivide_mesh(octa, levels);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> r(0.7f, 1.3f);
    for (Vec3f& p : m.positions) p = glm::normalize(p) * (r(rng) * radius);
    return m;
}

TriangleMesh make_soup(size_t n, float size, uint32_t seed) {
    TriangleMesh m;
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> c(-1.0f, 1.0f), e(-0.5f, 0.5f);
    for (size_t i = 0; i < n; ++i) {
        Vec3f p(c(rng), c(rng), c(rng));
        const auto base = uint32_t(m.positions.size());
        m.positions.push_back(p);
        m.positions.push_back(p + size * Vec3f(e(rng), e(rng), e(rng)));
        m.positions.push_back(p + size * Vec3f(e(rng), e(rng), e(rng)));
        m.triangles.push_back({base, base + 1, base + 2});
    }
    return m;
}

TriangleMesh make_planar_grid(int n, uint32_t seed) {
    TriangleMesh m;
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> j(-0.25f, 0.25f);
    for (int layer = 0; layer < 2; ++layer) {
        const auto base = uint32_t(m.positions.size());
        for (int y = 0; y <= n; ++y)
            for (int x = 0; x <= n; ++x)
                m.positions.push_back(layer == 0 ? Vec3f(float(x), float(y), 0.0f)
                                                 : Vec3f(float(x), float(y), 2.0f + j(rng)));
        auto id = [&](int x, int y) { return base + uint32_t(y * (n + 1) + x); };
        for (int y = 0; y < n; ++y)
            for (int x = 0; x < n; ++x) {
                m.triangles.push_back({id(x, y), id(x + 1, y), id(x + 1, y + 1)});
                m.triangles.push_back({id(x, y), id(x + 1, y + 1), id(x, y + 1)});
            }
    }
    return m;
}

bool same_closest_hit(const TriangleMesh& mesh, const Ray& ray, const Hit& hit, const Hit& ref) {
    if (hit.valid() != ref.valid()) return false;
    if (!hit.valid()) return true;
    if (!(std::fabs(hit.t - ref.t) <= 1e-6f * std::fabs(ref.t))) return false;
    if (hit.prim == ref.prim) return true;
    Ray tie = ray;
    tie.tmax = ref.t;
    float t, u, v;
    const Vec3u& tri = mesh.triangles[hit.prim];
    return intersect_triangle(tie, mesh.positions[tri.x], mesh.positions[tri.y],
                              mesh.positions[tri.z], t, u, v) &&
           t == ref.t;
}

bool bitwise_equal(const Hit& a, const Hit& b) {
    return a.prim == b.prim && std::memcmp(&a.t, &b.t, sizeof a.t) == 0 &&
           std::memcmp(&a.u, &b.u, sizeof a.u) == 0 && std::memcmp(&a.v, &b.v, sizeof a.v) == 0;
}

bool brute_force_occluded(const TriangleMesh& mesh, const Ray& ray) {
    if (!is_finite(ray.origin) || !is_finite(ray.dir) || ray.dir == Vec3f(0.0f)) return false;
    WatertightRay wr(ray.origin, ray.dir);
    for (const Vec3u& t : mesh.triangles) {
        float tt, u, v;
        if (intersect_triangle(wr, mesh.positions[t.x], mesh.positions[t.y], mesh.positions[t.z],
                               ray.tmin, ray.tmax, tt, u, v))
            return true;
    }
    return false;
}

std::shared_ptr<const KdTree> try_build(std::shared_ptr<const TriangleMesh> mesh,
                                        const KdTreeParams& params) {
    try {
        return build_kdtree(std::move(mesh), params);
    } catch (const Error& e) {
        if (std::string(e.what()).find("not built yet") != std::string::npos) return nullptr;
        throw;
    }
}

std::vector<Ray> grid_line_rays(int axis, float sign, float zero) {
    std::vector<Ray> rays;
    for (int y = 0; y <= 24; ++y) {
        for (int x = 0; x <= 24; ++x) {
            for (float z : {-1.0f, 0.0f, 1.0f, 3.0f}) {
                Ray r;
                r.origin = Vec3f(0.5f * float(x) - 0.5f, 0.5f * float(y) - 0.5f, z);
                r.dir = Vec3f(zero);
                r.dir[axis] = sign;
                rays.push_back(r);
            }
        }
    }
    return rays;
}

void spoil_rays(std::vector<Ray>& rays, size_t stride, int kinds) {
    constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
    constexpr float kInf = std::numeric_limits<float>::infinity();
    for (size_t i = 0; i < rays.size(); i += stride) {
        switch ((i / stride) % size_t(kinds)) {
            case 0:
                rays[i].dir.x = kNaN;
                break;
            case 1:
                rays[i].origin.y = kInf;
                break;
            case 2:
                rays[i].dir = Vec3f(0.0f);
                break;
            case 3:
                rays[i].tmax = -1.0f;
                break;
            case 4:
                rays[i].tmax = 1e-3f;
                break;
            case 5:
                rays[i].tmin = kNaN;
                break;
            case 6:
                rays[i].dir *= 1e30f;
                break;
            case 7:
                rays[i].dir *= 1e-30f;
                break;
        }
    }
}

std::shared_ptr<const TriangleMesh> load_dragon_res2() {
    const auto dir = dragon_dir();
    if (dir.empty() || !std::filesystem::exists(dir / "dragon_vrip_res2.ply")) return nullptr;
    return std::make_shared<const TriangleMesh>(load_mesh((dir / "dragon_vrip_res2.ply").string()));
}

}  // namespace kdt::test
