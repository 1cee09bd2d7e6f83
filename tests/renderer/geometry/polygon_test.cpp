// Polygon triangulation: convex polygons keep their fan; concave ones (L, dart, star,
// random star-shaped) are covered exactly, in 2D and tilted into 3D, in both windings;
// degenerate and hostile input ends with n - 2 triangles of valid corners.
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <glm/gtc/matrix_transform.hpp>

#include "renderer/geometry/polygon.h"

namespace kdt {
namespace {

using Poly2 = std::vector<glm::dvec2>;

double signed_area(const Poly2& p) {
    double a = 0.0;
    for (size_t i = 0; i < p.size(); ++i) {
        const glm::dvec2 &u = p[i], &v = p[(i + 1) % p.size()];
        a += u.x * v.y - v.x * u.y;
    }
    return 0.5 * a;
}

double tri_area(const glm::dvec2& a, const glm::dvec2& b, const glm::dvec2& c) {
    return 0.5 * ((b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x));
}

// Even-odd rule; the points tested are centroids of triangles with area, never on an edge
// for the polygons below.
bool inside(const Poly2& p, const glm::dvec2& q) {
    bool in = false;
    for (size_t i = 0, j = p.size() - 1; i < p.size(); j = i++) {
        if ((p[i].y > q.y) != (p[j].y > q.y) &&
            q.x < (p[j].x - p[i].x) * (q.y - p[i].y) / (p[j].y - p[i].y) + p[i].x)
            in = !in;
    }
    return in;
}

// The polygon in the plane z = 0, or tilted: rotated about a skew axis and moved far from
// the origin (the frame a scanned mesh's polygon may sit in).
std::vector<Vec3f> embed(const Poly2& p, bool tilted) {
    const glm::dmat4 m =
        glm::rotate(glm::translate(glm::dmat4(1.0), glm::dvec3(100.0, -50.0, 20.0)), 1.1,
                    glm::normalize(glm::dvec3(1.0, 2.0, 0.5)));
    std::vector<Vec3f> out;
    for (const glm::dvec2& q : p) {
        const glm::dvec3 v = tilted ? glm::dvec3(m * glm::dvec4(q, 0.0, 1.0)) : glm::dvec3(q, 0.0);
        out.emplace_back(v);
    }
    return out;
}

std::vector<Vec3u> triangulate(const std::vector<Vec3f>& c, bool* fanned = nullptr) {
    std::vector<Vec3u> t(c.size() - 2, Vec3u(~0u));
    PolygonScratch s;
    const bool f = triangulate_polygon(c, t.data(), s);
    if (fanned) *fanned = f;
    return t;
}

std::vector<Vec3u> fan_of(size_t n) {
    std::vector<Vec3u> t;
    for (uint32_t k = 1; k + 1 < n; ++k) t.emplace_back(0, k, k + 1);
    return t;
}

// The triangles cover p exactly: each has the polygon's winding (or no area), its centroid
// inside p, and their areas add up to p's.
void expect_covers(const Poly2& p, const std::vector<Vec3u>& tris) {
    ASSERT_EQ(tris.size(), p.size() - 2);
    const double area = signed_area(p);
    const double sign = area > 0 ? 1.0 : -1.0;
    double sum = 0.0;
    for (const Vec3u& t : tris) {
        ASSERT_LT(std::max({t.x, t.y, t.z}), p.size());
        const double a = tri_area(p[t.x], p[t.y], p[t.z]);
        EXPECT_GE(a * sign, -1e-12 * std::fabs(area)) << "triangle against the winding";
        sum += a;
        if (std::fabs(a) > 1e-9 * std::fabs(area)) {
            EXPECT_TRUE(inside(p, (p[t.x] + p[t.y] + p[t.z]) / 3.0))
                << "triangle " << t.x << " " << t.y << " " << t.z << " outside the polygon";
        }
    }
    EXPECT_NEAR(sum, area, 1e-9 * std::fabs(area));
}

// Every rotation of the corner list, both windings, flat and tilted.
void expect_covers_all_ways(const Poly2& p) {
    for (int reversed = 0; reversed < 2; ++reversed) {
        Poly2 q = p;
        if (reversed) std::reverse(q.begin(), q.end());
        for (size_t r = 0; r < q.size(); ++r) {
            for (int tilted = 0; tilted < 2; ++tilted) {
                SCOPED_TRACE(::testing::Message() << "reversed " << reversed << " rotation " << r
                                                  << " tilted " << tilted);
                expect_covers(q, triangulate(embed(q, tilted != 0)));
            }
            std::rotate(q.begin(), q.begin() + 1, q.end());
        }
    }
}

// Whether the fan covers p (the old behaviour): false for some rotation of each concave case.
bool fan_covers_every_rotation(Poly2 p) {
    for (size_t r = 0; r < p.size(); ++r) {
        for (uint32_t k = 1; k + 1 < p.size(); ++k)
            if (tri_area(p[0], p[k], p[k + 1]) * signed_area(p) < 0) return false;
        std::rotate(p.begin(), p.begin() + 1, p.end());
    }
    return true;
}

const Poly2 kL = {{2, 1}, {1, 1}, {1, 2}, {0, 2}, {0, 0}, {2, 0}};
const Poly2 kDart = {{0, 0}, {2, 1}, {4, 0}, {2, 3}};

Poly2 star(size_t points, double inner) {
    Poly2 p;
    for (size_t k = 0; k < 2 * points; ++k) {
        const double a = double(k) * M_PI / double(points);
        const double r = k % 2 ? inner : 1.0;
        p.emplace_back(r * std::cos(a), r * std::sin(a));
    }
    return p;
}

TEST(Polygon, LShapeIsCoveredExactly) {
    ASSERT_FALSE(fan_covers_every_rotation(kL));
    expect_covers_all_ways(kL);
}

TEST(Polygon, DartQuadIsCoveredExactly) {
    ASSERT_FALSE(fan_covers_every_rotation(kDart));
    expect_covers_all_ways(kDart);
    // The ear at corner 0, then what is left fanned from its lowest corner.
    bool fanned = true;
    EXPECT_EQ(triangulate(embed(kDart, false), &fanned),
              (std::vector<Vec3u>{{3, 0, 1}, {1, 2, 3}}));
    EXPECT_FALSE(fanned);
}

TEST(Polygon, StarIsCoveredExactly) {
    ASSERT_FALSE(fan_covers_every_rotation(star(5, 0.4)));
    expect_covers_all_ways(star(5, 0.4));
    expect_covers_all_ways(star(12, 0.7));
}

TEST(Polygon, RandomStarShapedPolygonsAreCoveredExactly) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> radius(0.2, 1.0), jitter(0.0, 1.0);
    for (int trial = 0; trial < 200; ++trial) {
        const size_t n = 4 + size_t(trial % 40);
        Poly2 p;
        for (size_t k = 0; k < n; ++k) {
            const double a = (double(k) + 0.8 * jitter(rng)) * 2.0 * M_PI / double(n);
            const double r = radius(rng);
            p.emplace_back(r * std::cos(a), r * std::sin(a));
        }
        SCOPED_TRACE(trial);
        expect_covers(p, triangulate(embed(p, trial % 2 == 1)));
    }
}

TEST(Polygon, ConvexPolygonsKeepTheirFan) {
    std::vector<Poly2> convex = {
        {{0, 0}, {1, 0}, {1, 1}, {0, 1}},          // square
        {{0, 0}, {1, 0}, {2, 0}, {2, 1}, {0, 1}},  // a corner on an edge
        {{0, 0}, {1, 0}, {1, 0}, {1, 1}, {0, 1}},  // a repeated corner
        {{0, 0}, {3, 0}, {3, 1e-7}, {0, 1}},       // nearly a triangle
    };
    Poly2 heptagon;
    for (int k = 0; k < 7; ++k) heptagon.emplace_back(std::cos(k * 0.9), std::sin(k * 0.9));
    convex.push_back(heptagon);
    for (Poly2 p : convex) {
        for (int reversed = 0; reversed < 2; ++reversed) {
            if (reversed) std::reverse(p.begin(), p.end());
            for (int tilted = 0; tilted < 2; ++tilted) {
                bool fanned = false;
                EXPECT_EQ(triangulate(embed(p, tilted != 0), &fanned), fan_of(p.size()));
                EXPECT_TRUE(fanned);
            }
        }
    }
    // A scanned mesh's quads are a little off their plane.
    bool fanned = false;
    EXPECT_EQ(triangulate({{0, 0, 0}, {1, 0, 0.05f}, {1, 1, 0}, {0, 1, 0.05f}}, &fanned),
              fan_of(4));
    EXPECT_TRUE(fanned);
}

TEST(Polygon, CollinearCornersInAConcavePolygon) {
    const Poly2 p = {{2, 1},   {1.5, 1}, {1, 1}, {1, 2}, {0, 2},  {0, 1},
                     {0, 0.5}, {0, 0},   {1, 0}, {2, 0}, {2, 0.5}};
    ASSERT_FALSE(fan_covers_every_rotation(p));
    expect_covers_all_ways(p);
}

TEST(Polygon, RepeatedCornersInAConcavePolygon) {
    expect_covers_all_ways({{0, 0}, {2, 1}, {2, 1}, {4, 0}, {2, 3}});
    expect_covers_all_ways({{2, 1}, {1, 1}, {1, 2}, {1, 2}, {1, 2}, {0, 2}, {0, 0}, {2, 0}});
}

TEST(Polygon, NonPlanarConcavePolygonIsClippedInItsNewellPlane) {
    std::vector<Vec3f> c = embed(kL, false);
    for (size_t k = 0; k < c.size(); ++k) c[k].z = 0.05f * float(k % 2);
    expect_covers(kL, triangulate(c));
}

// Degenerate and hostile input: n - 2 triangles of valid corners, quickly.
void expect_sane(const std::vector<Vec3f>& c) {
    const std::vector<Vec3u> t = triangulate(c);
    ASSERT_EQ(t.size(), c.size() - 2);
    for (const Vec3u& v : t) {
        EXPECT_LT(std::max({v.x, v.y, v.z}), c.size());
        EXPECT_TRUE(v.x != v.y && v.y != v.z && v.x != v.z);
    }
}

TEST(Polygon, DegenerateInputEndsWithValidTriangles) {
    expect_sane({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}});  // on a line: no area
    expect_sane({{1, 1, 1}, {1, 1, 1}, {1, 1, 1}, {1, 1, 1}});  // one point
    expect_sane({{0, 0, 0}, {1, 1, 0}, {1, 0, 0}, {0, 1, 0}});  // bow tie: no net area
    expect_sane({{0, 0, 0}, {2, 2, 0}, {2, 0, 0}, {0, 1, 0}});  // bow tie with net area
    expect_sane(embed(Poly2{{1, 0}, {-0.81, 0.59}, {0.31, -0.95}, {0.31, 0.95}, {-0.81, -0.59}},
                      false));  // pentagram: turns one way, goes around twice
    const float nan = std::nanf("");
    const float inf = std::numeric_limits<float>::infinity();
    expect_sane({{0, 0, 0}, {2, 1, 0}, {nan, 0, 0}, {2, 3, 0}});
    expect_sane({{0, 0, 0}, {2, 1, 0}, {inf, 0, 0}, {2, 3, 0}});
    expect_sane({{0, 0, 0}, {3e38f, 1, 0}, {-3e38f, 3e38f, 0}, {2, -3e38f, 0}, {1, 1, 0}});
    // Corners of a twisted band far off any plane.
    std::vector<Vec3f> twisted;
    for (int k = 0; k < 12; ++k)
        twisted.emplace_back(std::cos(k * 1.3f), std::sin(k * 2.1f), float(k % 3));
    expect_sane(twisted);
}

TEST(Polygon, HugeSelfIntersectingPolygonStopsWithinItsBudget) {
    // Random corners: self-intersecting everywhere, few ears; the budget fans the rest.
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    std::vector<Vec3f> c;
    for (int k = 0; k < 200000; ++k) c.emplace_back(u(rng), u(rng), 0.0f);
    expect_sane(c);
}

}  // namespace
}  // namespace kdt
