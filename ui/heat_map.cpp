#include "ui/heat_map.h"

#include <algorithm>
#include <cmath>

namespace kdt::ui {

namespace {

template <size_t N>
Vec3f ramp(const Vec3f (&stops)[N], float t) {
    constexpr int kN = int(N);
    const float x = (t > 0.0f ? std::min(t, 1.0f) : 0.0f) * float(kN - 1);  // NaN: 0
    const int i = std::min(int(x), kN - 2);
    const float f = x - float(i);
    return stops[i] * (1.0f - f) + stops[i + 1] * f;
}

void put(std::vector<float>& rgb, size_t i, const Vec3f& c) {
    rgb[3 * i] = c.x;
    rgb[3 * i + 1] = c.y;
    rgb[3 * i + 2] = c.z;
}

// The log scale of the positive, finite values, with their mean and the share of infinite ones.
HeatScale scale_of(const std::vector<float>& values) {
    HeatScale s;
    s.lo = INFINITY;
    size_t n = 0, inf = 0;
    for (float v : values) {
        inf += std::isinf(v);
        if (!(v > 0.0f) || !std::isfinite(v)) continue;
        s.lo = std::min(s.lo, v);
        s.hi = std::max(s.hi, v);
        s.mean += double(v);
        ++n;
    }
    if (n == 0) s.lo = 0.0f;
    s.mean = n > 0 ? s.mean / double(n) : 0.0;
    s.sky_fraction = values.empty() ? 0.0 : double(inf) / double(values.size());
    return s;
}

}  // namespace

Vec3f heat_ramp(float t) {
    static const Vec3f kStops[] = {{0.0f, 0.0f, 0.0f}, {0.1f, 0.1f, 0.6f}, {0.7f, 0.1f, 0.6f},
                                   {1.0f, 0.5f, 0.0f}, {1.0f, 0.9f, 0.1f}, {1.0f, 1.0f, 1.0f}};
    return ramp(kStops, t);
}

Vec3f depth_ramp(float t) {
    static const Vec3f kStops[] = {{1.0f, 0.95f, 0.8f},
                                   {0.95f, 0.6f, 0.2f},
                                   {0.5f, 0.3f, 0.55f},
                                   {0.1f, 0.15f, 0.45f},
                                   {0.03f, 0.04f, 0.12f}};
    return ramp(kStops, t);
}

Vec3f sky_color(int x, int y) { return ((x / 4 + y / 4) & 1) != 0 ? Vec3f(0.22f) : Vec3f(0.32f); }

float heat_position(float v, const HeatScale& s) {
    if (!(v > 0.0f) || !(s.hi > s.lo)) return v > 0.0f ? 1.0f : 0.0f;
    return std::clamp(std::log(v / s.lo) / std::log(s.hi / s.lo), 0.0f, 1.0f);
}

HeatScale widen(const HeatScale& a, const HeatScale& b) {
    if (!(b.lo > 0.0f && b.hi >= b.lo)) return a;
    if (!(a.lo > 0.0f && a.hi >= a.lo)) return HeatScale{b.lo, b.hi, a.mean, a.sky_fraction};
    return HeatScale{std::min(a.lo, b.lo), std::max(a.hi, b.hi), a.mean, a.sky_fraction};
}

HeatScale heat_colors(const std::vector<float>& values, std::vector<float>& rgb,
                      const HeatScale* also) {
    const HeatScale s = scale_of(values);
    const HeatScale c = also ? widen(s, *also) : s;
    rgb.resize(values.size() * 3);
    for (size_t i = 0; i < values.size(); ++i) {
        // A pixel at the minimum stays distinguishable from one without samples.
        put(rgb, i,
            values[i] > 0.0f ? heat_ramp(0.05f + 0.95f * heat_position(values[i], c))
                             : Vec3f(0.0f));
    }
    return s;
}

HeatScale normal_colors(const std::vector<float>& normals, const std::vector<float>& depth,
                        int width, std::vector<float>& rgb) {
    const size_t n = depth.size();
    HeatScale s;  // no range: only the share of sky
    s.sky_fraction = scale_of(depth).sky_fraction;
    rgb.resize(n * 3);
    for (size_t i = 0; i < n; ++i) {
        const int x = int(i % size_t(width)), y = int(i / size_t(width));
        const Vec3f m(normals[3 * i], normals[3 * i + 1], normals[3 * i + 2]);
        const float len = glm::length(m);
        if (std::isinf(depth[i])) {
            put(rgb, i, sky_color(x, y));
        } else if (len > 0.0f) {
            put(rgb, i, m / len * 0.5f + Vec3f(0.5f));
        } else {
            put(rgb, i, Vec3f(0.0f));
        }
    }
    return s;
}

HeatScale depth_colors(const std::vector<float>& depth, int width, std::vector<float>& rgb,
                       const HeatScale* also) {
    const HeatScale s = scale_of(depth);
    const HeatScale c = also ? widen(s, *also) : s;
    rgb.resize(depth.size() * 3);
    for (size_t i = 0; i < depth.size(); ++i) {
        const int x = int(i % size_t(width)), y = int(i / size_t(width));
        const float d = depth[i];
        if (std::isinf(d)) {
            put(rgb, i, sky_color(x, y));
        } else if (d > 0.0f) {
            put(rgb, i, depth_ramp(heat_position(d, c)));
        } else {
            put(rgb, i, Vec3f(0.0f));
        }
    }
    return s;
}

bool has_layer(DebugLayer layer, const FilmImage& img) {
    return is_heat(layer) ? !img.heat_nodes.empty() : !img.aov_depth.empty();
}

bool debug_colors(DebugLayer layer, const FilmImage& img, std::vector<float>& rgb, HeatScale& scale,
                  const HeatScale* also) {
    if (!has_layer(layer, img)) return false;
    switch (layer) {
        case DebugLayer::nodes:
        case DebugLayer::triangles:
            scale = heat_colors(layer == DebugLayer::nodes ? img.heat_nodes : img.heat_triangles,
                                rgb, also);
            return true;
        case DebugLayer::normals:
            scale = normal_colors(img.aov_normals, img.aov_depth, img.width, rgb);
            return true;
        case DebugLayer::depth:
            scale = depth_colors(img.aov_depth, img.width, rgb, also);
            return true;
    }
    return false;
}

}  // namespace kdt::ui
