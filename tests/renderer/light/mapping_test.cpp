// Tests of renderer/light/mapping.h: direction <-> image coordinates of both mappings,
// their Jacobians, the rotation, the disk coverage and the lat-long <-> angular resampling.
#include "renderer/light/mapping.h"

#include <cmath>
#include <cstdint>

#include <gtest/gtest.h>

#include "tests/test_util.h"

#include "renderer/material/material.h"

#include "renderer/light/image_environment.h"

namespace kdt {
namespace {

using test::HashRng;

void expect_near_vec(const Vec3f& a, const Vec3f& b, float tol) {
    EXPECT_NEAR(a.x, b.x, tol);
    EXPECT_NEAR(a.y, b.y, tol);
    EXPECT_NEAR(a.z, b.z, tol);
}

TEST(Mapping, LatlongAnchorsFollowTheDocumentedConvention) {
    expect_near_vec(latlong_dir_from_uv({0.5f, 0.0f}), {0, 1, 0}, 1e-6f);   // top row: +y
    expect_near_vec(latlong_dir_from_uv({0.5f, 1.0f}), {0, -1, 0}, 1e-6f);  // bottom: -y
    expect_near_vec(latlong_dir_from_uv({0.0f, 0.5f}), {0, 0, -1}, 1e-6f);  // left edge: -z
    expect_near_vec(latlong_dir_from_uv({0.25f, 0.5f}), {1, 0, 0}, 1e-6f);
    expect_near_vec(latlong_dir_from_uv({0.5f, 0.5f}), {0, 0, 1}, 1e-6f);  // centre: +z
    expect_near_vec(latlong_dir_from_uv({0.75f, 0.5f}), {-1, 0, 0}, 1e-6f);
}

TEST(Mapping, AngularAnchorsFollowDebevec) {
    expect_near_vec(*angular_dir_from_uv({0.5f, 0.5f}), {0, 0, 1}, 1e-6f);   // centre: +z
    expect_near_vec(*angular_dir_from_uv({1.0f, 0.5f}), {0, 0, -1}, 1e-6f);  // rim: -z
    expect_near_vec(*angular_dir_from_uv({0.75f, 0.5f}), {1, 0, 0}, 1e-6f);  // right: +x
    expect_near_vec(*angular_dir_from_uv({0.5f, 0.25f}), {0, 1, 0}, 1e-6f);  // up: +y
    expect_near_vec(*angular_dir_from_uv({0.5f, 0.75f}), {0, -1, 0}, 1e-6f);
    EXPECT_FALSE(angular_dir_from_uv({0.02f, 0.02f}).has_value());  // outside the disk
    // Debevec's formula: r = acos(Dz) / (pi sqrt(Dx^2 + Dy^2)), (a, b) = (Dx r, Dy r).
    HashRng rng(7);
    for (int i = 0; i < 1000; ++i) {
        Vec3f d = sample_uniform_sphere(rng.next2());
        double r =
            std::acos(double(d.z)) / (M_PI * std::sqrt(double(d.x) * d.x + double(d.y) * d.y));
        Vec2f uv = angular_uv_from_dir(d);
        EXPECT_NEAR(2.0 * uv.x - 1.0, d.x * r, 2e-5);
        EXPECT_NEAR(1.0 - 2.0 * uv.y, d.y * r, 2e-5);
    }
}

TEST(Mapping, RoundTripsDirectionsAndCoordinates) {
    HashRng rng(1);
    float worst_ll = 0.0f, worst_ang = 0.0f;
    for (int i = 0; i < 200000; ++i) {
        Vec3f d = sample_uniform_sphere(rng.next2());
        Vec2f uv = latlong_uv_from_dir(d);
        ASSERT_GE(uv.x, 0.0f);
        ASSERT_LT(uv.x, 1.0f);
        ASSERT_GE(uv.y, 0.0f);
        ASSERT_LE(uv.y, 1.0f);
        worst_ll = std::max(worst_ll, glm::length(latlong_dir_from_uv(uv) - d));
        Vec2f st = angular_uv_from_dir(d);
        auto back = angular_dir_from_uv(st);
        ASSERT_TRUE(back.has_value()) << st.x << " " << st.y;
        worst_ang = std::max(worst_ang, glm::length(*back - d));
    }
    EXPECT_LT(worst_ll, 2e-6f);
    EXPECT_LT(worst_ang, 2e-5f);

    // Coordinates -> direction -> coordinates, away from where they are ill-defined
    // (the poles of the lat-long map, the rim of the angular map, which is all -z).
    for (int i = 0; i < 100000; ++i) {
        Vec2f uv(rng.next(), 0.001f + 0.998f * rng.next());
        Vec2f back = latlong_uv_from_dir(latlong_dir_from_uv(uv));
        float du = std::abs(back.x - uv.x);
        EXPECT_LT(std::min(du, 1.0f - du), 2e-5f);
        EXPECT_NEAR(back.y, uv.y, 2e-5f);
        Vec2f st = rng.next2();
        Vec2f ab(2 * st.x - 1, 1 - 2 * st.y);
        if (glm::length(ab) > 0.995f) continue;
        Vec2f st_back = angular_uv_from_dir(*angular_dir_from_uv(st));
        EXPECT_NEAR(st_back.x, st.x, 2e-5f);
        EXPECT_NEAR(st_back.y, st.y, 2e-5f);
    }
}

TEST(Mapping, RotationTurnsTheMapAboutPlusY) {
    // +90 degrees carries the map's +x (u = 1/4) to world -z (right-hand rule about +y).
    ImageRGB img(8, 4);
    ImageEnvironment env(img, EnvMapping::latlong, 90.0f, 1.0f);
    expect_near_vec(*env.dir_from_uv({0.25f, 0.5f}), {0, 0, -1}, 1e-6f);
    expect_near_vec(*env.dir_from_uv({0.5f, 0.5f}), {1, 0, 0}, 1e-6f);
    expect_near_vec(rotate_y(Vec3f(1, 0, 0), kPi / 2), {0, 0, -1}, 1e-6f);

    for (EnvMapping m : {EnvMapping::latlong, EnvMapping::angular}) {
        ImageEnvironment rotated(img, m, 37.0f, 1.0f);
        HashRng rng(3);
        for (int i = 0; i < 20000; ++i) {
            Vec3f d = sample_uniform_sphere(rng.next2());
            Vec2f uv = rotated.uv_from_dir(d);
            auto back = rotated.dir_from_uv(uv);
            ASSERT_TRUE(back.has_value());
            EXPECT_LT(glm::length(*back - d), 2e-5f);
            // The rotated map sees d where the unrotated one sees R_y(-37 deg) d.
            Vec2f expect = env_uv_from_dir(m, rotate_y(d, -37.0f * kPi / 180.0f));
            if (m == EnvMapping::latlong && std::abs(uv.x - expect.x) > 0.5f) continue;  // seam
            EXPECT_NEAR(uv.x, expect.x, 1e-4f);
            EXPECT_NEAR(uv.y, expect.y, 1e-4f);
        }
    }
}

/// Solid angle per unit (u, v) area by finite differences of the inverse mapping.
double numeric_jacobian(EnvMapping m, const Vec2f& uv) {
    const double h = 1e-3;
    auto dir = [&](double du, double dv) {
        return Vec3d(*env_dir_from_uv(m, Vec2f(float(uv.x + du), float(uv.y + dv))));
    };
    Vec3d ddu = (dir(h, 0) - dir(-h, 0)) / (2 * h);
    Vec3d ddv = (dir(0, h) - dir(0, -h)) / (2 * h);
    return glm::length(glm::cross(ddu, ddv));
}

TEST(Mapping, JacobiansMatchFiniteDifferences) {
    HashRng rng(11);
    for (int i = 0; i < 2000; ++i) {
        Vec2f uv(0.01f + 0.98f * rng.next(), 0.02f + 0.96f * rng.next());
        Vec3f d = latlong_dir_from_uv(uv);
        EXPECT_NEAR(latlong_jacobian(d) / numeric_jacobian(EnvMapping::latlong, uv), 1.0, 3e-3);
        Vec2f st = rng.next2();
        Vec2f ab(2 * st.x - 1, 1 - 2 * st.y);
        if (glm::length(ab) > 0.97f || glm::length(ab) < 0.01f) continue;
        Vec3f e = *angular_dir_from_uv(st);
        EXPECT_NEAR(angular_jacobian(e) / numeric_jacobian(EnvMapping::angular, st), 1.0, 3e-3);
    }
}

TEST(Mapping, JacobiansIntegrateToTheSphere) {
    // Midpoint rule on a fine grid: integral of the Jacobian over the image = 4 pi.
    const int n = 1024;
    double ll = 0.0, ang = 0.0;
    for (int y = 0; y < n; ++y) {
        for (int x = 0; x < n; ++x) {
            Vec2f uv((x + 0.5f) / n, (y + 0.5f) / n);
            ll += latlong_jacobian(latlong_dir_from_uv(uv));
            if (auto d = angular_dir_from_uv(uv)) ang += angular_jacobian(*d);
        }
    }
    EXPECT_NEAR(ll / (double(n) * n), 4 * M_PI, 4 * M_PI * 1e-4);
    EXPECT_NEAR(ang / (double(n) * n), 4 * M_PI, 4 * M_PI * 2e-3);
}

TEST(Mapping, DiskRectAreaIsExact) {
    EXPECT_NEAR(disk_rect_area(-1, 1, -1, 1), M_PI, 1e-12);
    EXPECT_NEAR(disk_rect_area(-2, 2, -3, 3), M_PI, 1e-12);
    EXPECT_NEAR(disk_rect_area(0, 1, 0, 1), M_PI / 4, 1e-12);
    EXPECT_NEAR(disk_rect_area(-0.3, 0.2, -0.1, 0.4), 0.5 * 0.5, 1e-12);
    EXPECT_EQ(disk_rect_area(0.9, 1.0, 0.9, 1.0), 0.0);
    EXPECT_NEAR(disk_rect_area(-1, 1, 0, 1), M_PI / 2, 1e-12);
    // A pixel grid tiles the disk.
    for (int n : {7, 64, 255}) {
        double sum = 0.0;
        for (int y = 0; y < n; ++y) {
            for (int x = 0; x < n; ++x) {
                sum += disk_rect_area(2.0 * x / n - 1, 2.0 * (x + 1) / n - 1, 2.0 * y / n - 1,
                                      2.0 * (y + 1) / n - 1);
            }
        }
        EXPECT_NEAR(sum, M_PI, 1e-10) << n;
    }
    // Random rectangles against a fine point count.
    HashRng rng(5);
    for (int i = 0; i < 20; ++i) {
        double x0 = 2.4 * rng.next() - 1.2, y0 = 2.4 * rng.next() - 1.2;
        double x1 = x0 + 0.5 * rng.next(), y1 = y0 + 0.5 * rng.next();
        const int g = 400;
        int inside = 0;
        for (int a = 0; a < g; ++a) {
            for (int b = 0; b < g; ++b) {
                double x = x0 + (x1 - x0) * (a + 0.5) / g, y = y0 + (y1 - y0) * (b + 0.5) / g;
                inside += x * x + y * y <= 1.0;
            }
        }
        double grid = (x1 - x0) * (y1 - y0) * inside / (double(g) * g);
        EXPECT_NEAR(disk_rect_area(x0, x1, y0, y1), grid, 2e-3 * (x1 - x0) * (y1 - y0) + 1e-9);
    }
}

// The formulas docs/conventions.md gives for other renderers, checked against ours.
TEST(Mapping, OtherRendererConventionsAsDocumented) {
    HashRng rng(9);
    for (int i = 0; i < 1000; ++i) {
        Vec2f uv(rng.next(), 0.01f + 0.98f * rng.next());
        float phi = 2 * kPi * uv.x, theta = kPi * uv.y;
        Vec3f ours = latlong_dir_from_uv(uv);
        // Mitsuba 3 envmap: sample_direction gives (sin phi sin theta, cos theta, -cos phi sin
        // theta).
        expect_near_vec(
            ours,
            {std::sin(phi) * std::sin(theta), std::cos(theta), -std::cos(phi) * std::sin(theta)},
            1e-5f);
        // pbrt-v3 infinite light (z up): d_p = (sin theta cos phi, sin theta sin phi, cos theta);
        // ours = (d_p.y, d_p.z, -d_p.x).
        Vec3f dp(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
        expect_near_vec(ours, {dp.y, dp.z, -dp.x}, 1e-5f);
        // Blender/Cycles equirectangular (z up, u from the left, v from the top):
        // phi_b = pi - 2 pi u, d_b = (sin theta cos phi_b, sin theta sin phi_b, cos theta);
        // Blender (x, y, z) is our (x, z, -y) (the glTF/OBJ "Y up" export). It equals our
        // map rotated by +90 degrees about +y.
        float phib = kPi - 2 * kPi * uv.x;
        Vec3f db(std::sin(theta) * std::cos(phib), std::sin(theta) * std::sin(phib),
                 std::cos(theta));
        expect_near_vec(rotate_y(ours, kPi / 2), {db.x, db.z, -db.y}, 1e-5f);
    }
}

/// A smooth synthetic sky: bright towards +y and +x, never zero.
ImageRGB smooth_latlong(int w, int h) {
    ImageRGB img(w, h);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            Vec3f d = latlong_dir_from_uv({(x + 0.5f) / w, (y + 0.5f) / h});
            img.set(x, y, Vec3f(1.0f + d.y, 1.5f + d.x, 1.2f + 0.5f * d.z * d.y));
        }
    }
    return img;
}

TEST(Mapping, AngularConversionRoundTrips) {
    ImageRGB ll = smooth_latlong(128, 64);
    ImageRGB ang = latlong_to_angular(ll, 256);
    ASSERT_EQ(ang.width, 256);
    ASSERT_EQ(ang.height, 256);
    EXPECT_EQ(ang.at(0, 0), Vec3f(0.0f));  // corner: outside the disk
    ImageRGB back = angular_to_latlong(ang, 128);
    ASSERT_EQ(back.width, 128);
    ASSERT_EQ(back.height, 64);
    double err = 0.0, ref = 0.0;
    for (size_t i = 0; i < ll.rgb.size(); ++i) {
        err += std::abs(double(back.rgb[i]) - ll.rgb[i]);
        ref += ll.rgb[i];
    }
    EXPECT_LT(err / ref, 0.01) << "mean relative error of lat-long -> angular -> lat-long";

    // Both lights agree on radiance for random directions (up to one pixel of blur).
    ImageEnvironment a(ll, EnvMapping::latlong, 0.0f, 1.0f);
    ImageEnvironment b(ang, EnvMapping::angular, 0.0f, 1.0f);
    HashRng rng(13);
    double diff = 0.0, sum = 0.0;
    for (int i = 0; i < 20000; ++i) {
        Vec3f d = sample_uniform_sphere(rng.next2());
        diff += glm::length(a.eval(d) - b.eval(d));
        sum += glm::length(a.eval(d));
    }
    EXPECT_LT(diff / sum, 0.02);
}

}  // namespace
}  // namespace kdt
