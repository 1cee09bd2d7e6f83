// Batch queries (KdTree::intersect / occluded over arrays): every result bitwise equal to
// the single-ray query's, whether the rays went through the SIMD packet path (coherent
// groups) or one by one; the same work counted; packets formed exactly when rays are
// coherent; hard rays (axis-aligned, in a split plane, aimed at vertices, non-finite) in
// packets too.
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/accel/kdtree.h"
#include "renderer/accel/traversal_detail.h"
#include "tests/renderer/accel/kd_test_meshes.h"

namespace kdt {
namespace {

using test::bitwise_equal;

// Batch closest hits, batch any-hits and their counters against one query per ray.
void expect_batch_equals_single(const KdTree& tree, const std::vector<Ray>& rays,
                                const std::string& what, bool expect_hits = true) {
    std::vector<Hit> batch(rays.size());
    std::vector<uint8_t> occ(rays.size(), 7);
    TraversalCounters cb, co;
    tree.intersect(rays.data(), rays.size(), batch.data(), &cb);
    tree.occluded(rays.data(), rays.size(), occ.data(), &co);
    TraversalCounters sb, so;
    size_t hits = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
        Hit h;
        const bool got = tree.intersect(rays[i], h, &sb);
        hits += got;
        ASSERT_TRUE(bitwise_equal(h, batch[i]))
            << what << ": ray " << i << ": single prim " << h.prim << " t " << h.t
            << ", batch prim " << batch[i].prim << " t " << batch[i].t;
        ASSERT_EQ(occ[i], tree.occluded(rays[i], &so) ? 1 : 0) << what << ": ray " << i;
    }
    EXPECT_EQ(cb.nodes_visited, sb.nodes_visited) << what;
    EXPECT_EQ(cb.triangles_tested, sb.triangles_tested) << what;
    EXPECT_EQ(co.nodes_visited, so.nodes_visited) << what;
    EXPECT_EQ(co.triangles_tested, so.triangles_tested) << what;
    if (expect_hits) {
        EXPECT_GT(hits, 0u) << what << ": the rays should hit something";
    }
}

// Pinhole camera rays, `spp` jittered samples per pixel consecutively (as a renderer
// traces them), looking at `target` from `eye`.
std::vector<Ray> camera_rays(Vec3f eye, Vec3f target, int w, int h, int spp, float fov_deg,
                             uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    const Vec3f f = glm::normalize(target - eye);
    const Vec3f r = glm::normalize(glm::cross(f, Vec3f(0.0f, 1.0f, 0.3f)));
    const Vec3f up = glm::cross(r, f);
    const float t = std::tan(0.5f * fov_deg * 3.14159265f / 180.0f);
    std::vector<Ray> rays;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int s = 0; s < spp; ++s) {
                const float sx = (2.0f * (float(x) + u(rng)) / float(w) - 1.0f) * t;
                const float sy = (1.0f - 2.0f * (float(y) + u(rng)) / float(h)) * t;
                Ray ray;
                ray.origin = eye;
                ray.dir = glm::normalize(f + sx * r + sy * up);
                rays.push_back(ray);
            }
    return rays;
}

class Batch : public ::testing::TestWithParam<KdBuilder> {
protected:
    std::shared_ptr<const KdTree> build(TriangleMesh mesh) {
        KdTreeParams p;
        p.builder = GetParam();
        return build_kdtree(std::make_shared<TriangleMesh>(std::move(mesh)), p);
    }
};

TEST_P(Batch, CameraRaysOverSeveralMeshes) {
    const TriangleMesh meshes[] = {test::make_blob(5, 1.0f, 3), test::make_soup(3000, 0.3f, 4),
                                   test::make_planar_grid(16, 5)};
    for (size_t mi = 0; mi < std::size(meshes); ++mi) {
        auto tree = build(meshes[mi]);
        const Bounds3f b = meshes[mi].bounds();
        const Vec3f c = b.center();
        const float r = glm::length(b.extent());
        const Vec3f eyes[] = {c + Vec3f(0.3f, 0.4f, 1.5f) * r, c + Vec3f(-1.2f, 0.2f, -0.7f) * r,
                              c + Vec3f(0.05f, 0.05f, 0.05f) * r};
        for (size_t e = 0; e < std::size(eyes); ++e) {
            // 8 samples per pixel (full packets) and 3 (packets straddle pixels, tails).
            for (int spp : {8, 3}) {
                const auto rays = camera_rays(eyes[e], c, 40, 30, spp, 40.0f, uint32_t(e));
                expect_batch_equals_single(*tree, rays,
                                           "mesh " + std::to_string(mi) + " eye " +
                                               std::to_string(e) + " spp " + std::to_string(spp));
            }
        }
    }
}

TEST_P(Batch, IncoherentRaysTakeTheSingleRayPath) {
    auto tree = build(test::make_blob(4, 1.0f, 8));
    std::mt19937 rng(9);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    std::vector<Ray> rays;
    for (int i = 0; i < 4000; ++i) {
        Ray r;
        r.origin = 0.3f * Vec3f(u(rng), u(rng), u(rng));
        r.dir = Vec3f(u(rng), u(rng), u(rng));
        rays.push_back(r);
    }
    expect_batch_equals_single(*tree, rays, "random rays");
    const detail::TreeView tv = detail::view_of(*tree);
    Hit hits[8];
    EXPECT_FALSE(detail::trace_packet(tv, rays.data(), 8, false, hits, nullptr, nullptr));
}

TEST_P(Batch, CoherentRaysFormPackets) {
    auto tree = build(test::make_blob(4, 1.0f, 8));
    // 64 x 64 pixels over 30 degrees: a pixel's samples are within half a degree.
    const auto rays = camera_rays(Vec3f(0.2f, 0.1f, 3.0f), Vec3f(0.0f), 64, 64, 8, 30.0f, 1);
    const detail::TreeView tv = detail::view_of(*tree);
    Hit hits[8];
    size_t packets = 0;
    for (size_t i = 0; i + 8 <= rays.size(); i += 8)
        packets += detail::trace_packet(tv, rays.data() + i, 8, false, hits, nullptr, nullptr);
#ifdef __AVX2__
    // All but the pixels where a direction component changes sign (the lanes of a packet
    // share the order of the children).
    EXPECT_GE(packets, rays.size() / 8 * 9 / 10);
#else
    EXPECT_EQ(packets, 0u);
#endif
}

// Axis-parallel rays, several per packet, on grid lines, in the plane z = 0 where the
// triangles and split planes lie (t = 0 * inf = NaN at those planes), with +0 and -0
// components.
TEST_P(Batch, AxisAlignedPacketsOnGridLinesAndInPlanes) {
    auto tree = build(test::make_planar_grid(12, 5));
    for (int axis = 0; axis < 3; ++axis)
        for (float sign : {-1.0f, 1.0f})
            for (float zero : {0.0f, -0.0f}) {
                std::vector<Ray> rays;
                for (const Ray& r : test::grid_line_rays(axis, sign, zero)) {
                    // Eight parallel rays a hair apart: a packet.
                    for (int k = 0; k < 8; ++k) {
                        Ray q = r;
                        q.origin[(axis + 1) % 3] += float(k) * 1e-4f;
                        rays.push_back(q);
                    }
                }
                // Rays along x or y may all lie in the grid's plane or miss it.
                expect_batch_equals_single(*tree, rays,
                                           "axis " + std::to_string(axis) + " sign " +
                                               std::to_string(sign) + " zero " +
                                               std::to_string(std::signbit(zero)),
                                           axis == 2);
            }
}

// Coherent groups aimed exactly at the vertices of a closed mesh from inside: none escapes
// in a packet either.
TEST_P(Batch, VertexAimedPacketsNeverEscape) {
    auto tree = build(test::make_blob(4, 1.0f, 12));
    const TriangleMesh& m = tree->mesh();
    std::vector<Ray> rays;
    for (const Vec3f& v : m.positions)
        for (int k = 0; k < 8; ++k) {
            Ray r;
            r.origin = Vec3f(0.01f, -0.02f, 0.015f) + Vec3f(float(k) * 1e-5f, 0.0f, 0.0f);
            r.dir = v - r.origin;
            rays.push_back(r);
        }
    std::vector<Hit> hits(rays.size());
    std::vector<uint8_t> occ(rays.size());
    tree->intersect(rays.data(), rays.size(), hits.data());
    tree->occluded(rays.data(), rays.size(), occ.data());
    size_t escapes = 0;
    for (size_t i = 0; i < rays.size(); ++i) escapes += !hits[i].valid() + !occ[i];
    EXPECT_EQ(escapes, 0u);
    expect_batch_equals_single(*tree, rays, "vertex-aimed");
}

// NaN, infinite and zero directions, empty intervals and misses inside otherwise coherent
// groups; counts that are not a multiple of the packet size.
TEST_P(Batch, BadRaysInsidePacketsAndTails) {
    auto tree = build(test::make_blob(4, 1.0f, 14));
    auto rays = camera_rays(Vec3f(0.1f, 0.2f, 3.0f), Vec3f(0.0f), 12, 10, 8, 35.0f, 2);
    test::spoil_rays(rays, 13, 6);
    for (size_t n : {rays.size(), rays.size() - 3, size_t(5), size_t(1)}) {
        std::vector<Ray> part(rays.begin(), rays.begin() + long(n));
        expect_batch_equals_single(*tree, part, "n " + std::to_string(n), n > 8);
    }
    std::vector<Hit> none;
    tree->intersect(static_cast<const Ray*>(nullptr), 0, none.data());  // an empty batch
}

TEST(BatchEmpty, EmptyMeshMissesEverything) {
    auto tree = build_kdtree(std::make_shared<TriangleMesh>(), KdTreeParams{});
    const auto rays = camera_rays(Vec3f(0.0f, 0.0f, 3.0f), Vec3f(0.0f), 4, 4, 8, 30.0f, 3);
    std::vector<Hit> hits(rays.size(), Hit{1.0f, 0.0f, 0.0f, 5});
    std::vector<uint8_t> occ(rays.size(), 1);
    tree->intersect(rays.data(), rays.size(), hits.data());
    tree->occluded(rays.data(), rays.size(), occ.data());
    for (size_t i = 0; i < rays.size(); ++i) {
        EXPECT_FALSE(hits[i].valid());
        EXPECT_EQ(occ[i], 0);
    }
}

INSTANTIATE_TEST_SUITE_P(Builders, Batch, ::testing::Values(KdBuilder::thesis, KdBuilder::sah),
                         [](const ::testing::TestParamInfo<KdBuilder>& pi) {
                             return std::string(kKdBuilderNames[size_t(pi.param)]);
                         });

}  // namespace
}  // namespace kdt
