#include "ui/heat_map.h"

#include <algorithm>
#include <cmath>

namespace kdt::ui {

Vec3f heat_ramp(float t) {
    static const Vec3f kStops[] = {{0.0f, 0.0f, 0.0f}, {0.1f, 0.1f, 0.6f}, {0.7f, 0.1f, 0.6f},
                                   {1.0f, 0.5f, 0.0f}, {1.0f, 0.9f, 0.1f}, {1.0f, 1.0f, 1.0f}};
    constexpr int kN = int(std::size(kStops));
    const float x = std::clamp(t, 0.0f, 1.0f) * float(kN - 1);
    const int i = std::min(int(x), kN - 2);
    const float f = x - float(i);
    return kStops[i] * (1.0f - f) + kStops[i + 1] * f;
}

float heat_position(float v, const HeatScale& s) {
    if (!(v > 0.0f) || !(s.hi > s.lo)) return v > 0.0f ? 1.0f : 0.0f;
    return std::clamp(std::log(v / s.lo) / std::log(s.hi / s.lo), 0.0f, 1.0f);
}

HeatScale heat_colors(const std::vector<float>& values, std::vector<float>& rgb) {
    HeatScale s;
    s.lo = INFINITY;
    size_t n = 0;
    for (float v : values) {
        if (!(v > 0.0f) || !std::isfinite(v)) continue;
        s.lo = std::min(s.lo, v);
        s.hi = std::max(s.hi, v);
        s.mean += double(v);
        ++n;
    }
    if (n == 0) s.lo = 0.0f;
    s.mean = n > 0 ? s.mean / double(n) : 0.0;
    rgb.resize(values.size() * 3);
    for (size_t i = 0; i < values.size(); ++i) {
        // A pixel at the minimum stays distinguishable from one without samples.
        const Vec3f c =
            values[i] > 0.0f ? heat_ramp(0.05f + 0.95f * heat_position(values[i], s)) : Vec3f(0.0f);
        rgb[3 * i] = c.x;
        rgb[3 * i + 1] = c.y;
        rgb[3 * i + 2] = c.z;
    }
    return s;
}

}  // namespace kdt::ui
