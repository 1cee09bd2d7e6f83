#include "renderer/camera/camera.h"

#include <cmath>

#include <gtest/gtest.h>

#include "renderer/core/error.h"

namespace kdt {
namespace {

TEST(Camera, CentreRayLooksAtTarget) {
    const Camera c = make_camera({1, 2, 3}, {1, 2, -7}, {0, 1, 0}, 60.0f, 64, 32);
    const Ray r = c.generate_ray({32.0f, 16.0f});
    EXPECT_NEAR(r.dir.x, 0.0f, 1e-6f);
    EXPECT_NEAR(r.dir.y, 0.0f, 1e-6f);
    EXPECT_NEAR(r.dir.z, -1.0f, 1e-6f);
    EXPECT_EQ(r.origin, Vec3f(1, 2, 3));
}

TEST(Camera, VerticalFieldOfViewSpansTheImageHeight) {
    const float vfov = 50.0f;
    const Camera c = make_camera({0, 0, 0}, {0, 0, -1}, {0, 1, 0}, vfov, 200, 100);
    const Ray top = c.generate_ray({100.0f, 0.0f});  // top edge, centre column
    const Ray bottom = c.generate_ray({100.0f, 100.0f});
    const float angle = std::acos(glm::dot(top.dir, bottom.dir)) * 180.0f / kPi;
    EXPECT_NEAR(angle, vfov, 1e-3f);
    EXPECT_GT(top.dir.y, 0.0f);  // row 0 is the top of the image
    // Horizontal extent follows the aspect ratio.
    const Ray right = c.generate_ray({200.0f, 50.0f});
    EXPECT_GT(right.dir.x, 0.0f);
    EXPECT_NEAR(right.dir.x / -right.dir.z, 2.0f * std::tan(0.5f * vfov * kPi / 180.0f), 1e-5f);
}

TEST(Camera, RejectsBadInput) {
    EXPECT_THROW(make_camera({0, 0, 0}, {0, 0, 0}, {0, 1, 0}, 40, 10, 10), Error);
    EXPECT_THROW(make_camera({0, 0, 0}, {0, 1, 0}, {0, 1, 0}, 40, 10, 10), Error);
    EXPECT_THROW(make_camera({0, 0, 0}, {0, 0, 1}, {0, 1, 0}, 180, 10, 10), Error);
    EXPECT_THROW(make_camera({0, 0, 0}, {0, 0, 1}, {0, 1, 0}, 40, 0, 10), Error);
    // Absurd sizes are an error before the film allocates, not an out-of-memory.
    try {
        make_camera({0, 0, 0}, {0, 0, 1}, {0, 1, 0}, 40, 100000, 100000);
        ADD_FAILURE() << "no error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("100000x100000 is too large"), std::string::npos)
            << e.what();
    }
    EXPECT_THROW(make_camera({0, 0, 0}, {0, 0, 1}, {0, 1, 0}, 40, 65537, 1), Error);
    EXPECT_NO_THROW(make_camera({0, 0, 0}, {0, 0, 1}, {0, 1, 0}, 40, 65536, 1));
}

TEST(Camera, FiltersStayInTheirSupport) {
    double mean_box = 0.0, mean_tent = 0.0;
    for (int i = 0; i < 1000; ++i) {
        const Vec2f u((float(i) + 0.5f) / 1000.0f, 1.0f - (float(i) + 0.5f) / 1000.0f);
        const Vec2f b = sample_pixel_filter(PixelFilter::box, u);
        const Vec2f t = sample_pixel_filter(PixelFilter::tent, u);
        EXPECT_TRUE(b.x >= 0.0f && b.x < 1.0f);
        EXPECT_TRUE(t.x >= -0.5f && t.x <= 1.5f);
        mean_box += b.x;
        mean_tent += t.x;
    }
    EXPECT_NEAR(mean_box / 1000.0, 0.5, 1e-3);
    EXPECT_NEAR(mean_tent / 1000.0, 0.5, 1e-3);
}

}  // namespace
}  // namespace kdt
