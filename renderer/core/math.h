// Math vocabulary of kdtrace: GLM aliases, axis-aligned boxes and rays.
// Depends on the standard library and GLM only.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>

#include <glm/glm.hpp>

namespace kdt {

using Vec2f = glm::vec2;
using Vec3f = glm::vec3;
using Vec4f = glm::vec4;
using Vec3d = glm::dvec3;
using Vec2i = glm::ivec2;
using Vec3u = glm::uvec3;
using Mat3f = glm::mat3;
using Mat4f = glm::mat4;

/// Component k (0, 1, 2) of v as one indexed load. GLM's operator[] is a switch on k,
/// which costs a chain of compare-and-branch in hot loops where k is not a constant (split
/// axes, the watertight test's permuted axes), and copying v to an array first costs three
/// stores per call. glm::vec3 is three packed floats (checked below), indexed from x as
/// pbrt and GLM's own value_ptr do.
inline float component(const Vec3f& v, int k) {
    static_assert(sizeof(Vec3f) == 3 * sizeof(float), "glm::vec3 is three packed floats");
    return reinterpret_cast<const float*>(&v)[k];
}

constexpr float kPi = 3.14159265358979323846f;
constexpr float kInvPi = 0.31830988618379067154f;
constexpr float kInfinity = std::numeric_limits<float>::infinity();

/// Axis-aligned box; an empty box has lower > upper on every axis.
struct Bounds3f {
    Vec3f lower{kInfinity};
    Vec3f upper{-kInfinity};

    bool empty() const { return lower.x > upper.x || lower.y > upper.y || lower.z > upper.z; }
    void extend(const Vec3f& p) {
        lower = glm::min(lower, p);
        upper = glm::max(upper, p);
    }
    void extend(const Bounds3f& b) {
        lower = glm::min(lower, b.lower);
        upper = glm::max(upper, b.upper);
    }
    Vec3f extent() const { return upper - lower; }
    Vec3f center() const { return 0.5f * (lower + upper); }
    /// Surface area; 0 for an empty box.
    float surface_area() const {
        if (empty()) return 0.0f;
        Vec3f d = extent();
        return 2.0f * (d.x * d.y + d.y * d.z + d.z * d.x);
    }
    int longest_axis() const {
        Vec3f d = extent();
        return d.x >= d.y && d.x >= d.z ? 0 : (d.y >= d.z ? 1 : 2);
    }
};

/// A ray with its parametric interval [tmin, tmax]; dir need not be normalised.
struct Ray {
    Vec3f origin{0.0f};
    float tmin = 0.0f;
    Vec3f dir{0.0f, 0.0f, 1.0f};
    float tmax = kInfinity;
};

inline bool is_finite(const Vec3f& v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

}  // namespace kdt
