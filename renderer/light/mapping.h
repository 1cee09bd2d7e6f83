// Environment-map parameterisations: unit direction <-> image coordinates for the
// lat-long (equirectangular) and Debevec angular ("light probe") mappings, their
// Jacobians, the rotation about +y, and resampling between the two. Depends on core, io.
//
// Conventions (docs/conventions.md, "Environment maps"): world +y is up, right-handed.
// Image coordinates (u, v) are in [0,1]^2 over the whole image; u grows to the right,
// v grows downwards (v = 0 is the top edge of row 0). Pixel (x, y) covers
// [x/W, (x+1)/W) x [y/H, (y+1)/H).
//
// Lat-long (identical to Mitsuba 3's `envmap` with an identity to_world):
//   phi = 2 pi u, theta = pi v,
//   d = (sin(phi) sin(theta), cos(theta), -cos(phi) sin(theta)).
//   Top row = +y, bottom row = -y; u = 0 (left edge) looks along -z, u = 1/4 along +x,
//   u = 1/2 (centre column) along +z, u = 3/4 along -x. Seen from inside the sphere the
//   image is not mirrored. Jacobian: d(omega) = 2 pi^2 sin(theta) du dv.
//
// Angular map (Debevec, "Light Probe Image Gallery"; angmap.cal): with image coordinates
// a = 2u - 1 (right) and b = 1 - 2v (up), both in [-1,1], and rho = sqrt(a^2 + b^2) <= 1,
//   theta' = pi rho (angle from +z), d = (a/rho sin(theta'), b/rho sin(theta'), cos(theta')),
// i.e. r = acos(d_z) / (pi sqrt(d_x^2 + d_y^2)), (a, b) = (d_x r, d_y r). The probe frame is
// our world frame: the image centre is +z (towards the photographer of the mirror ball),
// the rim is -z (the direction the photographer faced), +y is up, +x is to the right.
// Pixels outside the unit circle are never looked up. Jacobian:
// d(omega) = (pi^2 sin(theta')/theta') da db = 4 pi^2 sin(theta')/theta' du dv.
//
// Rotation: rotation_degrees = alpha turns the map about +y by the right-hand rule:
// world = R_y(alpha) map, with R_y(alpha) (x, y, z) = (x cos a + z sin a, y, -x sin a + z cos a).
#pragma once

#include <cmath>
#include <optional>

#include "renderer/core/math.h"
#include "renderer/io/image_io.h"
#include "renderer/light/environment.h"

namespace kdt {

/// Rotates d about +y by `radians` (right-hand rule; +x goes towards -z for +90 degrees).
inline Vec3f rotate_y(const Vec3f& d, float cos_a, float sin_a) {
    return {d.x * cos_a + d.z * sin_a, d.y, -d.x * sin_a + d.z * cos_a};
}
inline Vec3f rotate_y(const Vec3f& d, float radians) {
    return rotate_y(d, std::cos(radians), std::sin(radians));
}

/// Lat-long: unit direction -> (u, v) with u in [0,1), v in [0,1].
inline Vec2f latlong_uv_from_dir(const Vec3f& d) {
    float phi = std::atan2(d.x, -d.z);  // (-pi, pi]
    if (phi < 0.0f) phi += 2.0f * kPi;
    float u = phi * (0.5f * kInvPi);
    if (u >= 1.0f) u = 0.0f;
    // atan2 keeps precision near the poles, where acos(d.y) would not.
    float theta = std::atan2(std::sqrt(d.x * d.x + d.z * d.z), d.y);
    return {u, theta * kInvPi};
}

/// Lat-long: (u, v) -> unit direction.
inline Vec3f latlong_dir_from_uv(const Vec2f& uv) {
    float phi = 2.0f * kPi * uv.x, theta = kPi * uv.y;
    float st = std::sin(theta);
    return {std::sin(phi) * st, std::cos(theta), -std::cos(phi) * st};
}

/// Lat-long: d(omega) / (du dv) at unit direction d, = 2 pi^2 sin(theta).
inline float latlong_jacobian(const Vec3f& d) {
    return 2.0f * kPi * kPi * std::sqrt(d.x * d.x + d.z * d.z);
}

/// Angular map: unit direction -> (u, v) inside the inscribed disk of [0,1]^2.
inline Vec2f angular_uv_from_dir(const Vec3f& d) {
    float s = std::sqrt(d.x * d.x + d.y * d.y);
    float theta = std::atan2(s, d.z);  // angle from +z, [0, pi]
    float rho = theta * kInvPi;
    float a, b;
    if (s > 0.0f) {
        a = d.x / s * rho;
        b = d.y / s * rho;
    } else {
        a = rho;  // +z -> centre; -z -> a point on the rim (all of the rim is -z)
        b = 0.0f;
    }
    return {0.5f * (a + 1.0f), 0.5f * (1.0f - b)};
}

/// Angular map: (u, v) -> unit direction, or nullopt outside the unit disk.
inline std::optional<Vec3f> angular_dir_from_uv(const Vec2f& uv) {
    float a = 2.0f * uv.x - 1.0f, b = 1.0f - 2.0f * uv.y;
    float rho2 = a * a + b * b;
    if (!(rho2 <= 1.0f)) return std::nullopt;
    float rho = std::sqrt(rho2);
    if (rho == 0.0f) return Vec3f(0.0f, 0.0f, 1.0f);
    float theta = kPi * rho;
    float k = std::sin(theta) / rho;
    return Vec3f(a * k, b * k, std::cos(theta));
}

/// Angular map: d(omega) / (du dv) at unit direction d, = 4 pi^2 sin(theta')/theta'.
inline float angular_jacobian(const Vec3f& d) {
    float s = std::sqrt(d.x * d.x + d.y * d.y);
    float theta = std::atan2(s, d.z);
    return theta > 0.0f ? 4.0f * kPi * kPi * s / theta : 4.0f * kPi * kPi;
}

/// Mapping-generic forms of the above.
inline Vec2f env_uv_from_dir(EnvMapping m, const Vec3f& d) {
    return m == EnvMapping::latlong ? latlong_uv_from_dir(d) : angular_uv_from_dir(d);
}
inline std::optional<Vec3f> env_dir_from_uv(EnvMapping m, const Vec2f& uv) {
    if (m == EnvMapping::latlong) return latlong_dir_from_uv(uv);
    return angular_dir_from_uv(uv);
}
inline float env_jacobian(EnvMapping m, const Vec3f& d) {
    return m == EnvMapping::latlong ? latlong_jacobian(d) : angular_jacobian(d);
}

/// Area of the intersection of the unit disk with the rectangle [x0,x1] x [y0,y1] (exact).
double disk_rect_area(double x0, double x1, double y0, double y1);

/// Resamples a lat-long map into a size x size angular map: each output pixel averages the
/// nearest-neighbour lookups at those of its supersample^2 stratified points that lie inside
/// the unit disk; pixels with no such point (outside the disk) stay black.
ImageRGB latlong_to_angular(const ImageRGB& latlong, int size, int supersample = 4);

/// Resamples an angular map into a width x width/2 lat-long map (supersample^2 nearest
/// lookups per output pixel).
ImageRGB angular_to_latlong(const ImageRGB& angular, int width, int supersample = 4);

}  // namespace kdt
