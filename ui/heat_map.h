// Heat maps of per-pixel kd-tree cost (nodes visited or triangles tested per sample) as
// display-ready colours on a log scale, with the scale for a legend. No GL.
// Depends on core only.
#pragma once

#include <vector>

#include "renderer/core/math.h"

namespace kdt::ui {

struct HeatScale {
    float lo = 0.0f, hi = 0.0f;  ///< smallest positive and largest value
    double mean = 0.0;           ///< over pixels with a positive value
};

/// The colour ramp at t in [0, 1] (black, blue, magenta, orange, yellow, white; clamped).
Vec3f heat_ramp(float t);
/// Position of `v` on the log scale of `scale`, in [0, 1].
float heat_position(float v, const HeatScale& scale);
/// Colours `values` (one per pixel) into rgb (3 floats in [0, 1] per pixel); a pixel of
/// value 0 (no samples) is black. Returns the scale.
HeatScale heat_colors(const std::vector<float>& values, std::vector<float>& rgb);

}  // namespace kdt::ui
