// The pinhole camera: film position in pixels -> world-space primary ray.
// Depends on core only. Conventions (docs/conventions.md): vfov is the full vertical field
// of view; pixel (0, 0) is the top-left pixel and covers [0,1)x[0,1) in film coordinates;
// the camera looks along -z of its own frame with +y up (right-handed, as in OpenGL/pbrt's
// LookAt with a flip to keep +x right).
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "renderer/core/math.h"

namespace kdt {

/// Pixel reconstruction filter, sampled by importance (every sample has weight 1).
enum class PixelFilter : uint8_t { box, tent };
inline constexpr std::array<const char*, 2> kPixelFilterNames = {"box", "tent"};

/// The tent case of sample_pixel_filter().
Vec2f sample_tent_filter(const Vec2f& u);

/// Maps [0,1)^2 to an offset from the pixel's lower corner: box -> uniform over the pixel,
/// tent -> tent of radius 1 pixel around the pixel centre.
inline Vec2f sample_pixel_filter(PixelFilter filter, const Vec2f& u) {
    return filter == PixelFilter::tent ? sample_tent_filter(u) : u;
}

/// A pinhole camera with a precomputed world-space frame.
struct Camera {
    Vec3f eye{0.0f, 0.0f, 5.0f};
    Vec3f right{1.0f, 0.0f, 0.0f};     ///< unit, world space
    Vec3f up{0.0f, 1.0f, 0.0f};        ///< unit, world space, orthogonal to right and forward
    Vec3f forward{0.0f, 0.0f, -1.0f};  ///< unit viewing direction
    float vfov_degrees = 40.0f;        ///< full vertical field of view
    int width = 640, height = 480;     ///< film size in pixels
    float tan_half_vfov = 0.0f;        ///< derived by make_camera()

    /// Derived by make_camera(): the unnormalised direction through film position (x, y)
    /// is dir_origin + x * dir_per_pixel_x + y * dir_per_pixel_y.
    Vec3f dir_origin{0.0f, 0.0f, -1.0f};
    Vec3f dir_per_pixel_x{0.0f}, dir_per_pixel_y{0.0f};

    /// Primary ray through film position `film` (pixels; x right, y down, (0,0) top-left).
    /// dir is unit length, tmin = 0, tmax = infinity.
    Ray generate_ray(const Vec2f& film) const {
        // forward + sx * right + sy * up with sx, sy affine in the film position, folded into
        // make_camera's three vectors: no divisions per ray.
        Ray r;
        r.origin = eye;
        r.dir = glm::normalize(dir_origin + film.x * dir_per_pixel_x + film.y * dir_per_pixel_y);
        return r;
    }
};

/// Largest image make_camera() accepts: per side, and in pixels (as image files, 2^27).
inline constexpr int kMaxCameraSide = 65536;
inline constexpr int64_t kMaxCameraPixels = int64_t(1) << 27;

/// Why a camera cannot look from eye at target with up ("eye and target coincide"), and which
/// of the three are to blame, so that a message can name where each came from; `why` is
/// empty when they make a camera frame.
struct CameraFrameProblem {
    std::string why;
    bool eye = false, target = false, up = false;
};
CameraFrameProblem camera_frame_problem(const Vec3f& eye, const Vec3f& target, const Vec3f& up);

/// Builds a camera looking from eye at target. Throws kdt::Error when eye == target, up is
/// parallel to the view direction, vfov is outside (0, 180) or the size is not positive.
Camera make_camera(const Vec3f& eye, const Vec3f& target, const Vec3f& up, float vfov_degrees,
                   int width, int height);

}  // namespace kdt
