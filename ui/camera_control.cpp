#include "ui/camera_control.h"

#include <algorithm>
#include <cmath>

#include "renderer/camera/camera.h"
#include "renderer/core/error.h"

namespace kdt::ui {

namespace {

constexpr float kDegrees = 3.14159265358979f / 180.0f;

struct Frame {
    Vec3f forward, right, up;
    float distance;
};

Frame frame_of(const CameraDesc& c) {
    Frame f;
    const Vec3f d = c.target - c.eye;
    f.distance = glm::length(d);
    f.forward = f.distance > 0.0f ? d / f.distance : Vec3f(0.0f, 0.0f, -1.0f);
    Vec3f r = glm::cross(f.forward, c.up);
    if (glm::length(r) < 1e-6f) r = glm::cross(f.forward, Vec3f(1.0f, 0.0f, 0.0f));
    f.right = glm::normalize(r);
    f.up = glm::cross(f.right, f.forward);
    return f;
}

// Rodrigues' rotation of v about the unit axis k by angle a.
Vec3f rotate(const Vec3f& v, const Vec3f& k, float a) {
    const float cs = std::cos(a), sn = std::sin(a);
    return v * cs + glm::cross(k, v) * sn + k * glm::dot(k, v) * (1.0f - cs);
}

}  // namespace

CameraDesc orbit(const CameraDesc& c, float yaw_degrees, float pitch_degrees) {
    const Frame f = frame_of(c);
    const Vec3f up = glm::normalize(c.up);
    Vec3f offset = c.eye - c.target;
    offset = rotate(offset, up, -yaw_degrees * kDegrees);
    // Pitch: keep the angle between the offset and the up vector within (1, 179) degrees.
    const float len = glm::length(offset);
    const float elevation = std::asin(std::clamp(glm::dot(offset / len, up), -1.0f, 1.0f));
    const float limit = 89.0f * kDegrees;
    const float target = std::clamp(elevation + pitch_degrees * kDegrees, -limit, limit);
    const Vec3f right = glm::normalize(rotate(f.right, up, -yaw_degrees * kDegrees));
    offset = rotate(offset, right, -(target - elevation));
    CameraDesc out = c;
    out.eye = c.target + offset;
    return out;
}

CameraDesc pan(const CameraDesc& c, float dx, float dy) {
    const Frame f = frame_of(c);
    const float view_height = 2.0f * f.distance * std::tan(0.5f * c.vfov_degrees * kDegrees);
    const Vec3f move = (f.right * dx + f.up * dy) * view_height;
    CameraDesc out = c;
    out.eye += move;
    out.target += move;
    return out;
}

CameraDesc zoom(const CameraDesc& c, float factor) {
    CameraDesc out = c;
    if (factor > 0.0f && std::isfinite(factor)) out.eye = c.target + (c.eye - c.target) * factor;
    return out;
}

CameraDesc zoom(const CameraDesc& c, float factor, const Bounds3f& scene) {
    CameraDesc out = zoom(c, factor);
    if (scene.empty() || out.eye == c.eye) return out;
    const float size = glm::length(scene.extent());
    if (!(size > 0.0f) || !std::isfinite(size)) return out;
    const float d = glm::length(c.eye - c.target);
    const float lo = std::min(d, kMinZoomDistance * size),
                hi = std::max(d, kMaxZoomDistance * size);
    const float wanted = d * factor;
    if (wanted < lo || wanted > hi) {
        const float to = std::clamp(wanted, lo, hi);
        out.eye = c.target + (c.eye - c.target) * (to / d);
    }
    return out;
}

CameraDesc fly(const CameraDesc& c, float right, float up, float forward) {
    const Frame f = frame_of(c);
    const Vec3f move = (f.right * right + f.up * up + f.forward * forward) * f.distance;
    CameraDesc out = c;
    out.eye += move;
    out.target += move;
    return out;
}

CameraDesc frame(const CameraDesc& c, const Bounds3f& box) {
    if (box.empty()) return c;
    const Frame f = frame_of(c);
    const float radius = std::max(0.5f * glm::length(box.extent()), 1e-20f);
    const float distance = radius / std::sin(0.5f * c.vfov_degrees * kDegrees);
    CameraDesc out = c;
    out.target = box.center();
    out.eye = out.target - f.forward * distance;
    return out;
}

std::string camera_problem(const CameraDesc& c) {
    if (!is_finite(c.eye) || !is_finite(c.target) || !is_finite(c.up) ||
        !std::isfinite(c.vfov_degrees)) {
        return "the camera is not finite";
    }
    const float scale = std::max({glm::length(c.eye), glm::length(c.target), 1e-30f});
    if (!(glm::length(c.target - c.eye) > 1e-4f * scale))
        return "eye and target (nearly) coincide at this distance from the origin";
    try {
        make_camera(c.eye, c.target, c.up, c.vfov_degrees, 1, 1);
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

}  // namespace kdt::ui
