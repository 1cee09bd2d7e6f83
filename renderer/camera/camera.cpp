#include "renderer/camera/camera.h"

#include <cmath>
#include <string>
#include <tuple>

#include "renderer/core/error.h"

namespace kdt {

namespace {

// Inverse CDF of the tent on [-1, 1] for u in [0, 1).
float sample_tent(float u) {
    if (u < 0.5f) return std::sqrt(2.0f * u) - 1.0f;
    return 1.0f - std::sqrt(2.0f - 2.0f * u);
}

// Directions are scaled by their largest component before normalizing, so that the squares
// in the length neither overflow nor underflow for huge or tiny scenes.
Vec3f unit_vector(const Vec3f& v) {
    const float m = std::max(std::fabs(v.x), std::max(std::fabs(v.y), std::fabs(v.z)));
    return m > 0.0f ? glm::normalize(v / m) : Vec3f(0.0f);
}

}  // namespace

Vec2f sample_tent_filter(const Vec2f& u) {
    return {0.5f + sample_tent(u.x), 0.5f + sample_tent(u.y)};
}

CameraFrameProblem camera_frame_problem(const Vec3f& eye, const Vec3f& target, const Vec3f& up) {
    // Name the vector: an overflowed or NaN coordinate is not "parallel" to anything.
    for (auto [name, v, blame] : {std::tuple{"eye", eye, &CameraFrameProblem::eye},
                                  std::tuple{"target", target, &CameraFrameProblem::target},
                                  std::tuple{"up", up, &CameraFrameProblem::up}}) {
        if (is_finite(v)) continue;
        CameraFrameProblem p{std::string(name) + " (" + std::to_string(v.x) + ", " +
                             std::to_string(v.y) + ", " + std::to_string(v.z) +
                             ") is not finite (infinite, NaN or overflowed float)"};
        p.*blame = true;
        return p;
    }
    const Vec3f view = target - eye;
    if (!is_finite(view)) {
        return {"eye and target are too far apart: their difference overflows float", true, true};
    }
    if (view == Vec3f(0.0f)) return {"eye and target coincide", true, true};
    if (up == Vec3f(0.0f)) return {"up vector is zero", false, false, true};
    if (!(glm::length(glm::cross(unit_vector(view), unit_vector(up))) > 1e-6f))
        return {"up vector is parallel to the viewing direction", true, true, true};
    return {};
}

Camera make_camera(const Vec3f& eye, const Vec3f& target, const Vec3f& up, float vfov_degrees,
                   int width, int height) {
    if (width <= 0 || height <= 0) {
        throw Error("camera: image size must be positive (got " + std::to_string(width) + "x" +
                    std::to_string(height) + ")");
    }
    // The film keeps about 40 bytes per pixel: 2^28 pixels would be 10 GB.
    if (width > kMaxCameraSide || height > kMaxCameraSide ||
        int64_t(width) * int64_t(height) > kMaxCameraPixels) {
        throw Error("camera: image size " + std::to_string(width) + "x" + std::to_string(height) +
                    " is too large (at most " + std::to_string(kMaxCameraSide) + " per side and " +
                    std::to_string(kMaxCameraPixels) + " pixels)");
    }
    if (!(vfov_degrees > 0.0f && vfov_degrees < 180.0f)) {
        throw Error("camera: vertical field of view must be in (0, 180) degrees (got " +
                    std::to_string(vfov_degrees) + ")");
    }
    if (CameraFrameProblem p = camera_frame_problem(eye, target, up); !p.why.empty())
        throw Error("camera: " + p.why);
    Camera c;
    c.eye = eye;
    c.forward = unit_vector(target - eye);
    const Vec3f r = glm::cross(c.forward, unit_vector(up));
    c.right = glm::normalize(r);
    c.up = glm::cross(c.right, c.forward);
    c.vfov_degrees = vfov_degrees;
    c.width = width;
    c.height = height;
    c.tan_half_vfov = std::tan(0.5f * vfov_degrees * kPi / 180.0f);
    // sx = (2 x / width - 1) tan * aspect and sy = (1 - 2 y / height) tan, in the camera
    // frame; generate_ray() adds x and y times the per-pixel steps to the top-left corner.
    const float aspect = float(width) / float(height);
    const float half_w = c.tan_half_vfov * aspect, half_h = c.tan_half_vfov;
    c.dir_origin = c.forward - half_w * c.right + half_h * c.up;
    c.dir_per_pixel_x = (2.0f * half_w / float(width)) * c.right;
    c.dir_per_pixel_y = (-2.0f * half_h / float(height)) * c.up;
    return c;
}

}  // namespace kdt
