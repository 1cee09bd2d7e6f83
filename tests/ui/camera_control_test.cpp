// Camera moves of the viewer: orbit keeps the distance and turns by the asked angles, pitch
// stops short of the poles, pan and fly move eye and target together, frame fits the box.
#include "ui/camera_control.h"

#include <cmath>

#include <gtest/gtest.h>

namespace kdt::ui {
namespace {

CameraDesc start() {
    CameraDesc c;
    c.eye = {0.0f, 1.0f, 5.0f};
    c.target = {0.0f, 1.0f, 0.0f};
    c.up = {0.0f, 1.0f, 0.0f};
    c.vfov_degrees = 40.0f;
    return c;
}

float elevation_degrees(const CameraDesc& c) {
    const Vec3f d = glm::normalize(c.eye - c.target);
    return std::asin(glm::dot(d, glm::normalize(c.up))) * 180.0f / 3.14159265f;
}

TEST(CameraControl, OrbitTurnsAboutTheTargetAndKeepsTheDistance) {
    const CameraDesc c = start();
    const CameraDesc yawed = orbit(c, 90.0f, 0.0f);
    EXPECT_NEAR(glm::length(yawed.eye - yawed.target), 5.0f, 1e-4f);
    EXPECT_NEAR(std::abs(yawed.eye.x), 5.0f, 1e-4f);  // a quarter turn about +y
    EXPECT_NEAR(yawed.eye.z, 0.0f, 1e-4f);
    EXPECT_EQ(yawed.target, c.target);
    const CameraDesc round = orbit(orbit(c, 360.0f, 0.0f), 0.0f, 0.0f);
    EXPECT_NEAR(glm::length(round.eye - c.eye), 0.0f, 1e-4f);

    const CameraDesc up = orbit(c, 0.0f, 30.0f);
    EXPECT_NEAR(elevation_degrees(up), 30.0f, 1e-2f);
    EXPECT_NEAR(glm::length(up.eye - up.target), 5.0f, 1e-4f);
    // Pitch stops one degree short of the pole, never flips over it.
    EXPECT_NEAR(elevation_degrees(orbit(c, 0.0f, 120.0f)), 89.0f, 1e-2f);
    EXPECT_NEAR(elevation_degrees(orbit(c, 0.0f, -120.0f)), -89.0f, 1e-2f);
}

TEST(CameraControl, PanFlyAndZoom) {
    const CameraDesc c = start();
    const CameraDesc p = pan(c, 0.5f, 0.0f);
    const Vec3f moved = p.eye - c.eye;
    EXPECT_EQ(p.target - c.target, moved);
    // Half the view's height at the target's distance, to the right (+x looking down -z).
    EXPECT_NEAR(moved.x, 0.5f * 2.0f * 5.0f * std::tan(20.0f * 3.14159265f / 180.0f), 1e-4f);
    const CameraDesc f = fly(c, 0.0f, 0.0f, 0.1f);
    EXPECT_NEAR(f.eye.z, 4.5f, 1e-5f);
    EXPECT_NEAR(f.target.z, -0.5f, 1e-5f);
    const CameraDesc z = zoom(c, 0.5f);
    EXPECT_NEAR(glm::length(z.eye - z.target), 2.5f, 1e-5f);
    EXPECT_EQ(zoom(c, -1.0f).eye, c.eye);  // a bad factor changes nothing
}

TEST(CameraControl, MovesFarAwayOrIntoTheTargetAreRefusedOrClamped) {
    const CameraDesc c = start();
    EXPECT_EQ(camera_problem(c), "");
    // Moves whose float result collapses eye onto target, or turns up along the view.
    for (const CameraDesc& bad :
         {fly(c, 1e10f, 0.0f, 0.0f), fly(c, 0.0f, 0.0f, -1e10f), fly(c, 0.0f, 1e30f, 0.0f),
          pan(c, 1e10f, 1e10f), pan(c, 1e30f, 0.0f), zoom(c, 1e-12f), zoom(c, 1e-30f)}) {
        EXPECT_NE(camera_problem(bad), "") << bad.eye.x << " " << bad.target.x;
    }
    CameraDesc nan = c;
    nan.eye.x = std::nanf("");
    EXPECT_NE(camera_problem(nan), "");

    // Zoom keeps to [1e-4, 1e4] times the scene's diagonal (here 2 * sqrt(3)).
    Bounds3f box;
    box.extend(Vec3f(-1.0f, 0.0f, -1.0f));
    box.extend(Vec3f(1.0f, 2.0f, 1.0f));
    const float size = glm::length(box.extent());
    CameraDesc z = c;
    for (int i = 0; i < 100; ++i) z = zoom(z, 0.35f, box);
    EXPECT_NEAR(glm::length(z.eye - z.target), kMinZoomDistance * size, 1e-6f);
    EXPECT_EQ(camera_problem(z), "");
    EXPECT_NEAR(glm::length(zoom(c, 1e30f, box).eye - c.target), kMaxZoomDistance * size, 1.0f);
    EXPECT_EQ(zoom(c, 0.5f, box).eye, zoom(c, 0.5f).eye);  // within the range: the same
    // A camera already beyond the range is not pulled in by a zoom out, and may zoom in.
    const CameraDesc far = zoom(c, 1e5f);
    EXPECT_EQ(zoom(far, 2.0f, box).eye, far.eye);
    EXPECT_EQ(zoom(far, 0.5f, box).eye, zoom(far, 0.5f).eye);
}

TEST(CameraControl, FrameFitsTheBoxFromTheSameDirection) {
    const CameraDesc c = start();
    Bounds3f box;
    box.extend(Vec3f(10.0f, 10.0f, 10.0f));
    box.extend(Vec3f(12.0f, 14.0f, 11.0f));
    const CameraDesc f = frame(c, box);
    EXPECT_EQ(f.target, box.center());
    const Vec3f dir = glm::normalize(f.target - f.eye);
    EXPECT_NEAR(glm::dot(dir, glm::normalize(c.target - c.eye)), 1.0f, 1e-5f);
    const float radius = 0.5f * glm::length(box.extent());
    const float half_fov = std::asin(radius / glm::length(f.eye - f.target));
    EXPECT_NEAR(half_fov * 180.0f / 3.14159265f, 20.0f, 1e-3f);
    EXPECT_EQ(frame(c, Bounds3f{}).eye, c.eye);  // an empty box changes nothing
}

}  // namespace
}  // namespace kdt::ui
