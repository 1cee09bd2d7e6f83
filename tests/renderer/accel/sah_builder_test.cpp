// Tests of the SAH kd-tree builder (renderer/accel/sah_builder.*): structural validity of the
// node array, exact leaf membership of every triangle against the leaf boxes rebuilt from the
// splits, degenerate inputs, and the conservative triangle clipping.
#include "renderer/accel/sah_builder.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "renderer/core/error.h"
#include "renderer/geometry/intersect.h"
#include "renderer/io/mesh_io.h"
#include "tests/renderer/accel/kd_test_meshes.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

// ----------------------------------------------------------------------------------------
// Meshes.

TriangleMesh random_soup(size_t count, uint32_t seed, float max_size) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> pos(-1.0f, 1.0f), off(-max_size, max_size);
    TriangleMesh m;
    for (size_t i = 0; i < count; ++i) {
        const Vec3f c(pos(rng), pos(rng), pos(rng));
        const auto base = uint32_t(m.positions.size());
        for (int j = 0; j < 3; ++j) m.positions.push_back(c + Vec3f(off(rng), off(rng), off(rng)));
        m.triangles.emplace_back(base, base + 1, base + 2);
    }
    return m;
}

TriangleMesh uv_sphere(int rings, int segments) {
    TriangleMesh m;
    for (int r = 0; r <= rings; ++r) {
        const float theta = kPi * float(r) / float(rings);
        for (int s = 0; s < segments; ++s) {
            const float phi = 2.0f * kPi * float(s) / float(segments);
            m.positions.emplace_back(std::sin(theta) * std::cos(phi), std::cos(theta),
                                     std::sin(theta) * std::sin(phi));
        }
    }
    auto at = [&](int r, int s) { return uint32_t(r * segments + (s % segments)); };
    for (int r = 0; r < rings; ++r) {
        for (int s = 0; s < segments; ++s) {
            if (r > 0) m.triangles.emplace_back(at(r, s), at(r, s + 1), at(r + 1, s));
            if (r < rings - 1)
                m.triangles.emplace_back(at(r, s + 1), at(r + 1, s + 1), at(r + 1, s));
        }
    }
    return m;
}

/// An n x n grid of squares in the plane z = 0: zero extent on z.
TriangleMesh flat_grid(int n) {
    TriangleMesh m;
    for (int y = 0; y <= n; ++y) {
        for (int x = 0; x <= n; ++x) m.positions.emplace_back(float(x), float(y), 0.0f);
    }
    auto at = [&](int x, int y) { return uint32_t(y * (n + 1) + x); };
    for (int y = 0; y < n; ++y) {
        for (int x = 0; x < n; ++x) {
            m.triangles.emplace_back(at(x, y), at(x + 1, y), at(x + 1, y + 1));
            m.triangles.emplace_back(at(x, y), at(x + 1, y + 1), at(x, y + 1));
        }
    }
    return m;
}

/// Axis-aligned unit cubes on an integer lattice: every face is planar and lies on the
/// split planes the sweep proposes.
TriangleMesh cube_lattice(int n) {
    TriangleMesh m;
    for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j) {
            for (int k = 0; k < n; ++k) {
                if ((i + j + k) % 2) continue;
                const auto base = uint32_t(m.positions.size());
                for (int c = 0; c < 8; ++c) {
                    m.positions.emplace_back(float(i + (c & 1)), float(j + ((c >> 1) & 1)),
                                             float(k + ((c >> 2) & 1)));
                }
                const uint32_t quads[6][4] = {{0, 1, 3, 2}, {4, 6, 7, 5}, {0, 4, 5, 1},
                                              {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 5, 7, 3}};
                for (const auto& q : quads) {
                    m.triangles.emplace_back(base + q[0], base + q[1], base + q[2]);
                    m.triangles.emplace_back(base + q[0], base + q[2], base + q[3]);
                }
            }
        }
    }
    return m;
}

/// Large triangles overlapping in the plane z = 0, their vertices anywhere in the unit
/// square: every split plane cuts most of them, the input that made the SAH builder double
/// its references at every level before the reference budget.
TriangleMesh overlapping_soup(size_t count, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    TriangleMesh m;
    for (size_t i = 0; i < 3 * count; ++i) m.positions.emplace_back(u(rng), u(rng), 0.0f);
    for (size_t i = 0; i < count; ++i) {
        const auto base = uint32_t(3 * i);
        m.triangles.emplace_back(base, base + 1, base + 2);
    }
    return m;
}

bool triangle_valid(const TriangleMesh& m, size_t i) {
    const Vec3u& t = m.triangles[i];
    return is_finite(m.positions[t.x]) && is_finite(m.positions[t.y]) &&
           is_finite(m.positions[t.z]) && t.x != t.y && t.y != t.z && t.z != t.x;
}

// ----------------------------------------------------------------------------------------
// Independent geometry for the checks (double precision, written apart from the builder).

/// True when the triangle meets the closed box [lo, hi] (Sutherland-Hodgman in double).
bool triangle_meets_box(const TriangleMesh& m, size_t tri, const Vec3d& lo, const Vec3d& hi) {
    std::vector<Vec3d> poly, next;
    for (int j = 0; j < 3; ++j) poly.emplace_back(m.positions[m.triangles[tri][j]]);
    for (int k = 0; k < 3; ++k) {
        for (int upper = 0; upper < 2; ++upper) {
            const double plane = upper ? hi[k] : lo[k];
            auto inside = [&](const Vec3d& v) { return upper ? v[k] <= plane : v[k] >= plane; };
            next.clear();
            for (size_t i = 0; i < poly.size(); ++i) {
                const Vec3d& p = poly[i];
                const Vec3d& q = poly[(i + 1) % poly.size()];
                if (inside(p)) next.push_back(p);
                if (inside(p) != inside(q)) {
                    Vec3d x = p + (plane - p[k]) / (q[k] - p[k]) * (q - p);
                    x[k] = plane;
                    next.push_back(x);
                }
            }
            poly.swap(next);
            if (poly.empty()) return false;
        }
    }
    return true;
}

struct LeafInfo {
    Vec3d lo, hi;
    bool open_lo[3], open_hi[3];  // faces made by a split (the side only its own child owns)
    std::vector<uint32_t> tris;   // sorted
};

struct TreeReport {
    std::vector<LeafInfo> leaves;
    int max_depth = 0;
    size_t inner = 0;
    double sah_cost = 0.0;  // expected cost, traversal 1 / intersection 1, relative to root
};

/// Walks the tree and checks the layout; rebuilds every leaf's box from the splits.
TreeReport check_layout(const TriangleMesh& mesh, const KdBuildOutput& out) {
    TreeReport rep;
    EXPECT_FALSE(out.nodes.empty());
    if (out.nodes.empty()) return rep;
    std::vector<int> seen(out.nodes.size(), 0);
    uint64_t total_refs = 0;
    const double root_area = out.bounds.surface_area();
    struct Item {
        uint32_t node;
        int depth;
        LeafInfo box;
    };
    LeafInfo root{};
    root.lo = Vec3d(out.bounds.lower);
    root.hi = Vec3d(out.bounds.upper);
    std::vector<Item> stack{{0, 0, root}};
    while (!stack.empty()) {
        Item it = stack.back();
        stack.pop_back();
        EXPECT_EQ(seen[it.node]++, 0) << "node " << it.node << " reached twice";
        rep.max_depth = std::max(rep.max_depth, it.depth);
        const KdNode& nd = out.nodes[it.node];
        Bounds3f fbox;
        fbox.lower = Vec3f(it.box.lo);
        fbox.upper = Vec3f(it.box.hi);
        const double p = root_area > 0 ? fbox.surface_area() / root_area : 1.0;
        if (nd.is_leaf()) {
            rep.sah_cost += p * nd.count();
            total_refs += nd.count();
            EXPECT_LE(uint64_t(nd.first) + nd.count(), out.indices.size());
            if (uint64_t(nd.first) + nd.count() > out.indices.size()) continue;
            LeafInfo leaf = it.box;
            leaf.tris.assign(out.indices.begin() + nd.first,
                             out.indices.begin() + nd.first + nd.count());
            std::sort(leaf.tris.begin(), leaf.tris.end());
            EXPECT_TRUE(std::adjacent_find(leaf.tris.begin(), leaf.tris.end()) == leaf.tris.end())
                << "duplicate triangle in leaf " << it.node;
            for (uint32_t t : leaf.tris) {
                EXPECT_LT(t, mesh.triangle_count());
                if (t < mesh.triangle_count()) {
                    EXPECT_TRUE(triangle_valid(mesh, t)) << "non-finite triangle " << t;
                }
            }
            rep.leaves.push_back(std::move(leaf));
            continue;
        }
        ++rep.inner;
        rep.sah_cost += p;
        const uint32_t c = nd.child();
        EXPECT_GT(c, it.node);
        EXPECT_LT(uint64_t(c) + 1, out.nodes.size());
        if (c <= it.node || uint64_t(c) + 1 >= out.nodes.size()) continue;
        const int k = nd.axis();
        const double s = nd.split;
        // No split on (or outside) the cell boundary.
        EXPECT_GT(s, it.box.lo[k]) << "node " << it.node;
        EXPECT_LT(s, it.box.hi[k]) << "node " << it.node;
        Item left{c, it.depth + 1, it.box}, right{c + 1, it.depth + 1, it.box};
        left.box.hi[k] = s;
        left.box.open_hi[k] = true;
        right.box.lo[k] = s;
        right.box.open_lo[k] = true;
        stack.push_back(right);
        stack.push_back(left);
    }
    for (size_t i = 0; i < seen.size(); ++i) EXPECT_EQ(seen[i], 1) << "node " << i;
    EXPECT_EQ(total_refs, out.indices.size()) << "leaf ranges must cover the index array";
    return rep;
}

/// Leaves whose closed box the point lies in (both sides when it lies on a split).
void leaves_at(const KdBuildOutput& out, uint32_t node, const Vec3d& p, std::vector<uint32_t>& r) {
    const KdNode& nd = out.nodes[node];
    if (nd.is_leaf()) {
        r.push_back(node);
        return;
    }
    const double s = nd.split;
    if (p[nd.axis()] <= s) leaves_at(out, nd.child(), p, r);
    if (p[nd.axis()] >= s) leaves_at(out, nd.child() + 1, p, r);
}

/// (a) every triangle meeting a leaf's box, with the faces made by splits opened by a tiny
/// margin, is referenced by that leaf; (b) every vertex and the centroid of every triangle
/// lies in the closed box of some leaf that references it (covers touching and planar
/// triangles on a split, which go to one side only).
void check_membership(const TriangleMesh& mesh, const KdBuildOutput& out, const TreeReport& rep) {
    const Bounds3f root = out.bounds;
    double magnitude = 1e-30;
    for (int k = 0; k < 3; ++k) {
        magnitude =
            std::max({magnitude, std::abs(double(root.lower[k])), std::abs(double(root.upper[k]))});
    }
    const double margin = 1e-10 * magnitude;
    size_t missing = 0, uncovered = 0;
    std::vector<uint32_t> leaf_nodes;
    // Map from leaf node index to report entry (same DFS order as check_layout).
    std::vector<const LeafInfo*> by_node(out.nodes.size(), nullptr);
    {
        size_t li = 0;
        std::vector<uint32_t> stack{0};
        while (!stack.empty()) {
            const uint32_t n = stack.back();
            stack.pop_back();
            if (out.nodes[n].is_leaf()) {
                if (li < rep.leaves.size()) by_node[n] = &rep.leaves[li++];
                continue;
            }
            stack.push_back(out.nodes[n].child() + 1);
            stack.push_back(out.nodes[n].child());
        }
    }
    for (size_t t = 0; t < mesh.triangle_count(); ++t) {
        if (!triangle_valid(mesh, t)) continue;
        const Bounds3f tb = mesh.triangle_bounds(t);
        // Leaves whose boxes the triangle's bounds touch, then the exact test on each.
        std::vector<uint32_t> stack{0};
        while (!stack.empty()) {
            const uint32_t n = stack.back();
            stack.pop_back();
            const KdNode& nd = out.nodes[n];
            if (!nd.is_leaf()) {
                if (tb.lower[nd.axis()] <= nd.split) stack.push_back(nd.child());
                if (tb.upper[nd.axis()] >= nd.split) stack.push_back(nd.child() + 1);
                continue;
            }
            const LeafInfo& leaf = *by_node[n];
            Vec3d lo = leaf.lo, hi = leaf.hi;
            bool skip = false;
            for (int k = 0; k < 3; ++k) {
                if (leaf.open_lo[k]) lo[k] += margin;
                if (leaf.open_hi[k]) hi[k] -= margin;
                if (lo[k] > hi[k]) skip = true;
            }
            if (skip || !triangle_meets_box(mesh, t, lo, hi)) continue;
            if (!std::binary_search(leaf.tris.begin(), leaf.tris.end(), uint32_t(t))) {
                if (++missing <= 5) ADD_FAILURE() << "triangle " << t << " missing from a leaf";
            }
        }
        const Vec3u& tri = mesh.triangles[t];
        Vec3d pts[4] = {Vec3d(mesh.positions[tri.x]), Vec3d(mesh.positions[tri.y]),
                        Vec3d(mesh.positions[tri.z]), Vec3d(0.0)};
        pts[3] = (pts[0] + pts[1] + pts[2]) / 3.0;
        for (const Vec3d& p : pts) {
            leaf_nodes.clear();
            leaves_at(out, 0, p, leaf_nodes);
            bool found = false;
            for (uint32_t n : leaf_nodes) {
                const LeafInfo* leaf = by_node[n];
                if (leaf && std::binary_search(leaf->tris.begin(), leaf->tris.end(), uint32_t(t))) {
                    found = true;
                }
            }
            if (!found && ++uncovered <= 5) {
                ADD_FAILURE() << "a point of triangle " << t << " lies in no leaf referencing it";
            }
        }
    }
    EXPECT_EQ(missing, 0u);
    EXPECT_EQ(uncovered, 0u);
}

TreeReport check_tree(const TriangleMesh& mesh, const KdBuildOutput& out, int max_depth) {
    TreeReport rep = check_layout(mesh, out);
    EXPECT_LE(rep.max_depth, max_depth);
    EXPECT_EQ(out.stats.sah_splits, rep.inner);
    if (!::testing::Test::HasFailure()) check_membership(mesh, out, rep);
    return rep;
}

int auto_depth(size_t n) {
    return std::min(64, int(8.0 + 1.3 * std::log2(double(std::max<size_t>(n, 1)))));
}

/// Tiny thresholds so that small meshes run through the binned phase and the task split.
SahTuning binned_tuning() {
    SahTuning t;
    t.sweep_threshold = 24;
    t.bins = 8;
    t.task_threshold = 64;
    return t;
}

// ----------------------------------------------------------------------------------------
// Tests.

TEST(SahBuilder, RandomSoupsAreValid) {
    for (uint32_t seed : {1u, 2u, 3u}) {
        const TriangleMesh mesh = random_soup(1500, seed, seed == 3 ? 0.5f : 0.05f);
        KdTreeParams params;
        const KdBuildOutput out = build_sah_tree(mesh, params);
        const TreeReport rep = check_tree(mesh, out, auto_depth(mesh.triangle_count()));
        EXPECT_GT(rep.inner, 10u) << "seed " << seed;
        EXPECT_EQ(out.bounds.lower, mesh.bounds().lower);
        EXPECT_EQ(out.bounds.upper, mesh.bounds().upper);
    }
}

TEST(SahBuilder, BinnedTopLevelsAreValid) {
    const TriangleMesh mesh = random_soup(3000, 7, 0.08f);
    KdTreeParams params;
    params.threads = 2;
    const KdBuildOutput out = build_sah_tree(mesh, params, binned_tuning());
    const TreeReport rep = check_tree(mesh, out, auto_depth(mesh.triangle_count()));
    EXPECT_GT(rep.inner, 100u);
}

TEST(SahBuilder, SphereIsValidAndCompact) {
    const TriangleMesh mesh = uv_sphere(40, 80);
    KdTreeParams params;
    for (const SahTuning& tuning : {SahTuning{}, binned_tuning()}) {
        const KdBuildOutput out = build_sah_tree(mesh, params, tuning);
        const TreeReport rep = check_tree(mesh, out, auto_depth(mesh.triangle_count()));
        const double refs = double(out.indices.size()) / double(mesh.triangle_count());
        EXPECT_GT(refs, 1.0);
        EXPECT_LT(refs, 5.0);
        // A useful tree: far cheaper than testing every triangle.
        EXPECT_LT(rep.sah_cost, 0.05 * double(mesh.triangle_count()));
    }
}

TEST(SahBuilder, FlatGridIsValid) {
    const TriangleMesh mesh = flat_grid(40);
    KdTreeParams params;
    for (const SahTuning& tuning : {SahTuning{}, binned_tuning()}) {
        const KdBuildOutput out = build_sah_tree(mesh, params, tuning);
        const TreeReport rep = check_tree(mesh, out, auto_depth(mesh.triangle_count()));
        EXPECT_GT(rep.inner, 10u);
        EXPECT_EQ(out.bounds.lower.z, 0.0f);
        EXPECT_EQ(out.bounds.upper.z, 0.0f);
    }
}

TEST(SahBuilder, PlanarFacesOnSplitPlanesAreValid) {
    const TriangleMesh mesh = cube_lattice(6);
    KdTreeParams params;
    for (const SahTuning& tuning : {SahTuning{}, binned_tuning()}) {
        const KdBuildOutput out = build_sah_tree(mesh, params, tuning);
        const TreeReport rep = check_tree(mesh, out, auto_depth(mesh.triangle_count()));
        EXPECT_GT(rep.inner, 10u);
    }
}

TEST(SahBuilder, EmptyMeshIsOneEmptyLeaf) {
    const TriangleMesh mesh;
    const KdBuildOutput out = build_sah_tree(mesh, KdTreeParams{});
    ASSERT_EQ(out.nodes.size(), 1u);
    EXPECT_TRUE(out.nodes[0].is_leaf());
    EXPECT_EQ(out.nodes[0].count(), 0u);
    EXPECT_TRUE(out.indices.empty());
    EXPECT_TRUE(out.bounds.empty());
}

TEST(SahBuilder, NonFiniteTrianglesAreNeverReferenced) {
    TriangleMesh mesh = random_soup(800, 11, 0.05f);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (size_t i = 0; i < mesh.triangle_count(); i += 7) {
        mesh.positions[mesh.triangles[i][int(i % 3)]] = Vec3f(nan, 0.0f, 0.0f);
    }
    mesh.positions[mesh.triangles[3].y] = Vec3f(0.0f, kInfinity, 0.0f);
    const KdBuildOutput out = build_sah_tree(mesh, KdTreeParams{});
    check_tree(mesh, out, auto_depth(mesh.triangle_count()));
    for (uint32_t t : out.indices) EXPECT_TRUE(triangle_valid(mesh, t)) << t;
    EXPECT_TRUE(std::find(out.indices.begin(), out.indices.end(), 3u) == out.indices.end());

    TriangleMesh all_nan = mesh;
    for (Vec3f& p : all_nan.positions) p = Vec3f(nan);
    const KdBuildOutput none = build_sah_tree(all_nan, KdTreeParams{});
    ASSERT_EQ(none.nodes.size(), 1u);
    EXPECT_EQ(none.nodes[0].count(), 0u);
}

TEST(SahBuilder, ZeroAreaTrianglesAreValid) {
    TriangleMesh mesh = random_soup(600, 5, 0.05f);
    std::mt19937 rng(9);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    for (int i = 0; i < 300; ++i) {
        const auto base = uint32_t(mesh.positions.size());
        const Vec3f a(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng));
        mesh.positions.push_back(a);
        mesh.positions.push_back(i % 2 ? b : a);  // points and collinear segments
        mesh.positions.push_back(i % 2 ? 0.5f * (a + b) : a);
        mesh.triangles.emplace_back(base, base + 1, base + 2);
    }
    for (const SahTuning& tuning : {SahTuning{}, binned_tuning()}) {
        const KdBuildOutput out = build_sah_tree(mesh, KdTreeParams{}, tuning);
        check_tree(mesh, out, auto_depth(mesh.triangle_count()));
    }
}

// Faces with a repeated vertex index (junk in scanned meshes) can never be hit: the thesis
// builder leaves them out, and so must the SAH builder. 100,000 of them as long segments
// across the box once cost 711,434 splits and 448 bytes per triangle at q 1, n0 0, depth 64.
TEST(SahBuilder, RepeatedIndexTrianglesAreNeverReferenced) {
    TriangleMesh mesh = random_soup(400, 13, 0.05f);
    const size_t hittable = mesh.triangle_count();
    std::mt19937 rng(17);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    for (int i = 0; i < 2000; ++i) {
        const auto base = uint32_t(mesh.positions.size());
        mesh.positions.emplace_back(u(rng), u(rng), u(rng));
        mesh.positions.emplace_back(u(rng), u(rng), u(rng));
        const int k = i % 3;  // the repeated index in each position
        mesh.triangles.emplace_back(k == 2 ? base + 1 : base, k == 0 ? base : base + 1,
                                    k == 1 ? base + 1 : base);
    }
    KdTreeParams p;
    p.q = 1.0f;
    p.n0 = 0;
    p.max_depth = 64;
    for (const SahTuning& tuning : {SahTuning{}, binned_tuning()}) {
        const KdBuildOutput out = build_sah_tree(mesh, p, tuning);
        check_tree(mesh, out, 64);
        for (uint32_t t : out.indices) ASSERT_LT(t, hittable) << "a repeated-index triangle";
    }
}

TEST(SahBuilder, IdenticalTrianglesMakeOneLeaf) {
    TriangleMesh mesh;
    mesh.positions = {Vec3f(0, 0, 0), Vec3f(1, 0, 0), Vec3f(0, 1, 0.5f)};
    for (int i = 0; i < 200; ++i) mesh.triangles.emplace_back(0, 1, 2);
    const KdBuildOutput out = build_sah_tree(mesh, KdTreeParams{}, binned_tuning());
    check_tree(mesh, out, auto_depth(mesh.triangle_count()));
    ASSERT_EQ(out.nodes.size(), 1u);
    EXPECT_EQ(out.nodes[0].count(), 200u);
}

TEST(SahBuilder, DepthLimitsAreHonoured) {
    const TriangleMesh mesh = random_soup(2000, 21, 0.03f);
    for (int depth : {1, 3, 64}) {
        KdTreeParams params;
        params.max_depth = depth;
        for (const SahTuning& tuning : {SahTuning{}, binned_tuning()}) {
            const KdBuildOutput out = build_sah_tree(mesh, params, tuning);
            check_tree(mesh, out, depth);
            if (depth == 1) {
                EXPECT_EQ(out.nodes.size(), 3u);
            }
        }
    }
}

TEST(SahBuilder, DeepTreeOnClusteredInput) {
    // Tiny triangles crowded in a corner of a huge box: needs many empty-space cuts.
    TriangleMesh mesh = random_soup(1000, 4, 1e-4f);
    for (Vec3f& p : mesh.positions) p = p * 1e-3f;
    mesh.positions.push_back(Vec3f(1000.0f));  // unreferenced vertex widening the bounds
    KdTreeParams params;
    params.max_depth = 64;
    params.traversal_cost = 1.0f;
    params.intersect_cost = 1.5f;
    const KdBuildOutput out = build_sah_tree(mesh, params);
    const TreeReport rep = check_tree(mesh, out, 64);
    EXPECT_GT(rep.max_depth, 20);
}

/// Whether two builds made the same tree: nodes bit for bit and the same leaf indices.
::testing::AssertionResult same_tree(const KdBuildOutput& a, const KdBuildOutput& b) {
    if (a.nodes.size() != b.nodes.size())
        return ::testing::AssertionFailure()
               << a.nodes.size() << " nodes against " << b.nodes.size();
    for (size_t i = 0; i < a.nodes.size(); ++i) {
        if (a.nodes[i].word != b.nodes[i].word || a.nodes[i].first != b.nodes[i].first)
            return ::testing::AssertionFailure() << "node " << i << " differs";
    }
    if (a.indices != b.indices) return ::testing::AssertionFailure() << "leaf indices differ";
    return ::testing::AssertionSuccess();
}

TEST(SahBuilder, OverlappingTrianglesStayWithinTheReferenceBudget) {
    const TriangleMesh mesh = overlapping_soup(1500, 5);
    const auto n = double(mesh.triangle_count());
    // The default budget is a bound worth having: at most a few hundred per triangle.
    EXPECT_LE(SahTuning{}.ref_budget_per_triangle, 1024.0);
    for (const double budget : {SahTuning{}.ref_budget_per_triangle, 64.0, 8.0}) {
        for (SahTuning tuning : {SahTuning{}, binned_tuning()}) {
            tuning.ref_budget_per_triangle = budget;
            KdTreeParams params;
            params.threads = 2;
            const KdBuildOutput out = build_sah_tree(mesh, params, tuning);
            check_tree(mesh, out, auto_depth(mesh.triangle_count()));
            EXPECT_LE(double(out.indices.size()), budget * n) << "budget " << budget;
            EXPECT_GT(out.stats.sah_splits, 4u) << "budget " << budget;
            // Still a tree for any thread count.
            params.threads = 1;
            EXPECT_TRUE(same_tree(build_sah_tree(mesh, params, tuning), out))
                << "budget " << budget;
        }
    }
}

// The default budget binds only where references multiply level after level: ordinary
// meshes get the trees an unlimited budget gives (the dragon's coarser version needs more
// than 16 references per triangle along some paths, a budget of 32 leaves it alone).
TEST(SahBuilder, ReferenceBudgetLeavesOrdinaryTreesAlone) {
    std::vector<TriangleMesh> meshes;
    meshes.push_back(uv_sphere(30, 60));
    meshes.push_back(random_soup(3000, 9, 0.2f));
    meshes.push_back(cube_lattice(5));
    if (const auto dragon = test::load_dragon_res2()) meshes.push_back(*dragon);
    for (size_t mi = 0; mi < meshes.size(); ++mi) {
        SahTuning unlimited;
        unlimited.ref_budget_per_triangle = std::numeric_limits<double>::infinity();
        EXPECT_TRUE(same_tree(build_sah_tree(meshes[mi], KdTreeParams{}),
                              build_sah_tree(meshes[mi], KdTreeParams{}, unlimited)))
            << "mesh " << mi;
    }
}

TEST(SahBuilder, SameTreeForAnyThreadCount) {
    const TriangleMesh mesh = random_soup(4000, 8, 0.05f);
    KdTreeParams one, two;
    one.threads = 1;
    two.threads = 2;
    EXPECT_TRUE(same_tree(build_sah_tree(mesh, one, binned_tuning()),
                          build_sah_tree(mesh, two, binned_tuning())));
}

TEST(SahBuilder, CostParametersChangeTheTree) {
    const TriangleMesh mesh = uv_sphere(30, 60);
    KdTreeParams cheap, costly;
    cheap.intersect_cost = 10.0f;   // intersections expensive: split deeper
    costly.traversal_cost = 10.0f;  // traversal expensive: shallower tree
    const KdBuildOutput a = build_sah_tree(mesh, cheap);
    const KdBuildOutput b = build_sah_tree(mesh, costly);
    EXPECT_GT(a.stats.sah_splits, 2 * b.stats.sah_splits);
    KdTreeParams linear;
    linear.q = 1.0f;
    linear.n0 = 0;
    check_tree(mesh, build_sah_tree(mesh, linear), auto_depth(mesh.triangle_count()));
}

TEST(SahBuilder, ReportsScratchMemory) {
    const TriangleMesh mesh = random_soup(2000, 12, 0.05f);
    const KdBuildOutput out = build_sah_tree(mesh, KdTreeParams{});
    EXPECT_GT(out.stats.peak_build_bytes, 28u * mesh.triangle_count());
}

// The peak counts every buffer the builder holds, the final arrays included, and stays
// within twice the tree once the mesh is large next to the per-thread sweep buffers (those
// scale with the sweep threshold, not with the mesh: the dragon needs the default 2048, a
// 40k-triangle sphere a smaller one).
TEST(SahBuilder, PeakBuildMemoryIsAtMostTwiceTheTree) {
    const TriangleMesh mesh = uv_sphere(100, 200);  // 40k triangles
    SahTuning tuning;
    tuning.sweep_threshold = 256;
    for (const int threads : {1, 2}) {
        KdTreeParams params;
        params.threads = threads;
        // Costs that make a tree of about one node per triangle, as on the dragon; the
        // default costs make a smaller tree, and the bound is then checked by
        // `kdtrace bench kdtree` on the dragon itself (peak build MB against size KB).
        params.traversal_cost = 3.0f;
        params.intersect_cost = 1.5f;
        const KdBuildOutput out = build_sah_tree(mesh, params, tuning);
        EXPECT_GE(out.stats.peak_build_bytes, out.stats.bytes) << threads << " threads";
        EXPECT_LE(out.stats.peak_build_bytes, 2 * out.stats.bytes) << threads << " threads";
    }
}

TEST(SahBuilder, OutOfRangeIndexThrows) {
    TriangleMesh mesh = random_soup(10, 1, 0.1f);
    mesh.triangles[4].y = 1000;
    try {
        build_sah_tree(mesh, KdTreeParams{});
        FAIL() << "expected kdt::Error";
    } catch (const Error& e) {
        EXPECT_EQ(e.where().index, 4);
        EXPECT_NE(std::string(e.what()).find("1000"), std::string::npos) << e.what();
    }
}

// ----------------------------------------------------------------------------------------
// Queries through KdTree on SAH trees against brute force.

/// Seeded rays of five kinds: random, aimed at triangles, axis-aligned from vertex
/// coordinates, lying exactly in one of the tree's split planes, and with a clipped interval.
std::vector<Ray> make_rays(const TriangleMesh& mesh, const KdBuildOutput& tree, size_t n,
                           uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u01(0.0f, 1.0f);
    const Bounds3f b = mesh.bounds();
    const Vec3f c = b.center(), e = b.extent() * 0.75f + Vec3f(0.1f);
    auto point = [&] {
        return c + e * Vec3f(2 * u01(rng) - 1, 2 * u01(rng) - 1, 2 * u01(rng) - 1);
    };
    auto direction = [&] {
        const float z = 2 * u01(rng) - 1, phi = 2 * kPi * u01(rng), r = std::sqrt(1 - z * z);
        return Vec3f(r * std::cos(phi), r * std::sin(phi), z);
    };
    auto on_triangle = [&] {
        const Vec3u& t = mesh.triangles[rng() % mesh.triangles.size()];
        float a = u01(rng), bb = u01(rng);
        if (a + bb > 1) a = 1 - a, bb = 1 - bb;
        return mesh.positions[t.x] + a * (mesh.positions[t.y] - mesh.positions[t.x]) +
               bb * (mesh.positions[t.z] - mesh.positions[t.x]);
    };
    std::vector<const KdNode*> inner;
    for (const KdNode& nd : tree.nodes) {
        if (!nd.is_leaf()) inner.push_back(&nd);
    }
    std::vector<Ray> rays(n);
    for (size_t i = 0; i < n; ++i) {
        Ray& r = rays[i];
        r.origin = point();
        const int kind = int(i % 5);
        if (kind == 0) {
            r.dir = direction();
        } else if (kind == 1 || (kind == 3 && inner.empty())) {
            r.dir = (on_triangle() - r.origin) * (0.5f + u01(rng));
        } else if (kind == 2) {
            const Vec3f& v = mesh.positions[mesh.triangles[rng() % mesh.triangles.size()].x];
            const int axis = int(rng() % 3);
            for (int k = 0; k < 3; ++k) {
                if (k != axis && (rng() & 1)) r.origin[k] = v[k];
            }
            r.dir = Vec3f(0.0f);
            r.dir[axis] = (rng() & 1) ? 1.0f : -1.0f;
        } else if (kind == 3) {
            // In a split plane: the case where both children must be visited.
            const KdNode& nd = *inner[rng() % inner.size()];
            r.origin[nd.axis()] = nd.split;
            Vec3f target = on_triangle();
            target[nd.axis()] = nd.split;
            r.dir = target - r.origin;
            if (r.dir == Vec3f(0.0f)) r.dir[(nd.axis() + 1) % 3] = 1.0f;
        } else {
            r.dir = (on_triangle() - r.origin) * (0.5f + u01(rng));
            r.tmin = 0.3f * u01(rng);
            r.tmax = r.tmin + 1.2f * u01(rng);
        }
    }
    return rays;
}

/// Closest hits of the tree equal the oracle's: same t within 1e-6 relative, and the same
/// triangle unless the tree's triangle is hit at exactly the same t (a tie).
size_t compare_hits(const KdTree& tree, const std::vector<Ray>& rays,
                    const std::function<Hit(const Ray&)>& oracle, const std::string& what) {
    const TriangleMesh& mesh = tree.mesh();
    size_t failures = 0, hits = 0;
    for (size_t i = 0; i < rays.size() && failures < 5; ++i) {
        const Ray& r = rays[i];
        const Hit ref = oracle(r);
        Hit hit;
        const bool got = tree.intersect(r, hit);
        hits += ref.valid();
        const bool ok = got == hit.valid() && test::same_closest_hit(mesh, r, hit, ref);
        if (!ok) {
            ++failures;
            ADD_FAILURE() << what << " ray " << i << ": tree "
                          << (got ? std::to_string(hit.t) + " prim " + std::to_string(hit.prim)
                                  : "miss")
                          << ", oracle "
                          << (ref.valid()
                                  ? std::to_string(ref.t) + " prim " + std::to_string(ref.prim)
                                  : "miss");
        }
    }
    EXPECT_GT(hits, rays.size() / 5) << what << ": the comparison is not vacuous";
    return failures;
}

std::shared_ptr<const KdTree> make_tree(const TriangleMesh& mesh, const KdTreeParams& params,
                                        const SahTuning& tuning, KdBuildOutput* copy = nullptr) {
    auto shared = std::make_shared<const TriangleMesh>(mesh);
    KdBuildOutput out = build_sah_tree(mesh, params, tuning);
    if (copy) *copy = out;
    return std::make_shared<const KdTree>(shared, out.bounds, std::move(out.nodes),
                                          std::move(out.indices), params, std::move(out.stats));
}

TEST(SahBuilderQueries, ClosestHitsMatchBruteForce) {
    TriangleMesh with_degenerates = random_soup(250, 31, 0.2f);
    with_degenerates.positions.push_back(Vec3f(0.1f));
    const auto p = uint32_t(with_degenerates.positions.size() - 1);
    with_degenerates.triangles.emplace_back(p, p, p);
    with_degenerates.positions[with_degenerates.triangles[5].x] =
        Vec3f(std::numeric_limits<float>::quiet_NaN());
    // The overlapping soup's tree is cut short by the reference budget.
    const TriangleMesh meshes[] = {
        random_soup(300, 30, 0.3f), uv_sphere(10, 20),       cube_lattice(3), flat_grid(12),
        with_degenerates,           overlapping_soup(400, 6)};
    size_t rays_checked = 0;
    for (size_t mi = 0; mi < std::size(meshes); ++mi) {
        const TriangleMesh& mesh = meshes[mi];
        for (const SahTuning& tuning : {SahTuning{}, binned_tuning()}) {
            KdBuildOutput copy;
            const auto tree = make_tree(mesh, KdTreeParams{}, tuning, &copy);
            const std::vector<Ray> rays = make_rays(mesh, copy, 10000, uint32_t(40 + mi));
            rays_checked += rays.size();
            compare_hits(
                *tree, rays, [&](const Ray& r) { return test::brute_force_hit(mesh, r); },
                "mesh " + std::to_string(mi));
        }
    }
    EXPECT_GE(rays_checked, 100000u);
}

TEST(SahBuilderQueries, DragonRes2MatchesBruteForce) {
    const auto mesh = test::load_dragon_res2();
    if (!mesh) GTEST_SKIP() << test::kDragonRes2Missing;
    KdBuildOutput copy;
    const auto sah = make_tree(*mesh, KdTreeParams{}, SahTuning{}, &copy);
    check_layout(*mesh, copy);
    EXPECT_LT(copy.stats.refs_per_triangle, 3.0);
    const std::vector<Ray> rays = make_rays(*mesh, copy, 100, 77);
    compare_hits(
        *sah, rays, [&](const Ray& r) { return test::brute_force_hit(*mesh, r); },
        "dragon res2 vs brute force");
}

TEST(ClipTriangleToBox, ContainsTheExactClipAndRejectsDisjoint) {
    Bounds3f box;
    box.lower = Vec3f(0.0f);
    box.upper = Vec3f(1.0f);
    Bounds3f c;
    // Sticks out of the box through x = 1: the clipped part spans x in [0.5, 1], y in [0, 0.5].
    ASSERT_TRUE(clip_triangle_to_box(Vec3f(0.5f, 0.0f, 0.5f), Vec3f(1.5f, 0.0f, 0.5f),
                                     Vec3f(0.5f, 1.0f, 0.5f), box, c));
    EXPECT_LE(c.lower.x, 0.5f);
    EXPECT_EQ(c.upper.x, 1.0f);
    EXPECT_LE(c.lower.y, 0.0f);
    EXPECT_GE(c.upper.y, 1.0f - 1e-6f);
    EXPECT_EQ(c.lower.z, 0.5f);
    EXPECT_EQ(c.upper.z, 0.5f);
    // A corner cut: the part inside x <= 1 has y <= 0.5 only.
    ASSERT_TRUE(clip_triangle_to_box(Vec3f(0.5f, 0.0f, 0.5f), Vec3f(1.5f, 0.0f, 0.5f),
                                     Vec3f(1.5f, 1.0f, 0.5f), box, c));
    EXPECT_GE(c.upper.y, 0.5f);
    EXPECT_LT(c.upper.y, 0.5f + 1e-6f);
    // Touching the box in one vertex still meets it.
    ASSERT_TRUE(clip_triangle_to_box(Vec3f(1.0f, 1.0f, 1.0f), Vec3f(2.0f, 1.0f, 1.0f),
                                     Vec3f(2.0f, 2.0f, 1.0f), box, c));
    EXPECT_EQ(c.lower, Vec3f(1.0f));
    EXPECT_EQ(c.upper, Vec3f(1.0f));
    EXPECT_FALSE(clip_triangle_to_box(Vec3f(1.5f, 0.0f, 0.0f), Vec3f(2.0f, 0.0f, 0.0f),
                                      Vec3f(1.5f, 1.0f, 0.0f), box, c));
    // Cuts the box corner region but misses the box itself.
    EXPECT_FALSE(clip_triangle_to_box(Vec3f(1.2f, 0.9f, 0.5f), Vec3f(0.9f, 1.2f, 0.5f),
                                      Vec3f(1.2f, 1.2f, 0.5f), box, c));
}

TEST(ClipTriangleToBox, RandomClipsAreConservative) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(-2.0f, 2.0f);
    Bounds3f box;
    box.lower = Vec3f(-0.7f, -0.3f, -1.1f);
    box.upper = Vec3f(0.9f, 0.4f, 0.2f);
    for (int i = 0; i < 2000; ++i) {
        const Vec3f a(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng)), c(u(rng), u(rng), u(rng));
        Bounds3f clipped;
        const bool meets = clip_triangle_to_box(a, b, c, box, clipped);
        // Sample points of the triangle: every one inside the box must be inside `clipped`.
        for (int s = 0; s <= 20; ++s) {
            for (int t = 0; s + t <= 20; ++t) {
                const double bs = s / 20.0, bt = t / 20.0;
                const Vec3d p = Vec3d(a) + bs * (Vec3d(b) - Vec3d(a)) + bt * (Vec3d(c) - Vec3d(a));
                bool in_box = true;
                for (int k = 0; k < 3; ++k) {
                    in_box = in_box && p[k] >= box.lower[k] && p[k] <= box.upper[k];
                }
                if (!in_box) continue;
                ASSERT_TRUE(meets) << "triangle " << i;
                for (int k = 0; k < 3; ++k) {
                    ASSERT_GE(p[k], double(clipped.lower[k])) << "triangle " << i;
                    ASSERT_LE(p[k], double(clipped.upper[k])) << "triangle " << i;
                }
            }
        }
    }
}

}  // namespace
}  // namespace kdt
