// Camera moves of the viewer as pure functions on a CameraDesc (eye, target, up, field of
// view): orbit about the target, pan, zoom, fly, frame a box. An unmoved camera stays the exact
// CameraDesc it came from, so the viewer renders bit for bit what `kdtrace render` does.
// Depends on core and scene (CameraDesc) only.
#pragma once

#include "renderer/core/math.h"
#include "renderer/scene/scene.h"

namespace kdt::ui {

/// Turns the eye about the target: yaw about the up vector, pitch about the camera's right
/// axis (clamped 1 degree short of the poles). Degrees.
CameraDesc orbit(const CameraDesc& c, float yaw_degrees, float pitch_degrees);
/// Moves eye and target together across the view; dx, dy are fractions of the view's height
/// at the target's distance (right and up on screen).
CameraDesc pan(const CameraDesc& c, float dx, float dy);
/// Scales the eye's distance to the target by `factor` (> 0; < 1 comes closer).
CameraDesc zoom(const CameraDesc& c, float factor);
/// Moves eye and target along the camera's right, up and forward axes by the given
/// fractions of the eye's distance to the target.
CameraDesc fly(const CameraDesc& c, float right, float up, float forward);
/// Looks at the centre of `box` from the same direction, from where its bounding sphere fills
/// the vertical field of view.
CameraDesc frame(const CameraDesc& c, const Bounds3f& box);

}  // namespace kdt::ui
