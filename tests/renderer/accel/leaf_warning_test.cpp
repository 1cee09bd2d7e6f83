// kdtree_leaf_warning(): silent for the builders' defaults, one line naming the cause (no
// split candidates, q, the depth limit, the SAH traversal cost, the thesis builder's one axis
// at the root, inseparable triangles) when a leaf holds far more triangles than the parameters
// intend.
#include <cmath>
#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "renderer/accel/kdtree.h"
#include "renderer/io/mesh_io.h"
#include "tests/renderer/accel/kd_test_meshes.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

std::string warning_of(const TriangleMesh& mesh, const KdTreeParams& params) {
    return kdtree_leaf_warning(*build_kdtree(std::make_shared<const TriangleMesh>(mesh), params));
}

KdTreeParams with_builder(KdBuilder b) {
    KdTreeParams p;
    p.builder = b;
    return p;
}

TEST(LeafWarning, NoneForTheDefaults) {
    const TriangleMesh blob = test::make_blob(5, 1.0f, 7);  // 8192 triangles
    const TriangleMesh soup = test::make_soup(5000, 0.1f, 3);
    for (const KdBuilder b : {KdBuilder::sah, KdBuilder::thesis}) {
        EXPECT_EQ(warning_of(blob, with_builder(b)), "");
        EXPECT_EQ(warning_of(soup, with_builder(b)), "");
    }
    // A small mesh may well be one leaf.
    EXPECT_EQ(warning_of(test::make_blob(2, 1.0f, 7), with_builder(KdBuilder::sah)), "");
}

TEST(LeafWarning, NamesTheCause) {
    const TriangleMesh blob = test::make_blob(5, 1.0f, 7);
    for (const KdBuilder b : {KdBuilder::sah, KdBuilder::thesis}) {
        KdTreeParams p = with_builder(b);
        p.q = 0.5f;
        const std::string w = warning_of(blob, p);
        EXPECT_NE(w.find("--q 0.5 makes the leaf cost f(n) grow as n^0.00, so splitting never "
                         "pays; try --q 0.9 or more (default 0.98)"),
                  std::string::npos)
            << w;
        if (b == KdBuilder::sah) {
            EXPECT_EQ(w.rfind("the kd-tree's largest leaf holds 8192 triangles (the root is a "
                              "leaf): ",
                              0),
                      0u)
                << w;
        }
        p = with_builder(b);
        p.max_depth = 2;
        EXPECT_NE(warning_of(blob, p).find("at the depth limit 2; try a larger --depth"),
                  std::string::npos)
            << warning_of(blob, p);
    }
    KdTreeParams p;
    p.traversal_cost = 1e30f;
    EXPECT_NE(warning_of(blob, p).find("(the root is a leaf): --sah-traversal-cost 1e+30 exceeds"),
              std::string::npos)
        << warning_of(blob, p);
    // An intersection cost in range whose product with f(n) overflows float: every cost is
    // infinite, the root stays a leaf, and the warning once blamed the triangles ("no split
    // plane separates them"). 1e35 x 8192 is about 8e38.
    p = KdTreeParams{};
    p.intersect_cost = 1e35f;
    EXPECT_EQ(warning_of(blob, p),
              "the kd-tree's largest leaf holds 8192 triangles (the root is a leaf): "
              "--sah-intersect-cost 1e+35 times the leaf cost f(8192) overflows float, so no "
              "split prices below it; only the ratio of the costs matters: try "
              "--sah-intersect-cost 1 --sah-traversal-cost 4e-35");
    // 100 copies of one triangle: no plane separates them.
    TriangleMesh same;
    same.positions = {Vec3f(0, 0, 0), Vec3f(1, 0, 0), Vec3f(0, 1, 0)};
    for (int i = 0; i < 100; ++i) same.triangles.emplace_back(0, 1, 2);
    EXPECT_EQ(warning_of(same, KdTreeParams{}),
              "the kd-tree's largest leaf holds 100 triangles (the root is a leaf): no split "
              "plane separates them (coincident or overlapping triangles?)");
    // A tube along x: every triangle spans the whole x extent, so the thesis builder, which
    // tries x alone at the root, leaves it whole, and the warning says so; with all axes it
    // splits.
    TriangleMesh tube;
    for (int i = 0; i < 200; ++i) {
        const float a = float(i) * 0.0314159f, b = float(i + 1) * 0.0314159f;
        const uint32_t k = uint32_t(tube.positions.size());
        tube.positions.insert(tube.positions.end(), {Vec3f(0, std::cos(a), std::sin(a)),
                                                     Vec3f(10, std::cos(a), std::sin(a)),
                                                     Vec3f(10, std::cos(b), std::sin(b))});
        tube.triangles.emplace_back(k, k + 1, k + 2);
    }
    KdTreeParams thesis = with_builder(KdBuilder::thesis);
    EXPECT_EQ(warning_of(tube, thesis),
              "the kd-tree's largest leaf holds 200 triangles (the root is a leaf): no split "
              "plane along x separates them, the one axis the thesis builder tries at the root "
              "(it alternates x, y, z by depth); --all-axes tries all three, --builder sah "
              "chooses among them");
    thesis.thesis_all_axes = true;
    EXPECT_EQ(warning_of(tube, thesis), "");
    EXPECT_EQ(warning_of(tube, with_builder(KdBuilder::sah)), "");
    // A grid in the plane z = 0: the thesis builder splits x at the root and y below it, then
    // tries z, along which every box is flat, and stops at leaves of about a quarter of the
    // grid, which the warning must name (it once said nothing: 502,002-triangle leaves of a
    // 1000x1000 grid, 108,927 triangle tests per ray). All three axes split it.
    TriangleMesh grid;
    for (int y = 0; y <= 40; ++y)
        for (int x = 0; x <= 40; ++x) grid.positions.emplace_back(float(x), float(y), 0.0f);
    for (uint32_t y = 0; y < 40; ++y) {
        for (uint32_t x = 0; x < 40; ++x) {
            const uint32_t k = y * 41 + x;
            grid.triangles.emplace_back(k, k + 1, k + 42);
            grid.triangles.emplace_back(k, k + 42, k + 41);
        }
    }
    thesis = with_builder(KdBuilder::thesis);
    const std::string flat = warning_of(grid, thesis);
    EXPECT_NE(flat.find(": its box is flat along z, the one axis the thesis builder tries at "
                        "depth 2 (it alternates x, y, z by depth); --all-axes tries all three, "
                        "--builder sah chooses among them"),
              std::string::npos)
        << flat;
    thesis.thesis_all_axes = true;
    EXPECT_EQ(warning_of(grid, thesis), "");
    EXPECT_EQ(warning_of(grid, with_builder(KdBuilder::sah)), "");
    // No split candidates left: the flags are the cause, not the mesh.
    p = with_builder(KdBuilder::thesis);
    p.use_median_split = p.use_center_split = p.use_cutoff_split = false;
    EXPECT_EQ(warning_of(blob, p),
              "the kd-tree's largest leaf holds 8192 triangles (the root is a leaf): --no-median, "
              "--no-center and --no-cutoff leave the thesis builder no split candidates; drop one "
              "of them");
    p.use_cutoff_split = true;
    EXPECT_NE(warning_of(blob, p).find("(the root is a leaf): --no-median and --no-center leave "
                                       "the thesis builder only planes that cut off empty space"),
              std::string::npos)
        << warning_of(blob, p);
    for (bool median : {false, true}) {
        p.use_median_split = median;
        p.use_center_split = !median;
        EXPECT_EQ(warning_of(blob, p), "") << "median " << median;
    }
    // n0 raises the bounds: leaves of up to n0 triangles are what it asks for.
    p = KdTreeParams{};
    p.n0 = 200;
    EXPECT_EQ(warning_of(same, p), "");
}

// The Stanford dragon's scans at the defaults of both builders (the full scan takes a few
// seconds per builder, so the two coarsest only).
TEST(LeafWarning, NoneForTheDragonScans) {
    const auto dir = test::dragon_dir();
    if (dir.empty()) GTEST_SKIP() << "the Stanford dragon is not fetched (scripts/fetch_assets.sh)";
    for (const char* name : {"dragon_vrip_res4.ply", "dragon_vrip_res3.ply"}) {
        const auto mesh = std::make_shared<const TriangleMesh>(load_mesh((dir / name).string()));
        for (const KdBuilder b : {KdBuilder::sah, KdBuilder::thesis})
            EXPECT_EQ(kdtree_leaf_warning(*build_kdtree(mesh, with_builder(b))), "") << name;
    }
}

}  // namespace
}  // namespace kdt
