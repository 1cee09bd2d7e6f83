// Stream queries (renderer/accel/traversal_stream.h): every result bit for bit the single-ray
// query's, for every lane count, on random rays, diffuse rays leaving surface points, shadow
// rays with a finite tmax, and the hard rays of the batch tests (in split planes, aimed at
// vertices, non-finite, empty intervals); on the dragon when it is present.
#include "renderer/accel/traversal_stream.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "renderer/accel/kdtree.h"
#include "renderer/accel/traversal_partition.h"
#include "tests/renderer/accel/kd_test_meshes.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

// Stream closest hits and any-hits with every lane count against one query per ray, and
// the traversal work they count against the sums of the single queries' counts; returns how
// many rays hit something.
size_t expect_stream_equals_single(const KdTree& tree, const std::vector<Ray>& rays,
                                   const std::string& what) {
    std::vector<Hit> single(rays.size());
    std::vector<uint8_t> single_occ(rays.size());
    size_t hits = 0;
    TraversalCounters single_closest, single_any;
    for (size_t i = 0; i < rays.size(); ++i) {
        hits += tree.intersect(rays[i], single[i], &single_closest);
        single_occ[i] = tree.occluded(rays[i], &single_any) ? 1 : 0;
    }
    for (int lanes : kStreamLaneChoices) {
        std::vector<Hit> stream(rays.size(), Hit{1.0f, 0.5f, 0.5f, 3});
        std::vector<uint8_t> occ(rays.size(), 7);
        TraversalCounters closest, any;
        intersect_stream(tree, rays.data(), rays.size(), stream.data(), lanes, &closest);
        occluded_stream(tree, rays.data(), rays.size(), occ.data(), lanes, &any);
        EXPECT_EQ(closest.nodes_visited, single_closest.nodes_visited) << what << ", " << lanes;
        EXPECT_EQ(closest.triangles_tested, single_closest.triangles_tested)
            << what << ", " << lanes;
        EXPECT_EQ(any.nodes_visited, single_any.nodes_visited) << what << ", " << lanes;
        EXPECT_EQ(any.triangles_tested, single_any.triangles_tested) << what << ", " << lanes;
        for (size_t i = 0; i < rays.size(); ++i) {
            EXPECT_TRUE(test::bitwise_equal(single[i], stream[i]))
                << what << ", " << lanes << " lanes: ray " << i << ": single prim "
                << single[i].prim << " t " << single[i].t << ", stream prim " << stream[i].prim
                << " t " << stream[i].t;
            EXPECT_EQ(single_occ[i], occ[i]) << what << ", " << lanes << " lanes: ray " << i;
            if (::testing::Test::HasFailure()) return hits;
        }
    }
    // Partition queries: fully breadth-first (1), the default, and single-ray throughout.
    for (int min_rays : {1, kPartitionMinRays, 1 << 30}) {
        std::vector<Hit> part(rays.size(), Hit{1.0f, 0.5f, 0.5f, 3});
        std::vector<uint8_t> occ(rays.size(), 7);
        TraversalCounters closest, any;
        intersect_partition(tree, rays.data(), rays.size(), part.data(), &closest, min_rays);
        occluded_partition(tree, rays.data(), rays.size(), occ.data(), &any, min_rays);
        const std::string how = what + ", partition " + std::to_string(min_rays);
        EXPECT_EQ(closest.nodes_visited, single_closest.nodes_visited) << how;
        EXPECT_EQ(closest.triangles_tested, single_closest.triangles_tested) << how;
        EXPECT_EQ(any.nodes_visited, single_any.nodes_visited) << how;
        EXPECT_EQ(any.triangles_tested, single_any.triangles_tested) << how;
        for (size_t i = 0; i < rays.size(); ++i) {
            EXPECT_TRUE(test::bitwise_equal(single[i], part[i]))
                << how << ": ray " << i << ": single prim " << single[i].prim << " t "
                << single[i].t << ", partition prim " << part[i].prim << " t " << part[i].t;
            EXPECT_EQ(single_occ[i], occ[i]) << how << ": ray " << i;
            if (::testing::Test::HasFailure()) return hits;
        }
    }
    return hits;
}

// Rays from random points in the mesh's box in random directions.
std::vector<Ray> random_rays(const TriangleMesh& mesh, size_t n, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    const Bounds3f b = mesh.bounds();
    std::vector<Ray> rays(n);
    for (Ray& r : rays) {
        r.origin = b.lower + Vec3f(u(rng), u(rng), u(rng)) * b.extent();
        r.dir = Vec3f(u(rng), u(rng), u(rng)) * 2.0f - 1.0f;
    }
    return rays;
}

// A path tracer's secondary rays: from a random point of a random triangle, offset a hair
// along the normal, a cosine-distributed bounce; every second ray is a shadow ray toward a
// point outside the mesh's box with tmax just short of it.
std::vector<Ray> surface_rays(const TriangleMesh& mesh, size_t n, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    std::uniform_int_distribution<size_t> pick(0, mesh.triangle_count() - 1);
    const Bounds3f b = mesh.bounds();
    const float scale = glm::length(b.extent());
    std::vector<Ray> rays;
    while (rays.size() < n) {
        const Vec3u t = mesh.triangles[pick(rng)];
        const Vec3f a = mesh.positions[t.x], e1 = mesh.positions[t.y] - a,
                    e2 = mesh.positions[t.z] - a;
        const Vec3f c = glm::cross(e1, e2);
        if (!(glm::length(c) > 0.0f)) continue;
        const Vec3f nrm = glm::normalize(c);
        float s = u(rng), w = u(rng);
        if (s + w > 1.0f) {
            s = 1.0f - s;
            w = 1.0f - w;
        }
        Ray r;
        r.origin = a + s * e1 + w * e2 + nrm * (1e-5f * scale);
        if (rays.size() % 2 == 0) {
            const Vec3f tangent =
                glm::normalize(std::fabs(nrm.x) > 0.5f ? glm::cross(nrm, Vec3f(0, 1, 0))
                                                       : glm::cross(nrm, Vec3f(1, 0, 0)));
            const Vec3f bitangent = glm::cross(nrm, tangent);
            const float r1 = u(rng), phi = 6.2831853f * u(rng);
            const float rad = std::sqrt(r1);
            r.dir = tangent * (rad * std::cos(phi)) + bitangent * (rad * std::sin(phi)) +
                    nrm * std::sqrt(std::max(0.0f, 1.0f - r1));
        } else {
            const Vec3f light = b.center() + scale * (Vec3f(u(rng), u(rng), u(rng)) - 0.5f);
            r.dir = light - r.origin;
            r.tmax = 0.999f;
        }
        rays.push_back(r);
    }
    return rays;
}

// A render tile's bounce and shadow rays: surface_rays() from the triangles near one point
// of the mesh (the tile's primary hits), so that the rays of a batch share the top of the tree.
std::vector<Ray> tile_rays(const TriangleMesh& mesh, size_t n, uint32_t seed) {
    const Bounds3f b = mesh.bounds();
    const Vec3f centre = mesh.positions[mesh.triangles[mesh.triangle_count() / 3].x];
    const float radius = 0.05f * glm::length(b.extent());
    TriangleMesh near = mesh;
    near.triangles.clear();
    for (const Vec3u& t : mesh.triangles)
        if (glm::length(mesh.positions[t.x] - centre) < radius) near.triangles.push_back(t);
    if (near.triangles.empty()) near.triangles.push_back(mesh.triangles[0]);
    return surface_rays(near, n, seed);
}

class Stream : public ::testing::TestWithParam<KdBuilder> {
protected:
    std::shared_ptr<const KdTree> build(TriangleMesh mesh,
                                        LeafVertexIndices leaf = LeafVertexIndices::within_budget) {
        KdTreeParams p;
        p.builder = GetParam();
        auto tree = build_kdtree(std::make_shared<TriangleMesh>(std::move(mesh)), p);
        if (leaf == LeafVertexIndices::within_budget) return tree;
        return std::make_shared<const KdTree>(tree->mesh_ptr(), tree->bounds(), tree->nodes(),
                                              tree->indices(), tree->params(), tree->stats(), leaf);
    }
};

TEST_P(Stream, RandomAndSurfaceRaysWithAndWithoutLeafVertexIndices) {
    const TriangleMesh meshes[] = {test::make_blob(6, 1.0f, 3), test::make_soup(4000, 0.3f, 4),
                                   test::make_planar_grid(24, 5)};
    for (size_t mi = 0; mi < std::size(meshes); ++mi) {
        for (LeafVertexIndices leaf : {LeafVertexIndices::always, LeafVertexIndices::never}) {
            auto tree = build(meshes[mi], leaf);
            EXPECT_EQ(tree->reference_triangles().empty(), leaf == LeafVertexIndices::never);
            const std::string what = "mesh " + std::to_string(mi) +
                                     (leaf == LeafVertexIndices::never ? ", via indices" : "");
            const auto random = random_rays(*tree->mesh_ptr(), 6000, uint32_t(mi));
            EXPECT_GT(expect_stream_equals_single(*tree, random, what + ", random"), 500u);
            const auto surface = surface_rays(*tree->mesh_ptr(), 6000, uint32_t(mi) + 10);
            EXPECT_GT(expect_stream_equals_single(*tree, surface, what + ", surface"), 500u);
        }
    }
}

// Axis-parallel rays on grid lines and in the plane z = 0, where triangles and split planes
// lie (t = 0 * inf = NaN at those planes), with +0 and -0 components.
TEST_P(Stream, AxisAlignedRaysOnGridLinesAndInPlanes) {
    auto tree = build(test::make_planar_grid(12, 5));
    std::vector<Ray> rays;
    for (int axis = 0; axis < 3; ++axis) {
        for (float sign : {-1.0f, 1.0f}) {
            for (float zero : {0.0f, -0.0f}) {
                const std::vector<Ray> line = test::grid_line_rays(axis, sign, zero);
                rays.insert(rays.end(), line.begin(), line.end());
            }
        }
    }
    EXPECT_GT(expect_stream_equals_single(*tree, rays, "axis-aligned"), 1000u);
}

// Rays aimed exactly at the vertices of a closed mesh from inside: none escapes.
TEST_P(Stream, VertexAimedRaysNeverEscape) {
    auto tree = build(test::make_blob(4, 1.0f, 12));
    std::vector<Ray> rays;
    for (const Vec3f& v : tree->mesh().positions) {
        Ray r;
        r.origin = Vec3f(0.01f, -0.02f, 0.015f);
        r.dir = v - r.origin;
        rays.push_back(r);
    }
    std::vector<Hit> hits(rays.size());
    std::vector<uint8_t> occ(rays.size());
    intersect_stream(*tree, rays.data(), rays.size(), hits.data());
    occluded_stream(*tree, rays.data(), rays.size(), occ.data());
    size_t escapes = 0;
    for (size_t i = 0; i < rays.size(); ++i) escapes += !hits[i].valid() + !occ[i];
    EXPECT_EQ(escapes, 0u);
    EXPECT_EQ(expect_stream_equals_single(*tree, rays, "vertex-aimed"), rays.size());
}

// NaN, infinite and zero directions, empty intervals, tiny tmax and huge or tiny directions
// among ordinary rays, so lanes finish and refill at every phase of their neighbours.
TEST_P(Stream, BadAndExtremeRaysAmongOrdinaryOnes) {
    auto tree = build(test::make_blob(5, 1.0f, 14));
    auto rays = random_rays(tree->mesh(), 3000, 21);
    test::spoil_rays(rays, 7, 8);
    for (size_t n : {rays.size(), size_t(13), size_t(5), size_t(1)}) {
        const std::vector<Ray> part(rays.begin(), rays.begin() + long(n));
        const size_t hits = expect_stream_equals_single(*tree, part, "n " + std::to_string(n));
        if (n == rays.size()) {
            EXPECT_GT(hits, 1000u) << "the comparison needs rays that hit";
        }
    }
    intersect_stream(*tree, nullptr, 0, nullptr);  // an empty stream
    occluded_stream(*tree, nullptr, 0, nullptr);
}

// Batches of a tile's rays as the renderer hands them over (1, 7 and 4096 rays, and none),
// and the same batches with bad rays among them.
TEST_P(Stream, PartitionOnTileBatches) {
    auto tree = build(test::make_blob(7, 1.0f, 31));
    for (size_t n : {size_t(1), size_t(7), size_t(4096)}) {
        auto rays = tile_rays(tree->mesh(), n, uint32_t(n));
        EXPECT_GT(expect_stream_equals_single(*tree, rays, "tile " + std::to_string(n)), 0u);
        test::spoil_rays(rays, 3, 8);
        expect_stream_equals_single(*tree, rays, "spoilt tile " + std::to_string(n));
    }
    intersect_partition(*tree, nullptr, 0, nullptr);  // an empty batch
    occluded_partition(*tree, nullptr, 0, nullptr);
}

TEST(StreamEmpty, EmptyMeshAndEmptyTreeMissEverything) {
    const auto rays = random_rays(test::make_blob(2, 1.0f, 1), 50, 2);
    const KdTree no_tree;
    const auto empty_mesh_tree = build_kdtree(std::make_shared<TriangleMesh>(), KdTreeParams{});
    for (const KdTree* tree : {empty_mesh_tree.get(), &no_tree}) {
        std::vector<Hit> hits(rays.size(), Hit{1.0f, 0.0f, 0.0f, 5});
        std::vector<uint8_t> occ(rays.size(), 1);
        intersect_stream(*tree, rays.data(), rays.size(), hits.data());
        occluded_stream(*tree, rays.data(), rays.size(), occ.data());
        for (size_t i = 0; i < rays.size(); ++i) {
            EXPECT_FALSE(hits[i].valid());
            EXPECT_EQ(occ[i], 0);
        }
        std::vector<Hit> part(rays.size(), Hit{1.0f, 0.0f, 0.0f, 5});
        std::vector<uint8_t> part_occ(rays.size(), 1);
        intersect_partition(*tree, rays.data(), rays.size(), part.data());
        occluded_partition(*tree, rays.data(), rays.size(), part_occ.data());
        for (size_t i = 0; i < rays.size(); ++i) {
            EXPECT_FALSE(part[i].valid());
            EXPECT_EQ(part_occ[i], 0);
        }
    }
}

// The reduced dragon (scripts/fetch_assets.sh): random and surface rays, SAH tree.
TEST(StreamDragon, Res2RandomAndSurfaceRays) {
    const auto mesh = test::load_dragon_res2();
    if (!mesh) GTEST_SKIP() << test::kDragonRes2Missing;
    const auto tree = build_kdtree(mesh, KdTreeParams{});
    EXPECT_GT(expect_stream_equals_single(*tree, random_rays(*mesh, 100000, 5), "dragon random"),
              10000u);
    EXPECT_GT(expect_stream_equals_single(*tree, surface_rays(*mesh, 100000, 6), "dragon surface"),
              10000u);
}

INSTANTIATE_TEST_SUITE_P(Builders, Stream, ::testing::Values(KdBuilder::thesis, KdBuilder::sah),
                         [](const ::testing::TestParamInfo<KdBuilder>& pi) {
                             return std::string(kKdBuilderNames[size_t(pi.param)]);
                         });

}  // namespace
}  // namespace kdt
