// Wavefront packets: packet_order() sorts rays by packet class and origin, and the grouped
// batch queries trace such groups as packets however incoherent their rays are, with every
// result bitwise the single-ray query's and the same as the brute-force oracle's.
#include "renderer/accel/ray_sort.h"

#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/accel/kdtree.h"
#include "renderer/accel/traversal_detail.h"
#include "tests/renderer/accel/kd_test_meshes.h"

namespace kdt {
namespace {

// Bounce-like rays: from points near the blob's surface (on its vertices, pushed out a
// little) in uniformly random directions, plus some from inside and axis-aligned ones.
std::vector<Ray> bounce_rays(const TriangleMesh& mesh, size_t n, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    std::uniform_int_distribution<size_t> pick(0, mesh.positions.size() - 1);
    std::vector<Ray> rays;
    for (size_t i = 0; i < n; ++i) {
        Ray r;
        const Vec3f p = mesh.positions[pick(rng)];
        r.origin = p * (i % 3 == 0 ? 0.5f : 1.01f);
        Vec3f d;
        do {
            d = {u(rng), u(rng), u(rng)};
        } while (glm::dot(d, d) > 1.0f || glm::dot(d, d) < 1e-4f);
        if (i % 17 == 0) d = Vec3f(0.0f, 0.0f, i % 2 ? 1.0f : -1.0f);  // zero components
        r.dir = glm::normalize(d);
        if (i % 5 == 0) r.tmax = 0.3f;
        rays.push_back(r);
    }
    return rays;
}

TEST(RaySort, PacketOrderIsAPermutationSortedByKey) {
    const TriangleMesh mesh = test::make_blob(4, 1.0f, 3);
    const std::vector<Ray> rays = bounce_rays(mesh, 5000, 1);
    Bounds3f b;
    for (const Vec3f& p : mesh.positions) b.extend(p);
    std::vector<uint32_t> order;
    packet_order(rays.data(), rays.size(), b, order);
    ASSERT_EQ(order.size(), rays.size());
    std::vector<int> seen(rays.size(), 0);
    for (uint32_t i : order) ++seen[i];
    for (int s : seen) ASSERT_EQ(s, 1);
    for (size_t k = 1; k < order.size(); ++k) {
        const uint64_t a = packet_sort_key(rays[order[k - 1]], b);
        const uint64_t c = packet_sort_key(rays[order[k]], b);
        ASSERT_LE(a, c) << k;
        if (a == c) {
            ASSERT_LT(order[k - 1], order[k]) << "stable";
        }
    }
    // The class is the packet's: same signs, dominant axis from |d|.
    Ray r;
    r.dir = glm::normalize(Vec3f(0.2f, -0.9f, 0.1f));
    EXPECT_EQ(packet_sort_key(r, b) >> 30, 1u * 8u + 2u);
    r.dir = Vec3f(0.0f, 0.0f, 1.0f);  // zero components count as negative
    EXPECT_EQ(packet_sort_key(r, b) >> 30, 2u * 8u + 3u);
}

#if KDT_SIMD_TRAVERSAL
// Eight rays of one class but spread directions and origins: the coherence test refuses
// them as a packet, the grouped form takes them.
TEST(RaySort, GroupedPacketsSkipOnlyTheCoherenceTest) {
    auto mesh = std::make_shared<TriangleMesh>(test::make_blob(3, 1.0f, 5));
    const auto tree = build_kdtree(mesh, KdTreeParams{});
    const detail::TreeView tv = detail::view_of(*tree);
    std::vector<Ray> rays;
    for (int i = 0; i < 8; ++i) {
        Ray r;
        r.origin = Vec3f(-0.3f + 0.08f * float(i), 0.1f * float(i % 3), -2.0f);
        r.dir = glm::normalize(Vec3f(0.05f * float(i + 1), 0.3f - 0.03f * float(i), 1.0f));
        rays.push_back(r);
    }
    Hit hits[8];
    EXPECT_FALSE(detail::trace_packet(tv, rays.data(), 8, false, hits, nullptr, nullptr, true));
    EXPECT_TRUE(detail::trace_packet(tv, rays.data(), 8, false, hits, nullptr, nullptr, false));
    for (int i = 0; i < 8; ++i) {
        Hit h;
        tree->intersect(rays[size_t(i)], h);
        EXPECT_TRUE(test::bitwise_equal(h, hits[i])) << i;
    }
    rays[3].dir.x = -rays[3].dir.x;  // another sign: never one packet
    EXPECT_FALSE(detail::trace_packet(tv, rays.data(), 8, false, hits, nullptr, nullptr, false));
}
#endif

// Sorted bounce rays through the grouped queries: bitwise the single-ray results, the same
// counted work, and the oracle's closest hit and occlusion.
TEST(RaySort, GroupedQueriesMatchSingleRaysAndTheOracle) {
    for (uint32_t seed : {7u, 8u}) {
        auto mesh = std::make_shared<TriangleMesh>(test::make_blob(4, 1.0f, seed));
        const auto tree = build_kdtree(mesh, KdTreeParams{});
        std::vector<Ray> rays = bounce_rays(*mesh, 3001, seed);
        std::vector<uint32_t> order;
        packet_order(rays.data(), rays.size(), tree->bounds(), order);
        std::vector<Ray> sorted;
        for (uint32_t i : order) sorted.push_back(rays[i]);
        std::vector<Hit> hits(sorted.size());
        std::vector<uint8_t> occ(sorted.size(), 7);
        TraversalCounters cg, co, cs, cso;
        tree->intersect_grouped(sorted.data(), sorted.size(), hits.data(), &cg);
        tree->occluded_grouped(sorted.data(), sorted.size(), occ.data(), &co);
        size_t n_hits = 0;
        for (size_t k = 0; k < sorted.size(); ++k) {
            Hit h;
            tree->intersect(sorted[k], h, &cs);
            ASSERT_TRUE(test::bitwise_equal(h, hits[k])) << "seed " << seed << " ray " << k;
            ASSERT_EQ(occ[k], tree->occluded(sorted[k], &cso) ? 1 : 0) << k;
            const Hit ref = test::brute_force_hit(*mesh, sorted[k]);
            ASSERT_TRUE(test::same_closest_hit(*mesh, sorted[k], hits[k], ref)) << k;
            ASSERT_EQ(occ[k], test::brute_force_occluded(*mesh, sorted[k]) ? 1 : 0) << k;
            n_hits += hits[k].valid();
        }
        EXPECT_EQ(cg.nodes_visited, cs.nodes_visited);
        EXPECT_EQ(cg.triangles_tested, cs.triangles_tested);
        EXPECT_EQ(co.nodes_visited, cso.nodes_visited);
        EXPECT_GT(n_hits, sorted.size() / 4);
        EXPECT_LT(n_hits, sorted.size());
    }
}

}  // namespace
}  // namespace kdt
