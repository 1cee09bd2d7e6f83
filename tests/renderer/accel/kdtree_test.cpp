// Cross-check of both builders' trees against brute force on seeded random rays, plus
// parameter validation, statistics and the node layout.
#include "renderer/accel/kdtree.h"

#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "renderer/accel/builder.h"
#include "renderer/core/error.h"
#include "renderer/geometry/intersect.h"
#include "tests/renderer/accel/kd_test_meshes.h"

namespace kdt {
namespace {

struct ParamCase {
    const char* name;
    KdTreeParams params;
};

KdTreeParams make_params(float q, int n0, int depth, bool all_axes = false) {
    KdTreeParams p;
    p.q = q;
    p.n0 = n0;
    p.max_depth = depth;
    p.thesis_all_axes = all_axes;
    return p;
}

const ParamCase kParamCases[] = {
    {"default", make_params(0.98f, 5, 0)},
    {"q1_n0_0_depth64_allaxes", make_params(1.0f, 0, 64, true)},
    {"q0.5_n0_2_depth12", make_params(0.5f, 2, 12)},
};

// Random rays of several kinds over a mesh: free, aimed at triangles, axis-aligned from
// vertex coordinates (origins on split planes), and with clipped intervals.
std::vector<Ray> make_rays(const TriangleMesh& mesh, size_t n, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u01(0.0f, 1.0f);
    const Bounds3f b = mesh.bounds();
    const Vec3f c = b.center(), e = b.extent() * 0.75f + Vec3f(0.1f);
    auto point = [&] {
        return c + e * Vec3f(2 * u01(rng) - 1, 2 * u01(rng) - 1, 2 * u01(rng) - 1);
    };
    auto sphere = [&] {
        float z = 2 * u01(rng) - 1, phi = 2 * kPi * u01(rng), r = std::sqrt(1 - z * z);
        return Vec3f(r * std::cos(phi), r * std::sin(phi), z);
    };
    std::vector<Ray> rays(n);
    for (size_t i = 0; i < n; ++i) {
        Ray& r = rays[i];
        r.origin = point();
        switch (i % 5) {
            case 0:
                r.dir = sphere();
                break;
            case 1:
            case 2: {  // aimed at a random point of a random triangle
                const Vec3u& t = mesh.triangles[rng() % mesh.triangles.size()];
                float a = u01(rng), bb = u01(rng);
                if (a + bb > 1) a = 1 - a, bb = 1 - bb;
                Vec3f target = mesh.positions[t.x] +
                               a * (mesh.positions[t.y] - mesh.positions[t.x]) +
                               bb * (mesh.positions[t.z] - mesh.positions[t.x]);
                r.dir = (target - r.origin) * (0.5f + u01(rng));
                break;
            }
            case 3: {  // axis-aligned, origin coordinates taken from vertices
                const Vec3f& v = mesh.positions[rng() % mesh.positions.size()];
                const int axis = int(rng() % 3);
                for (int k = 0; k < 3; ++k)
                    if (k != axis && (rng() & 1)) r.origin[k] = v[k];
                r.dir = Vec3f(0.0f);
                r.dir[axis] = (rng() & 1) ? 1.0f : -1.0f;
                break;
            }
            case 4:  // clipped interval
                r.dir = sphere() * (0.1f + 3 * u01(rng));
                r.tmin = 0.3f * u01(rng);
                r.tmax = r.tmin + 2 * u01(rng);
                break;
        }
    }
    return rays;
}

class KdTreeBruteForce : public ::testing::TestWithParam<std::tuple<KdBuilder, int>> {};

TEST_P(KdTreeBruteForce, ClosestAndAnyHitMatchBruteForce) {
    const KdBuilder builder = std::get<0>(GetParam());
    const ParamCase& pc = kParamCases[std::get<1>(GetParam())];
    KdTreeParams params = pc.params;
    params.builder = builder;
    // Small meshes keep the brute force affordable under the sanitizers.
    const TriangleMesh meshes[] = {test::make_blob(3, 1.0f, 11), test::make_soup(800, 0.3f, 12),
                                   test::make_planar_grid(14, 13)};
    size_t rays_checked = 0, hits = 0;
    for (size_t mi = 0; mi < std::size(meshes); ++mi) {
        auto mesh = std::make_shared<TriangleMesh>(meshes[mi]);
        auto tree = test::try_build(mesh, params);
        if (!tree) GTEST_SKIP() << "SAH builder not built yet (build_sah_tree throws)";
        const std::vector<Ray> rays = make_rays(*mesh, 12000, uint32_t(100 + mi));
        int failures = 0;
        for (size_t i = 0; i < rays.size() && failures < 5; ++i) {
            const Ray& r = rays[i];
            const Hit ref = test::brute_force_hit(*mesh, r);
            Hit hit;
            const bool got = tree->intersect(r, hit);
            ++rays_checked;
            hits += ref.valid();
            bool ok = got == hit.valid() && test::same_closest_hit(*mesh, r, hit, ref);
            const bool occ = tree->occluded(r);
            ok = ok && occ == (i % 4 ? got : test::brute_force_occluded(*mesh, r));
            if (!ok) {
                ++failures;
                ADD_FAILURE() << pc.name << " mesh " << mi << " ray " << i << ": tree "
                              << (got ? std::to_string(hit.t) + " prim " + std::to_string(hit.prim)
                                      : "miss")
                              << ", brute force "
                              << (ref.valid()
                                      ? std::to_string(ref.t) + " prim " + std::to_string(ref.prim)
                                      : "miss")
                              << ", occluded " << occ;
            }
        }
    }
    EXPECT_EQ(rays_checked, 36000u);
    EXPECT_GT(hits, rays_checked / 4);  // the comparison is not vacuous
}

INSTANTIATE_TEST_SUITE_P(Builders, KdTreeBruteForce,
                         ::testing::Combine(::testing::Values(KdBuilder::thesis, KdBuilder::sah),
                                            ::testing::Range(0, int(std::size(kParamCases)))),
                         [](const ::testing::TestParamInfo<std::tuple<KdBuilder, int>>& pi) {
                             std::string name =
                                 std::string(kKdBuilderNames[size_t(std::get<0>(pi.param))]) + "_" +
                                 kParamCases[std::get<1>(pi.param)].name;
                             for (char& ch : name)
                                 if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                             return name;
                         });

TEST(KdTreeParams, ValidateNamesTheBadParameter) {
    auto expect_error = [](KdTreeParams p, const std::string& name) {
        try {
            validate(p);
            ADD_FAILURE() << "no error for " << name;
        } catch (const Error& e) {
            EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
        }
    };
    KdTreeParams p;
    EXPECT_NO_THROW(validate(p));
    p.q = 0.0f;
    expect_error(p, "q");
    p.q = 1.0001f;
    expect_error(p, "q");
    p.q = std::numeric_limits<float>::quiet_NaN();
    expect_error(p, "q");
    p = {};
    p.n0 = -1;
    expect_error(p, "n0");
    p.n0 = 1000001;
    expect_error(p, "n0");
    p = {};
    p.max_depth = 65;
    expect_error(p, "max_depth");
    p.max_depth = -1;
    expect_error(p, "max_depth");
    p = {};
    p.q = 1.0f;
    p.n0 = 1000000;
    p.max_depth = 64;
    EXPECT_NO_THROW(validate(p));
    p.q = 1e-30f;
    p.n0 = 0;
    EXPECT_NO_THROW(validate(p));
    // build_kdtree validates too.
    KdTreeParams bad;
    bad.q = 2.0f;
    EXPECT_THROW(build_kdtree(std::make_shared<TriangleMesh>(), bad), Error);
}

// kd_tree_field_applies() is what the CLI warns by and the viewer greys out by: a field it
// calls foreign to a builder must not change that builder's tree, and one it calls the
// builder's own must be able to.
TEST(KdTreeParams, FieldsForeignToABuilderDoNotChangeItsTree) {
    auto mesh = std::make_shared<const TriangleMesh>(test::make_blob(4, 1.0f, 7));
    // A value other than the default for every field that takes part in the build.
    auto change = [](KdTreeParams& p, const std::string& name) {
        if (name == "use_median_split")
            p.use_median_split = false;
        else if (name == "use_center_split")
            p.use_center_split = false;
        else if (name == "use_cutoff_split")
            p.use_cutoff_split = false;
        else if (name == "thesis_all_axes")
            p.thesis_all_axes = true;
        else if (name == "traversal_cost")
            p.traversal_cost = 1.5f;
        else if (name == "intersect_cost")
            p.intersect_cost = 3.0f;
        else if (name == "empty_bonus")
            p.empty_bonus = 0.9f;
        else if (name == "q")
            p.q = 0.8f;
        else if (name == "n0")
            p.n0 = 1;
        else if (name == "max_depth")
            p.max_depth = 6;
        else
            return false;
        return true;
    };
    auto same = [](const KdTree& a, const KdTree& b) {
        return a.nodes().size() == b.nodes().size() && a.indices() == b.indices() &&
               std::memcmp(a.nodes().data(), b.nodes().data(), a.nodes().size() * sizeof(KdNode)) ==
                   0;
    };
    for (KdBuilder builder : {KdBuilder::thesis, KdBuilder::sah}) {
        KdTreeParams base;
        base.builder = builder;
        base.threads = 1;
        const auto reference = build_kdtree(mesh, base);
        int foreign = 0;
        for (const Field<KdTreeParams>& f : kd_tree_fields()) {
            KdTreeParams p = base;
            if (!change(p, f.name)) continue;  // builder, threads
            SCOPED_TRACE(std::string(kKdBuilderNames[size_t(builder)]) + " " + f.name);
            const auto tree = build_kdtree(mesh, p);
            if (kd_tree_field_applies(base, f.name)) {
                EXPECT_FALSE(same(*tree, *reference));
            } else {
                ++foreign;
                EXPECT_TRUE(same(*tree, *reference));
            }
        }
        EXPECT_GE(foreign, 3);
    }
}

TEST(ThesisF, MatchesTheFormula) {
    EXPECT_FLOAT_EQ(thesis_f(3.0f, 0.9f, 5), 3.0f);
    EXPECT_FLOAT_EQ(thesis_f(5.0f, 0.9f, 5), 5.0f);
    EXPECT_NEAR(thesis_f(21.0f, 0.9f, 5), std::pow(16.0f, 1.0f + std::log2(0.9f)) + 5.0f, 1e-4);
    EXPECT_FLOAT_EQ(thesis_f(21.0f, 1.0f, 5), 21.0f);
    EXPECT_LT(thesis_f(1000.0f, 0.98f, 5), 1000.0f);
}

TEST(ThesisBuilder, StatisticsAreConsistent) {
    auto mesh = std::make_shared<TriangleMesh>(test::make_blob(5, 1.0f, 3));
    KdTreeParams p;
    p.builder = KdBuilder::thesis;
    auto tree = build_kdtree(mesh, p);
    const KdTreeStats& s = tree->stats();
    EXPECT_EQ(s.nodes, tree->nodes().size());
    EXPECT_EQ(s.nodes, 2 * s.leaves - 1);
    EXPECT_EQ(s.references, tree->indices().size());
    EXPECT_EQ(s.nodes - s.leaves, s.median_splits + s.center_splits + s.cutoff_splits);
    EXPECT_EQ(s.sah_splits, 0u);
    EXPECT_GT(s.median_splits, 0u);
    EXPECT_GT(s.center_splits, 0u);
    EXPECT_GT(s.cutoff_splits, 0u);
    EXPECT_GE(s.refs_per_triangle, 1.0);
    // Nodes, indices, and each reference's three vertex indices (the render data) exactly
    // when they fit the budget together.
    const size_t ntri = mesh->triangle_count();
    const bool fits = s.nodes * 8 + s.references * 16 <= KdTree::kMaxBytesPerTriangle * ntri;
    ASSERT_EQ(tree->reference_triangles().size(), fits ? s.references : 0u);
    EXPECT_EQ(s.bytes, s.nodes * 8 + s.references * (fits ? 16 : 4));
    for (size_t i = 0; i < tree->reference_triangles().size(); ++i)
        ASSERT_EQ(tree->reference_triangles()[i], mesh->triangles[tree->indices()[i]]) << i;
    EXPECT_NEAR(s.bytes_per_triangle, double(s.bytes) / double(mesh->triangle_count()), 1e-9);
    uint64_t leaves = 0;
    for (uint64_t c : s.depth_histogram) leaves += c;
    EXPECT_EQ(leaves, s.leaves);
    EXPECT_EQ(s.depth_histogram.size(), s.max_depth_reached + 1u);
    // Automatic depth: 8 + 1.3 log2(N).
    EXPECT_LE(s.max_depth_reached, uint32_t(8 + 1.3 * std::log2(double(mesh->triangle_count()))));
    EXPECT_GT(s.build_seconds, 0.0);
    EXPECT_GT(s.peak_build_bytes, 0u);
    EXPECT_LE(s.max_leaf_size, 1000u);
    EXPECT_GT(s.mean_leaf_size, 0.0);

    // Layout: children adjacent and after their parent, every triangle referenced.
    std::vector<int> referenced(mesh->triangle_count(), 0);
    for (size_t i = 0; i < tree->nodes().size(); ++i) {
        const KdNode& n = tree->nodes()[i];
        if (n.is_leaf()) {
            for (uint32_t k = 0; k < n.count(); ++k) referenced[tree->indices()[n.first + k]] = 1;
        } else {
            EXPECT_GT(n.child(), i);
            EXPECT_LT(n.child() + 1, tree->nodes().size());
        }
    }
    for (int r : referenced) ASSERT_EQ(r, 1);
}

TEST(ThesisBuilder, CandidateSwitchesAreHonoured) {
    auto mesh = std::make_shared<TriangleMesh>(test::make_blob(4, 1.0f, 5));
    KdTreeParams p;
    p.builder = KdBuilder::thesis;
    p.use_median_split = false;
    auto t1 = build_kdtree(mesh, p);
    EXPECT_EQ(t1->stats().median_splits, 0u);
    EXPECT_GT(t1->stats().center_splits, 0u);
    p.use_median_split = true;
    p.use_center_split = false;
    auto t2 = build_kdtree(mesh, p);
    EXPECT_EQ(t2->stats().center_splits, 0u);
    EXPECT_GT(t2->stats().median_splits, 0u);
    p.use_center_split = p.use_median_split = p.use_cutoff_split = false;
    auto t3 = build_kdtree(mesh, p);  // only "terminate" is left
    EXPECT_EQ(t3->stats().nodes, 1u);
}

TEST(ThesisBuilder, ThreadCountDoesNotChangeTheTree) {
    auto mesh = std::make_shared<TriangleMesh>(test::make_blob(6, 1.0f, 9));  // 32k triangles
    KdTreeParams p;
    p.builder = KdBuilder::thesis;
    p.threads = 1;
    auto a = build_kdtree(mesh, p);
    p.threads = 2;
    auto b = build_kdtree(mesh, p);
    ASSERT_EQ(a->nodes().size(), b->nodes().size());
    ASSERT_EQ(a->indices(), b->indices());
    for (size_t i = 0; i < a->nodes().size(); ++i) {
        ASSERT_EQ(a->nodes()[i].word, b->nodes()[i].word) << i;
        ASSERT_EQ(a->nodes()[i].first, b->nodes()[i].first) << i;
    }
}

// A big blob next to a small one: the root's children are built as parts of very
// different sizes, which once changed the node order with the thread count.
TEST(ThesisBuilder, ThreadCountDoesNotChangeAnUnbalancedTree) {
    auto mesh = std::make_shared<TriangleMesh>(test::make_blob(6, 1.0f, 9));  // 32k triangles
    const TriangleMesh small = test::make_blob(3, 0.3f, 4);                   // 512 triangles
    const auto offset = uint32_t(mesh->positions.size());
    for (const Vec3f& v : small.positions) mesh->positions.push_back(v + Vec3f(3.0f, 0.5f, 0.0f));
    for (const Vec3u& t : small.triangles) mesh->triangles.push_back(t + Vec3u(offset));
    KdTreeParams p;
    p.builder = KdBuilder::thesis;
    p.max_depth = 20;
    p.threads = 1;
    auto a = build_kdtree(mesh, p);
    p.threads = 2;
    auto b = build_kdtree(mesh, p);
    ASSERT_EQ(a->nodes().size(), b->nodes().size());
    ASSERT_EQ(a->indices(), b->indices());
    for (size_t i = 0; i < a->nodes().size(); ++i) {
        ASSERT_EQ(a->nodes()[i].word, b->nodes()[i].word) << i;
        ASSERT_EQ(a->nodes()[i].first, b->nodes()[i].first) << i;
    }
}

// The builder's peak counts every buffer it holds, the final arrays included, and stays
// within twice the tree for the thesis's parameters (table 6.1: depth 20, n0 = 5).
TEST(ThesisBuilder, PeakBuildMemoryIsAtMostTwiceTheTree) {
    auto mesh = std::make_shared<TriangleMesh>(test::make_blob(6, 1.0f, 9));  // 32k triangles
    for (const float q : {0.9f, 0.98f, 1.0f}) {
        for (const bool median : {false, true}) {
            KdTreeParams p;
            p.builder = KdBuilder::thesis;
            p.q = q;
            p.use_median_split = median;
            p.max_depth = 20;
            p.threads = 2;
            const KdTreeStats s = build_kdtree(mesh, p)->stats();
            EXPECT_GE(s.peak_build_bytes, s.bytes) << "q " << q << ", median " << median;
            EXPECT_LE(s.peak_build_bytes, 2 * s.bytes) << "q " << q << ", median " << median;
        }
    }
}

// The per-reference vertex indices are stored only within the memory budget, and they are
// render data only: the same tree with them and without them gives bitwise the same hits.
TEST(KdTree, ReferenceTrianglesStayWithinTheBudgetAndNeverChangeAHit) {
    // Long slivers across the whole box: each is referenced from many leaves.
    std::mt19937 rng(17);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    auto slivers = std::make_shared<TriangleMesh>();
    for (uint32_t i = 0; i < 2000; ++i) {
        const Vec3f a(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng));
        slivers->positions.push_back(a);
        slivers->positions.push_back(b);
        slivers->positions.push_back(a + 0.02f * Vec3f(u(rng), u(rng), u(rng)));
        slivers->triangles.emplace_back(3 * i, 3 * i + 1, 3 * i + 2);
    }
    KdTreeParams p;
    p.builder = KdBuilder::thesis;
    p.q = 1.0f;
    p.max_depth = 20;
    const auto over = build_kdtree(slivers, p);
    const KdTreeStats& s = over->stats();
    ASSERT_GT(s.nodes * 8 + s.references * 16, KdTree::kMaxBytesPerTriangle * 2000)
        << "the test needs a tree over the budget";
    EXPECT_TRUE(over->reference_triangles().empty());
    EXPECT_EQ(s.bytes, s.nodes * 8 + s.references * 4);
    // The same nodes over a mesh with enough extra (unreferenced) triangles are within it.
    auto padded = std::make_shared<TriangleMesh>(*slivers);
    padded->triangles.resize((s.nodes * 8 + s.references * 16) / KdTree::kMaxBytesPerTriangle + 1,
                             Vec3u(0, 0, 0));
    const KdTree within(padded, over->bounds(), over->nodes(), over->indices(), p, s);
    ASSERT_EQ(within.reference_triangles().size(), s.references);
    for (size_t i = 0; i < s.references; ++i)
        ASSERT_EQ(within.reference_triangles()[i], slivers->triangles[within.indices()[i]]) << i;
    EXPECT_EQ(within.stats().bytes, s.nodes * 8 + s.references * 16);
    // A caller may ask for them over the budget, or go without them within it.
    const KdTree forced(slivers, over->bounds(), over->nodes(), over->indices(), p, s,
                        LeafVertexIndices::always);
    ASSERT_EQ(forced.reference_triangles().size(), s.references);
    EXPECT_EQ(forced.stats().bytes, s.nodes * 8 + s.references * 16);
    const KdTree without(padded, over->bounds(), over->nodes(), over->indices(), p, s,
                         LeafVertexIndices::never);
    EXPECT_TRUE(without.reference_triangles().empty());
    EXPECT_EQ(without.stats().bytes, s.nodes * 8 + s.references * 4);
    const std::vector<Ray> rays = make_rays(*slivers, 20000, 3);
    TraversalCounters ca, cb;
    size_t hits = 0;
    for (const Ray& r : rays) {
        Hit a, b;
        ASSERT_EQ(over->intersect(r, a, &ca), within.intersect(r, b, &cb));
        ASSERT_EQ(a.prim, b.prim);
        ASSERT_EQ(a.t, b.t);
        ASSERT_EQ(a.u, b.u);
        ASSERT_EQ(a.v, b.v);
        ASSERT_EQ(over->occluded(r), within.occluded(r));
        Hit c;
        ASSERT_EQ(forced.intersect(r, c), a.valid());
        ASSERT_EQ(c.prim, a.prim);
        ASSERT_EQ(c.t, a.t);
        ASSERT_EQ(forced.occluded(r), within.occluded(r));
        hits += a.valid() ? 1 : 0;
    }
    EXPECT_GT(hits, rays.size() / 4);
    EXPECT_EQ(ca.nodes_visited, cb.nodes_visited);
    EXPECT_EQ(ca.triangles_tested, cb.triangles_tested);
    std::vector<Hit> ha(rays.size()), hb(rays.size());
    over->intersect(rays.data(), rays.size(), ha.data());
    within.intersect(rays.data(), rays.size(), hb.data());
    for (size_t i = 0; i < rays.size(); ++i) {
        ASSERT_EQ(ha[i].prim, hb[i].prim) << i;
        ASSERT_EQ(ha[i].t, hb[i].t) << i;
    }
}

TEST(KdTree, ConstructorRejectsCorruptTrees) {
    auto mesh = std::make_shared<TriangleMesh>(test::make_soup(10, 0.3f, 1));
    auto make = [&](std::vector<KdNode> nodes, std::vector<uint32_t> indices) {
        return KdTree(mesh, mesh->bounds(), std::move(nodes), std::move(indices), {}, {});
    };
    EXPECT_NO_THROW(make({KdNode::make_leaf(2, 0)}, {0, 9}));
    EXPECT_THROW(make({KdNode::make_leaf(3, 0)}, {0, 9}), Error);     // past indices
    EXPECT_THROW(make({KdNode::make_leaf(2, 0)}, {0, 10}), Error);    // bad triangle
    EXPECT_THROW(make({KdNode::make_inner(0, 0.0f, 0)}, {}), Error);  // self loop
    EXPECT_THROW(make({KdNode::make_inner(0, 0.0f, 1), KdNode::make_leaf(0, 0)}, {}), Error);
    EXPECT_THROW(make({}, {}), Error);
    // A chain deeper than 64 levels.
    std::vector<KdNode> deep;
    for (uint32_t i = 0; i < 70; ++i) {
        deep.push_back(KdNode::make_inner(0, 0.0f, 2 * i + 1));
        deep.push_back(KdNode::make_leaf(0, 0));
    }
    deep.back() = KdNode::make_leaf(0, 0);
    deep.push_back(KdNode::make_leaf(0, 0));
    EXPECT_THROW(make(deep, {}), Error);
}

// The descent skips children flagged empty in their parent's word without reading them, so
// the flags must come from the children, whatever a builder or a cache file wrote.
TEST(KdTree, EmptyChildFlagsAreDerivedFromTheChildren) {
    // A closed surface: the builder cuts off the empty space inside and around it.
    auto mesh = std::make_shared<TriangleMesh>(test::make_blob(5, 1.0f, 3));
    const auto tree = build_kdtree(mesh, KdTreeParams{});
    ASSERT_GT(tree->stats().empty_leaves, 10u) << "the test needs empty leaves";
    std::vector<KdNode> lying = tree->nodes();
    uint64_t flagged = 0;
    for (KdNode& n : lying) {
        if (n.is_leaf()) continue;
        flagged += std::popcount(n.empty_children());
        n.set_empty_children(~n.empty_children());  // every flag wrong
    }
    ASSERT_EQ(flagged, tree->stats().empty_leaves);
    const KdTree rebuilt(mesh, tree->bounds(), lying, tree->indices(), tree->params(),
                         tree->stats());
    for (size_t i = 0; i < lying.size(); ++i) {
        const KdNode& n = rebuilt.nodes()[i];
        ASSERT_EQ(n.word, tree->nodes()[i].word) << i;
        if (n.is_leaf()) continue;
        const uint32_t want = uint32_t(rebuilt.nodes()[n.child()].is_empty_leaf()) |
                              (uint32_t(rebuilt.nodes()[n.child() + 1].is_empty_leaf()) << 1);
        ASSERT_EQ(n.empty_children(), want) << i;
    }
    uint64_t hits = 0;
    for (const Ray& r : make_rays(*mesh, 5000, 11)) {
        Hit a, b;
        ASSERT_EQ(tree->intersect(r, a), rebuilt.intersect(r, b));
        ASSERT_EQ(a.prim, b.prim);
        ASSERT_EQ(a.t, b.t);
        hits += a.valid() ? 1 : 0;
    }
    EXPECT_GT(hits, 1000u);
}

// Scaling a model by a power of two is exact, so both builders must make the same tree at
// any scale float holds: the SAH builder's surface areas, products of two extents, once
// overflowed float above extents of about 1e19 (and underflowed below 1e-19), and it then
// left the whole model in one leaf.
TEST(KdTree, SameTreeAtEveryPowerOfTwoScale) {
    const TriangleMesh base = test::make_blob(4, 1.0f, 31);
    for (KdBuilder builder : {KdBuilder::sah, KdBuilder::thesis}) {
        KdTreeParams p;
        p.builder = builder;
        const auto ref = build_kdtree(std::make_shared<TriangleMesh>(base), p);
        ASSERT_GT(ref->nodes().size(), 100u);
        for (int e : {-120, -66, 66, 100}) {
            const float s = std::ldexp(1.0f, e);
            auto scaled = std::make_shared<TriangleMesh>(base);
            for (Vec3f& v : scaled->positions) v *= s;
            const auto tree = build_kdtree(scaled, p);
            const std::string what =
                std::string(kKdBuilderNames[size_t(builder)]) + ", scale 2^" + std::to_string(e);
            ASSERT_EQ(tree->nodes().size(), ref->nodes().size()) << what;
            for (size_t i = 0; i < ref->nodes().size(); ++i) {
                const KdNode& a = ref->nodes()[i];
                const KdNode& b = tree->nodes()[i];
                ASSERT_EQ(a.word, b.word) << what << ": node " << i;
                // A split rounded outward from 0 is a subnormal, whose scaled value float
                // cannot hold: compare normal ones exactly.
                if (!a.is_leaf() && std::isnormal(a.split) && std::isnormal(a.split * s)) {
                    ASSERT_EQ(a.split * s, b.split) << what << ": node " << i;
                }
            }
            ASSERT_EQ(tree->indices(), ref->indices()) << what;
        }
    }
}

// A model wider than float's range (coordinates near +-2e38, so upper - lower overflows to
// infinity) once crashed the thesis builder: its median histogram took inf * 0 = NaN as a bin
// index. Both builders must build it, and rays from the centre must find what brute force does.
TEST(KdTree, ModelWiderThanFloatRangeBuildsAndTraces) {
    auto mesh = std::make_shared<TriangleMesh>(test::make_blob(3, 1.0f, 41));
    for (Vec3f& v : mesh->positions) v *= std::ldexp(1.0f, 127);  // radii up to 2.2e38
    const Bounds3f b = mesh->bounds();
    ASSERT_TRUE(std::isinf(b.upper.x - b.lower.x));
    std::mt19937 rng(42);
    std::normal_distribution<float> normal;
    for (KdBuilder builder : {KdBuilder::thesis, KdBuilder::sah}) {
        KdTreeParams p;
        p.builder = builder;
        const auto tree = build_kdtree(mesh, p);
        const std::string what = kKdBuilderNames[size_t(builder)];
        EXPECT_GT(tree->nodes().size(), 1u) << what;
        size_t hits = 0;
        for (int i = 0; i < 2000; ++i) {
            Ray r;
            r.origin = Vec3f(0.0f);
            r.dir = glm::normalize(Vec3f(normal(rng), normal(rng), normal(rng)));
            const Hit ref = test::brute_force_hit(*mesh, r);
            Hit hit;
            tree->intersect(r, hit);
            ASSERT_TRUE(test::same_closest_hit(*mesh, r, hit, ref)) << what << ": ray " << i;
            hits += hit.valid();
        }
        EXPECT_EQ(hits, 2000u) << what;  // the blob is closed around the origin
    }
}

// A build whose cancel flag is set gives no tree: BuildCancelled, whatever the builder and
// threads, and never a partial tree (the viewer drops a superseded build this way).
TEST(KdTree, CancelledBuildThrowsAndNeverReturnsAPartialTree) {
    auto mesh = std::make_shared<const TriangleMesh>(test::make_blob(6, 1.0f, 21));  // 32k
    for (KdBuilder builder : {KdBuilder::thesis, KdBuilder::sah}) {
        for (int threads : {1, 2}) {
            KdTreeParams p;
            p.builder = builder;
            p.threads = threads;
            const std::string what = std::string(kKdBuilderNames[size_t(builder)]) + ", threads " +
                                     std::to_string(threads);
            const std::atomic<bool> set{true};
            EXPECT_THROW(build_kdtree(mesh, p, &set), BuildCancelled) << what;
            const std::atomic<bool> clear{false};
            const auto whole = build_kdtree(mesh, p, &clear);
            EXPECT_EQ(whole->nodes().size(), build_kdtree(mesh, p)->nodes().size()) << what;
            // Set from another thread at some point of the build (or after it): either the
            // tree of an uncancelled build, node for node and reference for reference, or
            // BuildCancelled. Which one depends on timing; both are checked for.
            for (int delay_us : {0, 200, 1000, 5000, 20000}) {
                std::atomic<bool> flag{false};
                std::thread setter([&] {
                    std::this_thread::sleep_for(std::chrono::microseconds(delay_us));
                    flag = true;
                });
                std::shared_ptr<const KdTree> tree;
                try {
                    tree = build_kdtree(mesh, p, &flag);
                } catch (const BuildCancelled&) {
                }
                setter.join();
                if (!tree) continue;
                ASSERT_EQ(tree->nodes().size(), whole->nodes().size()) << what;
                EXPECT_EQ(std::memcmp(tree->nodes().data(), whole->nodes().data(),
                                      whole->nodes().size() * sizeof(KdNode)),
                          0)
                    << what;
                EXPECT_EQ(tree->indices(), whole->indices()) << what;
            }
        }
    }
}

}  // namespace
}  // namespace kdt
