#include "renderer/geometry/intersect.h"

#include "renderer/geometry/mesh.h"

#include <random>

#include <gtest/gtest.h>

namespace kdt {
namespace {

TEST(IntersectTriangle, HitsCentreWithBarycentrics) {
    Ray ray;
    ray.origin = Vec3f(0.25f, 0.25f, -2.0f);
    ray.dir = Vec3f(0.0f, 0.0f, 1.0f);
    float t = -1, u = -1, v = -1;
    ASSERT_TRUE(intersect_triangle(ray, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, t, u, v));
    EXPECT_FLOAT_EQ(t, 2.0f);
    EXPECT_FLOAT_EQ(u, 0.25f);
    EXPECT_FLOAT_EQ(v, 0.25f);
    // Two-sided: the same from behind.
    ray.origin.z = 2.0f;
    ray.dir.z = -1.0f;
    ASSERT_TRUE(intersect_triangle(ray, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, t, u, v));
    EXPECT_FLOAT_EQ(t, 2.0f);
}

TEST(IntersectTriangle, MissesOutsideAndOutsideInterval) {
    Ray ray;
    ray.origin = Vec3f(0.75f, 0.75f, -2.0f);
    float t = -1, u, v;
    EXPECT_FALSE(intersect_triangle(ray, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, t, u, v));
    ray.origin = Vec3f(0.25f, 0.25f, -2.0f);
    ray.tmax = 1.5f;
    EXPECT_FALSE(intersect_triangle(ray, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, t, u, v));
    ray.tmax = kInfinity;
    ray.tmin = 2.5f;
    EXPECT_FALSE(intersect_triangle(ray, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, t, u, v));
    EXPECT_EQ(t, -1.0f);
}

TEST(IntersectTriangle, DegenerateAndBadRaysNeverHit) {
    Ray ray;
    ray.origin = Vec3f(0.0f, 0.0f, -1.0f);
    float t, u, v;
    // Zero area: repeated vertex, collinear vertices.
    EXPECT_FALSE(intersect_triangle(ray, {0, 0, 0}, {0, 0, 0}, {1, 1, 0}, t, u, v));
    EXPECT_FALSE(intersect_triangle(ray, {-1, -1, 0}, {0, 0, 0}, {1, 1, 0}, t, u, v));
    // Edge-on: the ray lies in the triangle's plane.
    EXPECT_FALSE(intersect_triangle(ray, {0, -1, -2}, {0, 1, -2}, {0, 0, 5}, t, u, v));
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (Vec3f d : {Vec3f(nan, 0, 1), Vec3f(0, kInfinity, 1), Vec3f(0, 0, 0)}) {
        ray.dir = d;
        EXPECT_FALSE(intersect_triangle(ray, {-1, -1, 0}, {1, -1, 0}, {0, 1, 0}, t, u, v));
    }
}

// A closed, star-shaped mesh (subdivided octahedron with jittered radii): rays from random
// interior points aimed exactly at every vertex and every edge midpoint must hit at least
// one triangle. A ray aimed at a vertex passes within an ulp of it, i.e. through a shared
// vertex or edge, where a non-watertight test lets rays slip through.
TEST(IntersectTriangle, WatertightOnSharedVerticesAndEdges) {
    TriangleMesh octa;
    octa.positions = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    octa.triangles = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                      {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
    TriangleMesh m = subdivide_mesh(octa, 3);
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> radius(0.7f, 1.3f), o(-0.2f, 0.2f);
    for (Vec3f& p : m.positions) p = glm::normalize(p) * radius(rng) * 3.0f;
    std::vector<Vec3f> targets = m.positions;
    for (const Vec3u& t : m.triangles)
        for (int k = 0; k < 3; ++k)
            targets.push_back(0.5f * (m.positions[t[k]] + m.positions[t[(k + 1) % 3]]));
    int escapes = 0;
    for (int rep = 0; rep < 10; ++rep) {
        for (const Vec3f& target : targets) {
            Vec3f origin(o(rng), o(rng), o(rng));
            WatertightRay wr(origin, target - origin);
            bool hit = false;
            for (const Vec3u& tri : m.triangles) {
                float t, u, v;
                if (intersect_triangle(wr, m.positions[tri.x], m.positions[tri.y],
                                       m.positions[tri.z], 0.0f, kInfinity, t, u, v)) {
                    hit = true;
                    break;
                }
            }
            escapes += hit ? 0 : 1;
        }
    }
    EXPECT_EQ(escapes, 0);
}

TEST(IntersectBox, ClosedBoxIncludingFacesAndZeroComponents) {
    Bounds3f box{Vec3f(0.0f), Vec3f(1.0f)};
    Ray ray;
    ray.origin = Vec3f(0.5f, 0.5f, -1.0f);
    float t0, t1;
    ASSERT_TRUE(intersect_box(ray, box, t0, t1));
    EXPECT_NEAR(t0, 1.0f, 1e-5f);
    EXPECT_NEAR(t1, 2.0f, 1e-5f);
    // In the plane of a face, parallel to it.
    ray.origin = Vec3f(1.0f, 0.5f, -1.0f);
    EXPECT_TRUE(intersect_box(ray, box, t0, t1));
    ray.origin = Vec3f(std::nextafter(1.0f, 2.0f), 0.5f, -1.0f);
    EXPECT_FALSE(intersect_box(ray, box, t0, t1));
    // Exactly through a corner, diagonally.
    ray.origin = Vec3f(-1.0f, -1.0f, 0.5f);
    ray.dir = Vec3f(1.0f, 1.0f, 0.0f);
    EXPECT_TRUE(intersect_box(ray, box, t0, t1));
    ray.origin = Vec3f(2.0f, 0.0f, 0.5f);
    ray.dir = Vec3f(-1.0f, 1.0f, 0.0f);  // touches the corner (1, 1) only
    EXPECT_TRUE(intersect_box(ray, box, t0, t1));
    // Behind the origin.
    ray.origin = Vec3f(0.5f, 0.5f, 3.0f);
    ray.dir = Vec3f(0.0f, 0.0f, 1.0f);
    EXPECT_FALSE(intersect_box(ray, box, t0, t1));
}

TEST(ClipTriangle, BoundsOfClippedPart) {
    Bounds3f box{Vec3f(0.0f), Vec3f(1.0f)};
    // Large triangle in z = 0.5 covering the whole box cross-section.
    Bounds3f b = clip_triangle_bounds({-10, -10, 0.5f}, {10, -10, 0.5f}, {0, 10, 0.5f}, box);
    ASSERT_FALSE(b.empty());
    EXPECT_EQ(b.lower.x, 0.0f);
    EXPECT_EQ(b.upper.y, 1.0f);
    EXPECT_NEAR(b.lower.z, 0.5f, 1e-6f);
    EXPECT_NEAR(b.upper.z, 0.5f, 1e-6f);
    EXPECT_LE(b.lower.z, 0.5f);
    EXPECT_GE(b.upper.z, 0.5f);
    // A sloped triangle cut by the box: the clipped part is narrower than its bounds.
    b = clip_triangle_bounds({0.5f, 0.5f, 0.5f}, {3.0f, 0.5f, 0.5f}, {0.5f, 3.0f, 0.5f}, box);
    EXPECT_NEAR(b.upper.x, 1.0f, 1e-6f);
    EXPECT_NEAR(b.lower.x, 0.5f, 1e-6f);
    // Disjoint.
    EXPECT_TRUE(clip_triangle_bounds({2, 2, 2}, {3, 2, 2}, {2, 3, 2}, box).empty());
    EXPECT_FALSE(triangle_overlaps_box({2, 2, 2}, {3, 2, 2}, {2, 3, 2}, box));
    // Touching a corner with one vertex.
    EXPECT_TRUE(triangle_overlaps_box({1, 1, 1}, {3, 2, 2}, {2, 3, 2}, box));
    // Passing outside a corner: bounds overlap, the triangle does not.
    EXPECT_TRUE(
        triangle_overlaps_box({1.5f, 0.0f, 0.5f}, {0.0f, 1.5f, 0.5f}, {3.0f, 3.0f, 0.5f}, box));
    EXPECT_FALSE(
        triangle_overlaps_box({2.5f, 0.0f, 0.5f}, {0.0f, 2.5f, 0.5f}, {3.0f, 3.0f, 0.5f}, box));
}

}  // namespace
}  // namespace kdt
