// Mesh utilities: the spatial triangle order used by render snapshots (a permutation that
// keeps every triangle and its attributes, deterministic, spatially coherent).
#include <algorithm>
#include <array>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <glm/gtc/matrix_transform.hpp>

#include "renderer/core/error.h"
#include "renderer/geometry/mesh.h"

namespace kdt {
namespace {

// Random soup with shared vertices, normals and colours, and one unused vertex.
TriangleMesh make_mesh(size_t nv, size_t nt, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-5.0f, 5.0f);
    TriangleMesh m;
    for (size_t i = 0; i < nv; ++i) {
        m.positions.emplace_back(u(rng), u(rng), u(rng));
        m.normals.emplace_back(float(i), 0.0f, 1.0f);
        m.colors.emplace_back(0.0f, float(i), 0.5f);
    }
    std::uniform_int_distribution<uint32_t> vi(0, uint32_t(nv - 2));  // nv - 1 unused
    for (size_t i = 0; i < nt; ++i) m.triangles.emplace_back(vi(rng), vi(rng), vi(rng));
    return m;
}

using Corners = std::array<float, 9>;
Corners corners(const TriangleMesh& m, size_t i) {
    const Vec3u t = m.triangles[i];
    Corners c;
    for (int k = 0; k < 3; ++k)
        for (int j = 0; j < 3; ++j) c[size_t(3 * k + j)] = m.positions[t[k]][j];
    return c;
}

TEST(SpatialOrder, IsAPermutationKeepingEveryTriangleAndAttribute) {
    const TriangleMesh m = make_mesh(2000, 5000, 1);
    const MeshOrder order = spatial_order(m);
    ASSERT_EQ(order.triangles.size(), m.triangles.size());
    ASSERT_EQ(order.vertices.size(), m.positions.size());
    std::vector<uint32_t> t = order.triangles, v = order.vertices;
    std::sort(t.begin(), t.end());
    std::sort(v.begin(), v.end());
    for (size_t i = 0; i < t.size(); ++i) ASSERT_EQ(t[i], i);
    for (size_t i = 0; i < v.size(); ++i) ASSERT_EQ(v[i], i);

    TriangleMesh r = m;
    apply_order(r, order);
    for (size_t i = 0; i < r.triangles.size(); ++i) {
        // New triangle i is old triangle order.triangles[i], corner by corner.
        ASSERT_EQ(corners(r, i), corners(m, order.triangles[i])) << i;
        for (int k = 0; k < 3; ++k) {
            const uint32_t nv = r.triangles[i][k], ov = m.triangles[order.triangles[i]][k];
            ASSERT_EQ(r.normals[nv], m.normals[ov]);
            ASSERT_EQ(r.colors[nv], m.colors[ov]);
        }
    }
    // Vertices in order of first use; the unused one last.
    EXPECT_EQ(order.vertices.back(), uint32_t(m.positions.size() - 1));
    EXPECT_EQ(r.triangles[0].x, 0u);
    // Deterministic.
    const MeshOrder again = spatial_order(m);
    EXPECT_EQ(again.triangles, order.triangles);
    EXPECT_EQ(again.vertices, order.vertices);
    EXPECT_EQ(permuted(std::vector<int>{10, 20, 30}, {2, 0, 1}), (std::vector<int>{30, 10, 20}));
}

TEST(SpatialOrder, NeighboursInMemoryAreNeighboursInSpace) {
    TriangleMesh m = make_mesh(30000, 30000, 2);
    // Small triangles: each near its first vertex.
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(-0.01f, 0.01f);
    const std::vector<Vec3f> centres = m.positions;
    m.positions.resize(3 * m.triangles.size());
    for (size_t i = 0; i < m.triangles.size(); ++i) {
        const Vec3f c = centres[i];
        m.positions[3 * i] = c;
        m.positions[3 * i + 1] = c + Vec3f(u(rng), u(rng), u(rng));
        m.positions[3 * i + 2] = c + Vec3f(u(rng), u(rng), u(rng));
        m.triangles[i] = Vec3u(uint32_t(3 * i), uint32_t(3 * i + 1), uint32_t(3 * i + 2));
    }
    m.normals.clear();
    m.colors.clear();
    auto mean_step = [](const TriangleMesh& mesh) {
        double sum = 0.0;
        for (size_t i = 1; i < mesh.triangles.size(); ++i)
            sum += glm::length(mesh.positions[mesh.triangles[i].x] -
                               mesh.positions[mesh.triangles[i - 1].x]);
        return sum / double(mesh.triangles.size() - 1);
    };
    const double before = mean_step(m);
    apply_order(m, spatial_order(m));
    const double after = mean_step(m);
    EXPECT_LT(after, 0.1 * before) << "before " << before << " after " << after;
}

TEST(SpatialOrder, EmptyDegenerateAndNonFiniteMeshes) {
    TriangleMesh empty;
    const MeshOrder e = spatial_order(empty);
    EXPECT_TRUE(e.triangles.empty());
    EXPECT_TRUE(e.vertices.empty());
    apply_order(empty, e);

    TriangleMesh flat;  // all vertices at one point, plus a NaN and an infinite vertex
    flat.positions = {Vec3f(1.0f), Vec3f(1.0f), Vec3f(1.0f), Vec3f(std::nanf("")),
                      Vec3f(INFINITY, 0.0f, 0.0f)};
    flat.triangles = {{0, 1, 2}, {2, 3, 4}, {4, 1, 0}};
    const MeshOrder f = spatial_order(flat);
    ASSERT_EQ(f.triangles.size(), 3u);
    ASSERT_EQ(f.vertices.size(), 5u);
    apply_order(flat, f);
    EXPECT_EQ(flat.triangles.size(), 3u);
}

// Normals follow the inverse transpose at any scale: a uniform scale of 1e-20 (whose float
// inverse divides by a determinant that underflows) leaves them as they are, a mirror flips
// them with the surface, and a shear matches the float inverse transpose.
TEST(TransformMesh, NormalsAtAnyScaleAndUnderMirrors) {
    TriangleMesh base;
    base.positions = {Vec3f(0, 0, 0), Vec3f(1, 0, 0), Vec3f(0, 1, 0)};
    base.triangles = {Vec3u(0, 1, 2)};
    base.normals = {glm::normalize(Vec3f(1, 2, 3)), Vec3f(0, 0, 1), Vec3f(0, -1, 0)};
    auto transformed = [&](const Mat4f& m) {
        TriangleMesh t = base;
        transform_mesh(t, m);
        return t;
    };
    const TriangleMesh tiny = transformed(glm::scale(Mat4f(1.0f), Vec3f(1e-20f)));
    for (size_t i = 0; i < base.normals.size(); ++i) {
        EXPECT_NEAR(glm::length(tiny.normals[i] - base.normals[i]), 0.0f, 1e-6f) << i;
        EXPECT_EQ(tiny.positions[i], base.positions[i] * 1e-20f) << i;
    }
    const TriangleMesh mirror = transformed(glm::scale(Mat4f(1.0f), Vec3f(-1.0f, 1.0f, 1.0f)));
    EXPECT_NEAR(glm::length(mirror.normals[0] - glm::normalize(Vec3f(-1, 2, 3))), 0.0f, 1e-6f);
    Mat4f shear(1.0f);
    shear[1][0] = 0.5f;   // x += 0.5 y
    shear[2][1] = -2.0f;  // y -= 2 z
    const TriangleMesh sheared = transformed(glm::scale(shear, Vec3f(-3.0f, 0.5f, 2.0f)));
    const Mat3f expected =
        glm::transpose(glm::inverse(Mat3f(glm::scale(shear, Vec3f(-3.0f, 0.5f, 2.0f)))));
    for (size_t i = 0; i < base.normals.size(); ++i) {
        const Vec3f e = glm::normalize(expected * base.normals[i]);
        EXPECT_NEAR(glm::length(sheared.normals[i] - e), 0.0f, 1e-5f) << i;
    }
}

// Under a transform with a negative determinant (a mirror, alone or with a rotation and a
// non-uniform scale) a closed mesh stays outward-facing: every triangle's geometric normal,
// file normal and computed vertex normal points away from the centroid, as without one.
// The mesh is irregular, so that no mirror maps it onto itself.
TEST(TransformMesh, MirrorsReverseTheWindingSoClosedMeshesStayOutward) {
    TriangleMesh base;  // a tetrahedron, counter-clockwise seen from outside
    base.positions = {Vec3f(0.1f, -0.2f, 0.3f), Vec3f(2.0f, 0.1f, 0.0f), Vec3f(0.2f, 3.0f, 0.4f),
                      Vec3f(0.3f, 0.5f, 1.5f)};
    base.triangles = {Vec3u(0, 2, 1), Vec3u(0, 1, 3), Vec3u(0, 3, 2), Vec3u(1, 2, 3)};
    const Vec3f centre =
        0.25f * (base.positions[0] + base.positions[1] + base.positions[2] + base.positions[3]);
    for (const Vec3f& p : base.positions) base.normals.push_back(glm::normalize(p - centre));
    const Mat4f rotation = glm::rotate(Mat4f(1.0f), 0.9f, glm::normalize(Vec3f(1, 2, 3)));
    const struct {
        const char* name;
        Mat4f m;
    } cases[] = {
        {"identity", Mat4f(1.0f)},
        {"scale (2, 3, 4) rotated", glm::scale(rotation, Vec3f(2, 3, 4))},
        {"scale (-1, 1, 1)", glm::scale(Mat4f(1.0f), Vec3f(-1, 1, 1))},
        {"scale (-2, 3, 4)", glm::scale(Mat4f(1.0f), Vec3f(-2, 3, 4))},
        {"scale (-1, -1, -1)", glm::scale(Mat4f(1.0f), Vec3f(-1, -1, -1))},
        {"rotation times a mirror, translated",
         glm::translate(Mat4f(1.0f), Vec3f(5, -1, 2)) * glm::scale(rotation, Vec3f(1, -1, 1))},
    };
    for (const auto& c : cases) {
        TriangleMesh t = base;
        transform_mesh(t, c.m);
        const Vec3f world_centre = Vec3f(c.m * Vec4f(centre, 1.0f));
        for (const Vec3u& f : t.triangles) {
            const Vec3f a = t.positions[f.x], b = t.positions[f.y], d = t.positions[f.z];
            const Vec3f outward = (a + b + d) / 3.0f - world_centre;
            EXPECT_GT(glm::dot(triangle_normal(a, b, d), outward), 0.0f) << c.name;
        }
        const std::vector<Vec3f> computed = compute_vertex_normals(t);
        for (size_t v = 0; v < t.positions.size(); ++v) {
            const Vec3f outward = t.positions[v] - world_centre;
            EXPECT_GT(glm::dot(t.normals[v], outward), 0.0f) << c.name << ", vertex " << v;
            EXPECT_GT(glm::dot(computed[v], outward), 0.0f) << c.name << ", vertex " << v;
        }
    }
}

// A subdivision the kd-tree could not take is refused before anything is allocated (2^32
// triangles would also overflow the 32-bit vertex indices).
TEST(SubdivideMesh, CountsAndRefusesResultsBeyondTheTreeLimit) {
    EXPECT_EQ(subdivided_triangle_count(12, 0), 12u);
    EXPECT_EQ(subdivided_triangle_count(12, 3), 12u * 64u);
    EXPECT_EQ(subdivided_triangle_count(0, 40), 0u);
    EXPECT_EQ(subdivided_triangle_count(3, 40), uint64_t(1) << 63);  // saturates
    TriangleMesh one;
    one.positions = {Vec3f(0.0f), Vec3f(1.0f, 0.0f, 0.0f), Vec3f(0.0f, 1.0f, 0.0f)};
    one.triangles = {Vec3u(0, 1, 2)};
    EXPECT_EQ(subdivide_mesh(one, 2).triangle_count(), 16u);
    try {
        subdivide_mesh(one, 15);  // 2^30 triangles
        ADD_FAILURE() << "no error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("1073741824 triangles"), std::string::npos)
            << e.what();
    }
}

}  // namespace
}  // namespace kdt
