// Camera moves of the viewer as pure functions on a CameraDesc (eye, target, up, field of
// view): orbit about the target, pan, zoom, fly, frame a box. An unmoved camera stays the exact
// CameraDesc it came from, so the viewer renders bit for bit what `kdtrace render` does.
// Depends on core and scene (CameraDesc) only.
#pragma once

#include <string>

#include "renderer/core/math.h"
#include "renderer/scene/scene.h"

namespace kdt::ui {

/// Turns the eye about the target: yaw about the up vector, pitch about the camera's right
/// axis (clamped 1 degree short of the poles). Degrees.
CameraDesc orbit(const CameraDesc& c, float yaw_degrees, float pitch_degrees);
/// Moves eye and target together across the view; dx, dy are fractions of the view's height
/// at the target's distance (right and up on screen).
CameraDesc pan(const CameraDesc& c, float dx, float dy);
/// Scales the eye's distance to the target by `factor` (> 0; < 1 comes closer; another factor
/// changes nothing).
CameraDesc zoom(const CameraDesc& c, float factor);
/// zoom() kept to the distances at which a scene of bounds `scene` can be seen:
/// [kMinZoomDistance, kMaxZoomDistance] times the box's diagonal (unclamped for an empty box).
/// A camera already outside that range may move back into it, never further out.
CameraDesc zoom(const CameraDesc& c, float factor, const Bounds3f& scene);
inline constexpr float kMinZoomDistance = 1e-4f, kMaxZoomDistance = 1e4f;
/// Moves eye and target along the camera's right, up and forward axes by the given
/// fractions of the eye's distance to the target.
CameraDesc fly(const CameraDesc& c, float right, float up, float forward);
/// Looks at the centre of `box` from the same direction, from where its bounding sphere fills
/// the vertical field of view.
CameraDesc frame(const CameraDesc& c, const Bounds3f& box);

/// "" when `c` makes a camera the renderer accepts with its view direction resolved in float:
/// finite, eye and target apart by more than 1e-4 of their largest coordinate (so a move far
/// away cannot collapse them by rounding), an up vector not along the view. Otherwise why not.
std::string camera_problem(const CameraDesc& c);

}  // namespace kdt::ui
