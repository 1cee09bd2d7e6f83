// Closest-hit and any-hit queries: iterative, stack-based, front-to-back kd-tree traversal
// with the ray interval clipped at each split (Havran's TA_rec_B family; the thesis's
// section 5.3.1 in iterative form), and the watertight triangle test in the leaves.
//
// Robustness: planes are crossed at t = (split - o) / d, computed in float. Decisions that
// skip a child compare against the current interval widened by kIntervalSlack, so a child
// the ray really touches is never skipped; together with the builder's closed
// classification (triangles touching a plane are on both sides) no hit can slip between
// leaves. A hit beyond the current leaf does not end the search (the thesis's figure 3):
// the search ends when every remaining node starts beyond the closest hit.
#include <cmath>

#include "renderer/accel/kdtree.h"
#include "renderer/geometry/intersect.h"

namespace kdt {
namespace {

constexpr int kStackSize = 68;  // one entry per level; trees are at most 64 deep

struct StackItem {
    uint32_t node;
    float t0, t1;
};

inline float lower_slack(float t) { return t - kIntervalSlack * std::fabs(t); }
inline float upper_slack(float t) { return t + kIntervalSlack * std::fabs(t); }

// Per-ray constants of the traversal and of the triangle test.
struct RayState {
    Vec3f origin, dir, inv_dir;
    uint32_t dir_neg[3];   // 1 if the ray runs toward -axis: then the right child is near
    float t_scale = 1.0f;  // internal t times t_scale = caller's t
    WatertightRay wr;
};

// Rejects non-finite or zero-direction rays and clips the interval to the root box.
// Directions with extreme magnitudes are rescaled by a power of two (exact), so
// 1 / d and the distances stay finite. Returns false on a certain miss.
inline bool setup_ray(const Ray& ray, const Bounds3f& bounds, RayState& rs, float& t0, float& t1) {
    if (!is_finite(ray.origin) || !is_finite(ray.dir) || std::isnan(ray.tmin) ||
        std::isnan(ray.tmax) || !(ray.tmin <= ray.tmax) || bounds.empty())
        return false;
    // Zero components become -0 so that 1/d = -inf and dir_neg agree on the sign.
    Vec3f d = ray.dir;
    const float m = std::max(std::fabs(d.x), std::max(std::fabs(d.y), std::fabs(d.z)));
    if (!(m > 0.0f)) return false;
    t0 = ray.tmin;
    t1 = ray.tmax;
    if (m < 0x1p-40f || m > 0x1p40f) {
        int e;
        std::frexp(m, &e);
        d = Vec3f(std::ldexp(d.x, -e), std::ldexp(d.y, -e), std::ldexp(d.z, -e));
        rs.t_scale = std::ldexp(1.0f, -e);
        t0 = std::ldexp(t0, e);
        t1 = std::ldexp(t1, e);
    }
    for (int k = 0; k < 3; ++k)
        if (d[k] == 0.0f) d[k] = -0.0f;
    rs.origin = ray.origin;
    rs.dir = d;
    rs.inv_dir = 1.0f / d;
    for (int k = 0; k < 3; ++k) rs.dir_neg[k] = std::signbit(d[k]) ? 1u : 0u;
    if (!intersect_box(rs.origin, d, rs.inv_dir, bounds, t0, t1)) return false;
    rs.wr = WatertightRay(rs.origin, d);
    return true;
}

template <bool kAnyHit, bool kCount>
bool traverse(const KdNode* nodes, const uint32_t* indices, const Vec3f* positions,
              const Vec3u* triangles, const RayState& rs, float t0, float t1, float tmin,
              float tmax, Hit* hit, TraversalCounters* counters) {
    StackItem stack[kStackSize];
    int sp = 0;
    uint32_t idx = 0;
    float best_t = tmax, best_u = 0.0f, best_v = 0.0f;
    uint32_t best_prim = Hit::kNoHit;
    uint64_t visited = 0, tested = 0;
    for (;;) {
        KdNode node = nodes[idx];
        if (kCount) ++visited;
        while (!node.is_leaf()) {
            const int axis = node.axis();
            const float ts = (node.split - rs.origin[axis]) * rs.inv_dir[axis];
            const uint32_t first = node.child();
            const uint32_t near_child = first + rs.dir_neg[axis];
            const uint32_t far_child = first + 1 - rs.dir_neg[axis];
            // A ray lying in the plane (origin on it, d = 0: t = 0 * inf = NaN) visits both
            // sides: a builder may reference a triangle that only touches the plane from
            // either side. Comparisons are written so that NaN means "visit".
            const bool visit_near = !(ts < lower_slack(t0));
            const bool visit_far = !(ts > upper_slack(t1));
            if (visit_near && visit_far) {
                if (sp < kStackSize) stack[sp++] = {far_child, ts > t0 ? ts : t0, t1};
                idx = near_child;
                t1 = ts < t1 ? ts : t1;
            } else {
                idx = visit_near ? near_child : far_child;
            }
            node = nodes[idx];
            if (kCount) ++visited;
        }
        const uint32_t count = node.count();
        const uint32_t* ids = indices + node.first;
        for (uint32_t i = 0; i < count; ++i) {
            const uint32_t prim = ids[i];
            const Vec3u& tri = triangles[prim];
            float t, u, v;
            if (kCount) ++tested;
            if (intersect_triangle(rs.wr, positions[tri.x], positions[tri.y], positions[tri.z],
                                   tmin, best_t, t, u, v)) {
                if (kAnyHit) {
                    if (kCount) {
                        counters->nodes_visited += visited;
                        counters->triangles_tested += tested;
                    }
                    return true;
                }
                best_t = t;
                best_u = u;
                best_v = v;
                best_prim = prim;
            }
        }
        // Next node front to back; skip those starting beyond the closest hit.
        bool next = false;
        while (sp > 0) {
            const StackItem& s = stack[--sp];
            if (lower_slack(s.t0) <= best_t) {
                idx = s.node;
                t0 = s.t0;
                t1 = std::min(s.t1, best_t);
                next = true;
                break;
            }
        }
        if (!next) break;
    }
    if (kCount) {
        counters->nodes_visited += visited;
        counters->triangles_tested += tested;
    }
    if (kAnyHit || best_prim == Hit::kNoHit) return false;
    hit->t = best_t * rs.t_scale;
    hit->u = best_u;
    hit->v = best_v;
    hit->prim = best_prim;
    return true;
}

// Sets up the ray and dispatches to the traversal with or without cost counters.
template <bool kAnyHit>
bool query(const TriangleMesh* mesh, const Bounds3f& bounds, const std::vector<KdNode>& nodes,
           const std::vector<uint32_t>& indices, const Ray& ray, Hit* hit,
           TraversalCounters* counters) {
    RayState rs;
    float t0, t1;
    if (!mesh || !setup_ray(ray, bounds, rs, t0, t1)) return false;
    const float tmin = ray.tmin / rs.t_scale, tmax = ray.tmax / rs.t_scale;
    if (counters)
        return traverse<kAnyHit, true>(nodes.data(), indices.data(), mesh->positions.data(),
                                       mesh->triangles.data(), rs, t0, t1, tmin, tmax, hit,
                                       counters);
    return traverse<kAnyHit, false>(nodes.data(), indices.data(), mesh->positions.data(),
                                    mesh->triangles.data(), rs, t0, t1, tmin, tmax, hit, nullptr);
}

}  // namespace

bool KdTree::intersect(const Ray& ray, Hit& hit, TraversalCounters* counters) const {
    hit = Hit{};
    return query<false>(mesh_.get(), bounds_, nodes_, indices_, ray, &hit, counters);
}

bool KdTree::occluded(const Ray& ray, TraversalCounters* counters) const {
    return query<true>(mesh_.get(), bounds_, nodes_, indices_, ray, nullptr, counters);
}

}  // namespace kdt
