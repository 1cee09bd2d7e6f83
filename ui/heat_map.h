// The debug views as display-ready colours: heat maps of per-pixel kd-tree cost (nodes
// visited or triangles tested per sample) on a log scale, shading normals as n * 0.5 + 0.5 and
// depth on a log scale auto-ranged to the frame, with the scales for a legend. No GL.
// Depends on core and the render session's FilmImage only.
#pragma once

#include <optional>
#include <vector>

#include "renderer/core/math.h"
#include "renderer/render/session.h"

namespace kdt::ui {

struct HeatScale {
    float lo = 0.0f, hi = 0.0f;  ///< smallest positive and largest (finite) value
    double mean = 0.0;           ///< over pixels with a positive, finite value
    double sky_fraction = 0.0;   ///< normals and depth: share of pixels whose samples all escaped
};

/// The debug views of FilmImage layers.
enum class DebugLayer { nodes, triangles, normals, depth };

/// The colour ramp at t in [0, 1] (black, blue, magenta, orange, yellow, white; clamped).
Vec3f heat_ramp(float t);
/// The depth view's ramp at t in [0, 1] (near, warm and bright, to far, blue and dark).
Vec3f depth_ramp(float t);
/// The colour that marks sky pixels in the normals and depth views: a grey checkerboard of
/// 4-pixel squares, by pixel position.
Vec3f sky_color(int x, int y);
/// Position of `v` on the log scale of `scale`, in [0, 1].
float heat_position(float v, const HeatScale& scale);
/// Colours `values` (one per pixel) into rgb (3 floats in [0, 1] per pixel); a pixel of
/// value 0 (no samples) is black. Returns the values' own scale; the colours use it widened
/// to `also` when given (the other side of a split view, so both share one scale).
HeatScale heat_colors(const std::vector<float>& values, std::vector<float>& rgb,
                      const HeatScale* also = nullptr);
/// The range covering both scales' ranges (a scale without 0 < lo <= hi has none); mean and
/// sky_fraction are a's.
HeatScale widen(const HeatScale& a, const HeatScale& b);
/// Colours FilmImage::aov_normals (3 floats a pixel): n * 0.5 + 0.5 of the normalised mean,
/// sky_color() where depth (FilmImage::aov_depth) is infinite, black without samples.
HeatScale normal_colors(const std::vector<float>& normals, const std::vector<float>& depth,
                        int width, std::vector<float>& rgb);
/// Colours FilmImage::aov_depth with depth_ramp() on the log scale from the frame's nearest
/// to its farthest hit (widened to `also` as heat_colors does); sky_color() where infinite,
/// black without samples.
HeatScale depth_colors(const std::vector<float>& depth, int width, std::vector<float>& rgb,
                       const HeatScale* also = nullptr);
/// The heat-map layers (kd-tree cost counts) and the AOV layers (normals, depth).
inline bool is_heat(std::optional<DebugLayer> layer) {
    return layer == DebugLayer::nodes || layer == DebugLayer::triangles;
}
inline bool is_aov(std::optional<DebugLayer> layer) {
    return layer == DebugLayer::normals || layer == DebugLayer::depth;
}
/// Whether `image` carries `layer` (the heat counts, or the normals and depth).
bool has_layer(DebugLayer layer, const FilmImage& image);
/// Colours `layer` of `image` into rgb and sets `scale` to the image's own; false (rgb
/// untouched) when the image lacks the layer. `also` as for heat_colors.
bool debug_colors(DebugLayer layer, const FilmImage& image, std::vector<float>& rgb,
                  HeatScale& scale, const HeatScale* also = nullptr);

}  // namespace kdt::ui
