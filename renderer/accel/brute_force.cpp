#include "renderer/accel/brute_force.h"

#include "renderer/geometry/intersect.h"

namespace kdt {

Hit brute_force_hit(const TriangleMesh& mesh, const Ray& ray) {
    Hit hit;
    if (!is_finite(ray.origin) || !is_finite(ray.dir) || ray.dir == Vec3f(0.0f)) return hit;
    WatertightRay wr(ray.origin, ray.dir);
    float best = ray.tmax;
    for (size_t i = 0; i < mesh.triangles.size(); ++i) {
        const Vec3u& t = mesh.triangles[i];
        float tt, u, v;
        if (intersect_triangle(wr, mesh.positions[t.x], mesh.positions[t.y], mesh.positions[t.z],
                               ray.tmin, best, tt, u, v)) {
            best = tt;
            hit.t = tt;
            hit.u = u;
            hit.v = v;
            hit.prim = uint32_t(i);
        }
    }
    return hit;
}

}  // namespace kdt
