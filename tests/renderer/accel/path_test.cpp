// Queries that report the path to their hit's leaf (KdTree::intersect with a KdPath) and
// queries that start from such a path (intersect_from, occluded_from): the recorded path
// leads from the root to a leaf holding the hit triangle and changes nothing in the hit;
// a query from any path of the tree finds the root query's hit (bit for bit the same t),
// bounces from the hit's own leaf as well as from random paths and nodes; paths that are
// not paths of the tree are ignored; hard rays (in split planes, aimed at vertices).
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/accel/kdtree.h"
#include "renderer/geometry/intersect.h"
#include "tests/renderer/accel/kd_test_meshes.h"

namespace kdt {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

class Path : public ::testing::TestWithParam<KdBuilder> {
protected:
    std::shared_ptr<const KdTree> build(TriangleMesh mesh, int max_depth = 0) {
        KdTreeParams p;
        p.builder = GetParam();
        p.max_depth = max_depth;
        return build_kdtree(std::make_shared<TriangleMesh>(std::move(mesh)), p);
    }
};

// The path is one of the tree's: it starts at the root, each node is a child of the one
// before, and it ends at a leaf that references triangle `prim`.
void expect_leaf_path(const KdTree& tree, const KdPath& path, uint32_t prim,
                      const std::string& what) {
    ASSERT_GE(path.length, 1u) << what;
    ASSERT_LE(path.length, KdPath::kMaxLength) << what;
    ASSERT_EQ(path.nodes[0], 0u) << what;
    const std::vector<KdNode>& nodes = tree.nodes();
    for (uint32_t i = 0; i + 1 < path.length; ++i) {
        const KdNode& n = nodes[path.nodes[i]];
        ASSERT_FALSE(n.is_leaf()) << what << ": level " << i;
        ASSERT_LE(path.nodes[i + 1] - n.child(), 1u) << what << ": level " << i;
    }
    const KdNode& leaf = nodes[path.nodes[path.length - 1]];
    ASSERT_TRUE(leaf.is_leaf()) << what;
    bool found = false;
    for (uint32_t k = 0; k < leaf.count(); ++k) found |= tree.indices()[leaf.first + k] == prim;
    ASSERT_TRUE(found) << what << ": the leaf does not hold triangle " << prim;
}

// A random path of the tree: down to a leaf, or (to_leaf false) stopping at a random level.
KdPath random_path(const KdTree& tree, std::mt19937& rng, bool to_leaf) {
    std::uniform_int_distribution<int> coin(0, 1), stop(0, 4);
    KdPath p;
    p.nodes[0] = 0;
    p.length = 1;
    uint32_t idx = 0;
    while (!tree.nodes()[idx].is_leaf()) {
        if (!to_leaf && stop(rng) == 0) break;
        idx = tree.nodes()[idx].child() + uint32_t(coin(rng));
        p.nodes[p.length++] = idx;
    }
    return p;
}

// Rays between random points in and around the mesh's box (some start outside it).
std::vector<Ray> random_rays(const TriangleMesh& mesh, size_t n, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-0.2f, 1.2f);
    const Bounds3f b = mesh.bounds();
    auto point = [&] { return b.lower + Vec3f(u(rng), u(rng), u(rng)) * (b.upper - b.lower); };
    std::vector<Ray> rays(n);
    for (Ray& r : rays) {
        r.origin = point();
        r.dir = point() - r.origin;
    }
    return rays;
}

// From-path query against the root query: same verdict, bit for bit the same t, the same
// triangle or one hit at exactly that t; the same any-hit verdict.
void expect_same_as_root(const KdTree& tree, const KdPath& start, const Ray& ray,
                         const std::string& what) {
    Hit ref, got;
    const bool r = tree.intersect(ray, ref);
    KdPath leaf;
    ASSERT_EQ(tree.intersect_from(start, ray, got, &leaf), r) << what;
    ASSERT_EQ(tree.occluded_from(start, ray), tree.occluded(ray)) << what;
    if (!r) {
        ASSERT_EQ(leaf.length, 0u) << what;
        return;
    }
    ASSERT_EQ(got.t, ref.t) << what << ": prim " << got.prim << " vs " << ref.prim;
    ASSERT_TRUE(test::same_closest_hit(tree.mesh(), ray, got, ref)) << what;
    expect_leaf_path(tree, leaf, got.prim, what + ": path of the hit");
    Hit plain;
    ASSERT_TRUE(tree.intersect_from(start, ray, plain));  // without a path out: the same
    ASSERT_TRUE(test::bitwise_equal(plain, got)) << what;
}

TEST_P(Path, RecordedPathLeadsToTheHitsLeafAndChangesNothing) {
    for (int m = 0; m < 3; ++m) {
        const TriangleMesh mesh = m == 0   ? test::make_blob(4, 1.0f, 5)
                                  : m == 1 ? test::make_soup(3000, 0.2f, 6)
                                           : test::make_planar_grid(12, 7);
        const auto tree = build(mesh);
        size_t hits = 0;
        for (const Ray& ray : random_rays(tree->mesh(), 4000, uint32_t(10 + m))) {
            Hit plain, recorded;
            KdPath path;
            path.length = 99;  // must be reset on a miss
            TraversalCounters a, b;
            ASSERT_EQ(tree->intersect(ray, plain, &a), tree->intersect(ray, recorded, path, &b));
            ASSERT_TRUE(test::bitwise_equal(plain, recorded));
            ASSERT_EQ(a.nodes_visited, b.nodes_visited);
            ASSERT_EQ(a.triangles_tested, b.triangles_tested);
            if (!plain.valid()) {
                ASSERT_EQ(path.length, 0u);
                continue;
            }
            ++hits;
            expect_leaf_path(*tree, path, recorded.prim, "mesh " + std::to_string(m));
        }
        EXPECT_GT(hits, 1000u) << "mesh " << m;
    }
}

// What a path tracer does: a bounce from a hit starts at the path of that hit's leaf.
TEST_P(Path, BouncesFromTheHitsLeafFindTheRootQuerysHit) {
    for (int m = 0; m < 2; ++m) {
        const TriangleMesh mesh =
            m == 0 ? test::make_blob(5, 1.0f, 8) : test::make_soup(5000, 0.15f, 9);
        const auto tree = build(mesh);
        std::mt19937 rng(uint32_t(20 + m));
        std::normal_distribution<float> gauss;
        size_t bounces = 0, bounce_hits = 0;
        for (const Ray& ray : random_rays(tree->mesh(), 3000, uint32_t(30 + m))) {
            Hit hit;
            KdPath path;
            if (!tree->intersect(ray, hit, path)) continue;
            const Vec3u t = tree->mesh().triangles[hit.prim];
            const Vec3f p0 = tree->mesh().positions[t.x], p1 = tree->mesh().positions[t.y],
                        p2 = tree->mesh().positions[t.z];
            Vec3f n = glm::cross(p1 - p0, p2 - p0);
            if (!(glm::length(n) > 0.0f)) continue;
            n = glm::normalize(n);
            if (glm::dot(n, ray.dir) > 0.0f) n = -n;
            const Vec3f p = (1.0f - hit.u - hit.v) * p0 + hit.u * p1 + hit.v * p2;
            for (int k = 0; k < 4; ++k) {
                Ray bounce;
                // Offset to either side: into the surface as well as away from it.
                bounce.origin = p + (k < 2 ? 1e-5f : -1e-5f) * n;
                bounce.dir = Vec3f(gauss(rng), gauss(rng), gauss(rng));
                if (k == 3) bounce.tmax = 0.05f;  // a short shadow ray
                expect_same_as_root(
                    *tree, path, bounce,
                    "mesh " + std::to_string(m) + " bounce " + std::to_string(bounces));
                Hit h;
                bounce_hits += tree->intersect(bounce, h);
                ++bounces;
            }
        }
        EXPECT_GT(bounces, 2000u) << "mesh " << m;
        EXPECT_GT(bounce_hits, bounces / 10) << "mesh " << m;
    }
}

// A path tracer keeps one path and updates it in place from bounce to bounce.
TEST_P(Path, OnePathUpdatedInPlaceAlongAPath) {
    const auto tree = build(test::make_blob(4, 1.0f, 24));
    std::mt19937 rng(25);
    std::normal_distribution<float> gauss;
    size_t bounces = 0;
    for (const Ray& camera : random_rays(tree->mesh(), 500, 26)) {
        Hit hit;
        KdPath path;
        Ray ray = camera;
        if (!tree->intersect(ray, hit, path)) continue;
        for (int k = 0; k < 4 && hit.valid(); ++k, ++bounces) {
            ray.origin = ray.origin + 0.999f * hit.t * ray.dir;
            ray.dir = Vec3f(gauss(rng), gauss(rng), gauss(rng));
            const KdPath copy = path;
            KdPath separate;
            Hit expected;
            tree->intersect_from(copy, ray, expected, &separate);
            tree->intersect_from(path, ray, hit, &path);  // start and result alike
            ASSERT_TRUE(test::bitwise_equal(hit, expected));
            ASSERT_EQ(path.length, separate.length);
            for (uint32_t i = 0; i < path.length; ++i) ASSERT_EQ(path.nodes[i], separate.nodes[i]);
        }
    }
    EXPECT_GT(bounces, 500u);
}

// Any path works: to any leaf or any inner node, however far from the ray; a path
// only costs time when it is far from the origin.
TEST_P(Path, AnyPathOfTheTreeGivesTheRootQuerysHit) {
    const auto tree = build(test::make_soup(4000, 0.2f, 11));
    std::mt19937 rng(12);
    const std::vector<Ray> rays = random_rays(tree->mesh(), 6000, 13);
    for (size_t i = 0; i < rays.size(); ++i) {
        const KdPath start = random_path(*tree, rng, i % 2 == 0);
        expect_same_as_root(*tree, start, rays[i], "ray " + std::to_string(i));
    }
    KdPath root;
    root.length = 1;
    root.nodes[0] = 0;
    for (size_t i = 0; i < 500; ++i) {
        // The root alone is the plain query, step for step.
        Hit a, b;
        TraversalCounters ca, cb;
        ASSERT_EQ(tree->intersect(rays[i], a, &ca),
                  tree->intersect_from(root, rays[i], b, nullptr, &cb));
        ASSERT_TRUE(test::bitwise_equal(a, b));
        ASSERT_EQ(ca.nodes_visited, cb.nodes_visited);
        ASSERT_EQ(ca.triangles_tested, cb.triangles_tested);
    }
}

// Rays in split planes, along grid lines, and aimed exactly at vertices, from random
// paths: the walk takes the descent's decisions, so no hit slips between the children.
TEST_P(Path, HardRaysFromRandomPaths) {
    const auto grid = build(test::make_planar_grid(16, 14));
    std::mt19937 rng(15);
    std::uniform_int_distribution<int> cell(0, 16);
    for (int i = 0; i < 3000; ++i) {
        Ray r;
        const float x = float(cell(rng)), y = float(cell(rng));
        switch (i % 4) {
            case 0:  // straight down onto a grid vertex
                r.origin = Vec3f(x, y, 5.0f);
                r.dir = Vec3f(0.0f, 0.0f, -1.0f);
                break;
            case 1:  // along a grid line, in the plane z = 0
                r.origin = Vec3f(-1.0f, y, 0.0f);
                r.dir = Vec3f(1.0f, 0.0f, 0.0f);
                break;
            case 2:  // a diagonal in the plane
                r.origin = Vec3f(x, -1.0f, 0.0f);
                r.dir = Vec3f(1.0f, 1.0f, 0.0f);
                break;
            default:  // aimed at a vertex from above, slanted
                r.origin = Vec3f(x + 3.0f, y - 2.0f, 4.0f);
                r.dir = Vec3f(x, y, 0.0f) - r.origin;
                break;
        }
        expect_same_as_root(*grid, random_path(*grid, rng, i % 3 != 0), r,
                            "grid ray " + std::to_string(i));
    }
    // Closed blob, rays from inside aimed at its vertices: none escapes from any path.
    const auto blob = build(test::make_blob(4, 1.0f, 16));
    const TriangleMesh& mesh = blob->mesh();
    size_t escapes = 0;
    for (uint32_t v = 0; v < mesh.positions.size(); ++v) {
        Ray r;
        r.origin = Vec3f(0.05f, -0.02f, 0.03f);
        r.dir = mesh.positions[v] - r.origin;  // t = 1 at the vertex
        Hit h;
        if (!blob->intersect_from(random_path(*blob, rng, true), r, h) || h.t > 1.0f + 1e-5f)
            ++escapes;
    }
    EXPECT_EQ(escapes, 0u);
}

TEST_P(Path, InvalidPathsAreIgnoredAndBadRaysMiss) {
    const auto tree = build(test::make_blob(4, 1.0f, 17));
    const std::vector<Ray> rays = random_rays(tree->mesh(), 300, 18);
    std::mt19937 rng(19);
    const KdPath good = random_path(*tree, rng, true);
    ASSERT_GE(good.length, 3u);
    std::vector<KdPath> bad(6, good);
    bad[0].length = 0;                               // empty
    bad[1].length = KdPath::kMaxLength + 1;          // longer than any path
    bad[2].nodes[0] = 1;                             // not from the root
    bad[3].nodes[1] = tree->nodes()[0].child() + 2;  // not a child of the root
    bad[4].nodes[2] = 0xfffffff0u;                   // out of range
    bad[5].nodes[good.length] = 1;                   // past a leaf
    bad[5].length = good.length + 1;
    for (size_t i = 0; i < rays.size(); ++i) {
        Hit ref;
        tree->intersect(rays[i], ref);
        for (size_t k = 0; k < bad.size(); ++k) {
            Hit h;
            TraversalCounters a, b;
            KdPath leaf;
            ASSERT_EQ(tree->intersect_from(bad[k], rays[i], h, &leaf, &a),
                      tree->intersect(rays[i], ref, &b))
                << "path " << k;
            ASSERT_TRUE(test::bitwise_equal(h, ref)) << "path " << k;
            ASSERT_EQ(a.nodes_visited, b.nodes_visited) << "path " << k;  // from the root
            ASSERT_EQ(tree->occluded_from(bad[k], rays[i]), ref.valid()) << "path " << k;
        }
        Hit h;
        ASSERT_EQ(tree->intersect_from(nullptr, 3, rays[i], h), ref.valid());
        ASSERT_TRUE(test::bitwise_equal(h, ref));
    }
    Ray nan_ray;
    nan_ray.origin = Vec3f(0.0f, kNaN, 0.0f);
    nan_ray.dir = Vec3f(1.0f, 0.0f, 0.0f);
    Hit h;
    KdPath leaf;
    leaf.length = 5;
    EXPECT_FALSE(tree->intersect_from(good, nan_ray, h, &leaf));
    EXPECT_EQ(leaf.length, 0u);
    EXPECT_FALSE(tree->occluded_from(good, nan_ray));
    Ray zero = rays[0];
    zero.dir = Vec3f(0.0f);
    EXPECT_FALSE(tree->intersect_from(good, zero, h));

    // A tree over no triangles at all.
    const auto empty = build(TriangleMesh{});
    KdPath root;
    root.length = 1;
    root.nodes[0] = 0;
    EXPECT_FALSE(empty->intersect_from(root, rays[0], h, &leaf));
    EXPECT_FALSE(empty->occluded_from(root, rays[0]));
    EXPECT_FALSE(empty->intersect(rays[0], h, leaf));
    EXPECT_EQ(leaf.length, 0u);
}

// The shallowest and deepest trees: paths of 1 or 2 nodes, and up to 65 (64 levels), are
// walked and recorded in full.
TEST_P(Path, ShallowestAndDeepestTrees) {
    for (int depth : {1, 64}) {
        const auto tree = build(test::make_soup(2000, 0.05f, 21), depth);
        std::mt19937 rng(22);
        for (const Ray& ray : random_rays(tree->mesh(), 1500, 23)) {
            Hit hit;
            KdPath path;
            if (tree->intersect(ray, hit, path)) {
                expect_leaf_path(*tree, path, hit.prim, "depth " + std::to_string(depth));
                if (depth == 1) {
                    ASSERT_LE(path.length, 2u);
                }
            }
            expect_same_as_root(*tree, random_path(*tree, rng, true), ray,
                                "depth " + std::to_string(depth));
        }
    }
}

INSTANTIATE_TEST_SUITE_P(Builders, Path, ::testing::Values(KdBuilder::thesis, KdBuilder::sah),
                         [](const ::testing::TestParamInfo<KdBuilder>& pi) {
                             return std::string(kKdBuilderNames[size_t(pi.param)]);
                         });

}  // namespace
}  // namespace kdt
