// Hard cases for the traversal with both builders: rays aimed exactly at vertices and edge
// midpoints of closed meshes (zero escapes, also far from the origin and at extreme
// scales), axis-aligned and grazing rays, planar and degenerate geometry, bad rays,
// extreme parameters.
#include <cmath>
#include <limits>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "renderer/accel/kdtree.h"
#include "renderer/core/error.h"
#include "renderer/geometry/intersect.h"
#include "tests/renderer/accel/kd_test_meshes.h"

namespace kdt {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

class Traversal : public ::testing::TestWithParam<KdBuilder> {
protected:
    KdTreeParams params() const {
        KdTreeParams p;
        p.builder = GetParam();
        return p;
    }
    std::shared_ptr<const KdTree> build(TriangleMesh mesh, KdTreeParams p) {
        p.builder = GetParam();
        return test::try_build(std::make_shared<TriangleMesh>(std::move(mesh)), p);
    }
};

#define BUILD_OR_SKIP(tree, mesh, p)                                    \
    auto tree = build(mesh, p);                                         \
    if (!tree) GTEST_SKIP() << "SAH builder not built yet (it throws)"; \
    do {                                                                \
    } while (0)

// Same verdict as brute force; t within 1e-6 relative.
void expect_matches_brute_force(const KdTree& tree, const Ray& r, const std::string& what) {
    const Hit ref = test::brute_force_hit(tree.mesh(), r);
    Hit hit;
    const bool got = tree.intersect(r, hit);
    ASSERT_EQ(got, ref.valid()) << what;
    ASSERT_EQ(tree.occluded(r), ref.valid()) << what;
    if (got) {
        ASSERT_LE(std::fabs(hit.t - ref.t), 1e-6f * std::fabs(ref.t)) << what;
    }
}

struct Escapes {
    size_t rays = 0, escapes = 0;
};

// Rays from random interior points of a closed star-shaped mesh (centred on `centre`,
// radius about `radius`) aimed exactly at every vertex and every edge midpoint.
Escapes shoot_at_vertices_and_edges(const KdTree& tree, Vec3f centre, float radius, size_t min_rays,
                                    uint32_t seed) {
    const TriangleMesh& m = tree.mesh();
    std::vector<Vec3f> targets = m.positions;
    for (const Vec3u& t : m.triangles)
        for (int k = 0; k < 3; ++k) {
            const uint32_t a = t[k], b = t[(k + 1) % 3];
            if (a < b) targets.push_back(0.5f * (m.positions[a] + m.positions[b]));
        }
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-0.25f, 0.25f);
    Escapes e;
    while (e.rays < min_rays) {
        for (const Vec3f& target : targets) {
            Ray r;
            r.origin = centre + radius * Vec3f(u(rng), u(rng), u(rng));
            r.dir = target - r.origin;
            Hit hit;
            const bool ok = (e.rays & 1) ? tree.occluded(r) : tree.intersect(r, hit);
            e.escapes += ok ? 0 : 1;
            ++e.rays;
        }
    }
    return e;
}

TEST_P(Traversal, VertexAndEdgeAimedRaysNeverEscape) {
    BUILD_OR_SKIP(tree, test::make_blob(5, 1.0f, 21), params());  // 8192 triangles
    const Escapes e = shoot_at_vertices_and_edges(*tree, Vec3f(0.0f), 1.0f, 1000000, 1);
    EXPECT_GE(e.rays, 1000000u);
    EXPECT_EQ(e.escapes, 0u);
}

TEST_P(Traversal, VertexAndEdgeAimedRaysNeverEscapeTranslatedAndScaled) {
    struct Case {
        const char* name;
        float scale;
        Vec3f offset;
    };
    const Case cases[] = {{"translated by 1e5", 1.0f, Vec3f(1e5f, -1e5f, 1e5f)},
                          {"scaled by 1e-3", 1e-3f, Vec3f(0.0f)},
                          {"scaled by 1e4", 1e4f, Vec3f(0.0f)},
                          {"scaled by 1e-3, translated by 1", 1e-3f, Vec3f(1.0f, 2.0f, 3.0f)}};
    for (const Case& c : cases) {
        TriangleMesh m = test::make_blob(4, c.scale, 22);
        for (Vec3f& p : m.positions) p += c.offset;
        BUILD_OR_SKIP(tree, m, params());
        const Escapes e = shoot_at_vertices_and_edges(*tree, c.offset, c.scale, 200000, 2);
        EXPECT_EQ(e.escapes, 0u) << c.name << ": " << e.escapes << " of " << e.rays;
    }
}

TEST_P(Traversal, AxisAlignedRaysOnGridLinesAndInPlanes) {
    BUILD_OR_SKIP(tree, test::make_planar_grid(12, 5), params());
    int checked = 0;
    for (int y = 0; y <= 24; ++y)
        for (int x = 0; x <= 24; ++x) {
            const Vec3f o(0.5f * float(x) - 0.5f, 0.5f * float(y) - 0.5f, 0.0f);
            for (float z : {-1.0f, 0.0f, 1.0f, 3.0f}) {
                for (int axis = 0; axis < 3; ++axis)
                    for (float sign : {-1.0f, 1.0f}) {
                        Ray r;
                        r.origin = Vec3f(o.x, o.y, z);
                        r.dir = Vec3f(0.0f);
                        r.dir[axis] = sign;
                        expect_matches_brute_force(*tree, r, "axis ray " + std::to_string(checked));
                        ++checked;
                        // The same with -0 components and a non-unit length.
                        r.dir = -0.0f * Vec3f(1.0f);
                        r.dir[axis] = 3.0f * sign;
                        expect_matches_brute_force(*tree, r,
                                                   "axis ray -0 " + std::to_string(checked));
                    }
            }
        }
    EXPECT_GT(checked, 10000);
}

TEST_P(Traversal, GrazingRays) {
    BUILD_OR_SKIP(tree, test::make_planar_grid(16, 6), params());
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(0.0f, 16.0f), s(-1.0f, 1.0f);
    size_t hits = 0;
    for (int i = 0; i < 20000; ++i) {
        Ray r;
        const float eps = std::ldexp(1.0f, -int(rng() % 30));  // slopes from 1 down to 2^-29
        r.origin = Vec3f(u(rng), u(rng), (i & 1 ? 1.0f : -1.0f) * eps * u(rng));
        r.dir = glm::normalize(Vec3f(s(rng), s(rng), 0.0f));
        r.dir.z = (r.origin.z > 0 ? -eps : eps) * (0.5f + 0.5f * s(rng));
        expect_matches_brute_force(*tree, r, "grazing ray " + std::to_string(i));
        Hit h;
        hits += tree->intersect(r, h);
    }
    EXPECT_GT(hits, 3000u);  // the comparison is not vacuous
}

TEST_P(Traversal, DegenerateTrianglesAreHarmless) {
    TriangleMesh m = test::make_soup(400, 0.4f, 7);
    std::mt19937 rng(8);
    const auto nv = uint32_t(m.positions.size());
    for (int i = 0; i < 300; ++i) {
        const uint32_t a = rng() % nv, b = rng() % nv;
        m.triangles.push_back({a, a, b});  // repeated vertex
        m.triangles.push_back({a, a, a});
        const Vec3f p = m.positions[a], q = m.positions[b];
        const auto base = uint32_t(m.positions.size());
        m.positions.push_back(p);
        m.positions.push_back(0.5f * (p + q));  // collinear: zero area
        m.positions.push_back(q);
        m.triangles.push_back({base, base + 1, base + 2});
    }
    BUILD_OR_SKIP(tree, m, params());
    std::mt19937 r2(9);
    std::uniform_real_distribution<float> u(-1.5f, 1.5f);
    for (int i = 0; i < 5000; ++i) {
        Ray r;
        r.origin = Vec3f(u(r2), u(r2), u(r2));
        r.dir = Vec3f(u(r2), u(r2), u(r2));
        expect_matches_brute_force(*tree, r, "ray " + std::to_string(i));
    }
}

TEST_P(Traversal, ThousandsOfIdenticalTriangles) {
    TriangleMesh m;
    m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    for (int i = 0; i < 5000; ++i) m.triangles.push_back({0, 1, 2});
    // And copies with their own (equal) vertices.
    for (int i = 0; i < 2000; ++i) {
        const auto b = uint32_t(m.positions.size());
        m.positions.insert(m.positions.end(), {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
        m.triangles.push_back({b, b + 1, b + 2});
    }
    BUILD_OR_SKIP(tree, m, params());
    EXPECT_LT(tree->stats().nodes, 1000u);
    Ray r;
    r.origin = Vec3f(0.2f, 0.2f, 1.0f);
    r.dir = Vec3f(0.0f, 0.0f, -1.0f);
    Hit h;
    ASSERT_TRUE(tree->intersect(r, h));
    EXPECT_FLOAT_EQ(h.t, 1.0f);
    EXPECT_TRUE(tree->occluded(r));
    r.origin.x = 0.9f;
    EXPECT_FALSE(tree->intersect(r, h));
    EXPECT_FALSE(h.valid());
}

TEST_P(Traversal, EmptyMeshAndNonFiniteVertices) {
    BUILD_OR_SKIP(empty, TriangleMesh{}, params());
    EXPECT_EQ(empty->stats().nodes, 1u);
    Ray r;
    Hit h;
    EXPECT_FALSE(empty->intersect(r, h));
    EXPECT_FALSE(empty->occluded(r));

    TriangleMesh m = test::make_soup(200, 0.4f, 4);
    m.positions[0] = Vec3f(kNaN, 0.0f, 0.0f);
    m.positions[4] = Vec3f(0.0f, kInfinity, 0.0f);
    BUILD_OR_SKIP(tree, m, params());
    for (uint32_t id : tree->indices()) EXPECT_GT(id, 1u);  // triangles 0 and 1: never referenced
    EXPECT_TRUE(is_finite(tree->bounds().lower) && is_finite(tree->bounds().upper));
    r.origin = Vec3f(0.0f, 0.0f, -3.0f);
    for (int i = 0; i < 200; ++i) {
        r.dir = Vec3f(std::sin(0.1f * float(i)), std::cos(0.37f * float(i)), 3.0f);
        Hit a;
        tree->intersect(r, a);  // must not crash; finite triangles still hit
        if (a.valid()) {
            EXPECT_GT(a.prim, 1u);
        }
    }
}

TEST_P(Traversal, NonFiniteAndExtremeRays) {
    BUILD_OR_SKIP(tree, test::make_blob(4, 1.0f, 5), params());
    Ray good;
    good.origin = Vec3f(0.1f, 0.2f, -5.0f);
    good.dir = Vec3f(0.0f, 0.0f, 1.0f);
    Hit h;
    ASSERT_TRUE(tree->intersect(good, h));
    const float t_ref = h.t;

    auto expect_miss = [&](Ray r, const char* what) {
        Hit hit;
        EXPECT_FALSE(tree->intersect(r, hit)) << what;
        EXPECT_FALSE(hit.valid()) << what;
        EXPECT_FALSE(tree->occluded(r)) << what;
    };
    for (int k = 0; k < 3; ++k) {
        Ray r = good;
        r.origin[k] = kNaN;
        expect_miss(r, "NaN origin");
        r = good;
        r.dir[k] = kNaN;
        expect_miss(r, "NaN direction");
        r = good;
        r.origin[k] = -kInfinity;
        expect_miss(r, "infinite origin");
        r = good;
        r.dir[k] = kInfinity;
        expect_miss(r, "infinite direction");
    }
    Ray r = good;
    r.dir = Vec3f(0.0f);
    expect_miss(r, "zero direction");
    r = good;
    r.tmin = kNaN;
    expect_miss(r, "NaN tmin");
    r = good;
    r.tmax = kNaN;
    expect_miss(r, "NaN tmax");
    r = good;
    r.tmin = 3.0f;
    r.tmax = 2.0f;
    expect_miss(r, "empty interval");

    // Extreme but finite direction lengths: the same hit, t scaled exactly.
    for (float len : {1e-30f, 1e-12f, 1e12f, 1e30f}) {
        r = good;
        r.dir *= len;
        Hit hs;
        ASSERT_TRUE(tree->intersect(r, hs)) << len;
        EXPECT_NEAR(hs.t * len, t_ref, 1e-5f * t_ref) << len;
        EXPECT_EQ(hs.prim, h.prim) << len;
        EXPECT_TRUE(tree->occluded(r)) << len;
    }
    // An infinite tmin on the far side, a negative tmin.
    r = good;
    r.tmin = -kInfinity;
    EXPECT_TRUE(tree->intersect(r, h));
    r.tmin = kInfinity;
    r.tmax = kInfinity;
    expect_miss(r, "interval at infinity");
}

TEST_P(Traversal, CountersCountWork) {
    BUILD_OR_SKIP(tree, test::make_blob(4, 1.0f, 5), params());
    Ray r;
    r.origin = Vec3f(0.1f, 0.2f, -5.0f);
    r.dir = Vec3f(0.0f, 0.0f, 1.0f);
    TraversalCounters c;
    Hit h;
    ASSERT_TRUE(tree->intersect(r, h, &c));
    EXPECT_GE(c.nodes_visited, 2u);
    EXPECT_GE(c.triangles_tested, 1u);
    const TraversalCounters first = c;
    ASSERT_TRUE(tree->occluded(r, &c));
    EXPECT_GT(c.nodes_visited, first.nodes_visited);
    EXPECT_GT(c.triangles_tested, first.triangles_tested);
    TraversalCounters miss;
    r.origin.x = 10.0f;
    EXPECT_FALSE(tree->intersect(r, h, &miss));
    EXPECT_EQ(miss.triangles_tested, 0u);
    // The ray runs parallel to x outside the root box's x slab: rejected before any node.
    EXPECT_EQ(miss.nodes_visited, 0u);
    r.origin = Vec3f(0.1f, -10.0f, -5.0f);
    EXPECT_FALSE(tree->occluded(r, &miss));
    EXPECT_EQ(miss.nodes_visited, 0u);
    EXPECT_EQ(miss.triangles_tested, 0u);
}

// A leaf's triangles are tested several at a time (SIMD) where the CPU allows: the closest
// hit must be bit for bit the scalar test's over the leaf in order (a later triangle at the
// same t wins), and an any-hit query must count the tests up to the first hit. One leaf of
// 1 to 13 triangles (every tail length), with exact duplicates for ties and rays whose
// interval ends inside the leaf.
TEST(TraversalLeafTest, WideLeafTestIsTheScalarTestBitForBit) {
    std::mt19937 rng(17);
    std::uniform_real_distribution<float> u(-1.5f, 1.5f), tmax(0.5f, 4.0f);
    size_t hits = 0, ties = 0;
    for (size_t n : {1, 2, 3, 4, 5, 6, 7, 8, 9, 12, 13}) {
        TriangleMesh mesh = test::make_soup(n, 1.5f, uint32_t(n));
        for (size_t k = 0; k + 1 < n; k += 3) mesh.triangles.push_back(mesh.triangles[k]);
        KdTreeParams p;
        p.traversal_cost = 1e30f;  // never split: one leaf holds every triangle
        const auto tree = build_kdtree(std::make_shared<TriangleMesh>(std::move(mesh)), p);
        ASSERT_EQ(tree->nodes().size(), 1u);
        const TriangleMesh& m = tree->mesh();
        ASSERT_EQ(tree->indices().size(), m.triangles.size());
        for (int i = 0; i < 4000; ++i) {
            Ray r;
            r.origin = Vec3f(u(rng), u(rng), -3.0f + u(rng));
            r.dir = Vec3f(u(rng), u(rng), 3.0f) - r.origin;
            r.tmax = (i & 1) ? tmax(rng) : kInfinity;
            const WatertightRay wr(r.origin, r.dir);
            Hit ref;
            size_t first = 0;
            for (size_t k = 0; k < tree->indices().size(); ++k) {
                const Vec3u t = m.triangles[tree->indices()[k]];
                float th, uh, vh;
                const float bound = ref.valid() ? ref.t : r.tmax;
                if (!intersect_triangle(wr, m.positions[t.x], m.positions[t.y], m.positions[t.z],
                                        r.tmin, bound, th, uh, vh))
                    continue;
                if (!ref.valid()) first = k + 1;
                ties += ref.valid() && th == ref.t;
                ref = {th, uh, vh, tree->indices()[k]};
            }
            Hit hit;
            const std::string what = std::to_string(n) + " triangles, ray " + std::to_string(i);
            ASSERT_EQ(tree->intersect(r, hit), ref.valid()) << what;
            TraversalCounters c;
            ASSERT_EQ(tree->occluded(r, &c), ref.valid()) << what;
            if (!ref.valid()) continue;
            ++hits;
            EXPECT_TRUE(test::bitwise_equal(hit, ref))
                << what << ": prim " << hit.prim << " vs " << ref.prim << ", t " << hit.t << " vs "
                << ref.t << ", u " << hit.u << " vs " << ref.u << ", v " << hit.v << " vs "
                << ref.v;
            EXPECT_EQ(c.triangles_tested, first) << what;
        }
    }
    EXPECT_GT(hits, 3000u);
    EXPECT_GT(ties, 100u);
}

// q, n0 and max_depth at the ends of their ranges still give exact trees.
TEST_P(Traversal, ExtremeParameters) {
    struct P {
        float q;
        int n0, depth;
    };
    const P cases[] = {{1.0f, 0, 64}, {1e-6f, 0, 64}, {1.0f, 1000000, 0},
                       {0.5f, 0, 1},  {1e-30f, 3, 0}, {1.0f, 0, 0}};
    const TriangleMesh meshes[] = {test::make_blob(3, 1.0f, 3), test::make_planar_grid(8, 4),
                                   test::make_soup(300, 0.5f, 5)};
    std::mt19937 rng(6);
    std::uniform_real_distribution<float> u(-2.0f, 2.0f);
    for (const P& c : cases) {
        KdTreeParams p;
        p.q = c.q;
        p.n0 = c.n0;
        p.max_depth = c.depth;
        for (size_t mi = 0; mi < std::size(meshes); ++mi) {
            BUILD_OR_SKIP(tree, meshes[mi], p);
            const std::string what = "q " + std::to_string(c.q) + " n0 " + std::to_string(c.n0) +
                                     " depth " + std::to_string(c.depth) + " mesh " +
                                     std::to_string(mi);
            EXPECT_LE(tree->stats().max_depth_reached, c.depth ? uint32_t(c.depth) : 64u) << what;
            EXPECT_LE(tree->stats().refs_per_triangle, 64.0) << what;
            const Vec3f centre = meshes[mi].bounds().center();
            for (int i = 0; i < 1500; ++i) {
                Ray r;
                r.origin = centre + Vec3f(u(rng), u(rng), u(rng)) * 4.0f;
                r.dir = centre + Vec3f(u(rng), u(rng), u(rng)) - r.origin;
                expect_matches_brute_force(*tree, r, what + " ray " + std::to_string(i));
            }
        }
    }
}

INSTANTIATE_TEST_SUITE_P(Builders, Traversal, ::testing::Values(KdBuilder::thesis, KdBuilder::sah),
                         [](const ::testing::TestParamInfo<KdBuilder>& pi) {
                             return std::string(kKdBuilderNames[size_t(pi.param)]);
                         });

}  // namespace
}  // namespace kdt
