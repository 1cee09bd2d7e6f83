// Colour vocabulary: linear Rec.709/sRGB-primaries RGB, luminance, the sRGB transfer
// curve and the tone curves used for 8-bit output. Depends on the standard library and GLM.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>

#include "renderer/core/math.h"

namespace kdt {

/// Luminance Y of linear RGB with Rec.709 primaries (the sRGB primaries).
inline float luminance(const Vec3f& rgb) {
    return 0.2126f * rgb.x + 0.7152f * rgb.y + 0.0722f * rgb.z;
}

/// sRGB opto-electronic transfer function (IEC 61966-2-1): linear [0,1] -> encoded [0,1].
/// Values outside [0,1] are clamped first; NaN maps to 0.
inline float linear_to_srgb(float x) {
    if (!(x > 0.0f)) return 0.0f;  // also catches NaN
    if (x >= 1.0f) return 1.0f;
    return x <= 0.0031308f ? 12.92f * x : 1.055f * std::pow(x, 1.0f / 2.4f) - 0.055f;
}

/// Inverse of linear_to_srgb: encoded [0,1] -> linear [0,1].
inline float srgb_to_linear(float x) {
    if (!(x > 0.0f)) return 0.0f;
    if (x >= 1.0f) return 1.0f;
    return x <= 0.04045f ? x / 12.92f : std::pow((x + 0.055f) / 1.055f, 2.4f);
}

/// How linear radiance (after exposure) is compressed into [0,1] before sRGB encoding.
/// Every curve maps 0 (and negatives, NaN) to 0, is monotone non-decreasing, and reaches 1
/// at +infinity at the latest.
enum class ToneCurve : uint8_t { clamp, reinhard, aces, filmic };
inline constexpr std::array<const char*, 4> kToneCurveNames = {"clamp", "reinhard", "aces",
                                                               "filmic"};

/// Parameters of 8-bit output (PNG; EXR, PFM and HDR stay linear). exposure is in stops:
/// radiance is multiplied by 2^exposure before the curve.
struct ToneParams {
    float exposure = 0.0f;
    ToneCurve curve = ToneCurve::clamp;
    bool operator==(const ToneParams&) const = default;
};

/// Hable's filmic curve ("Filmic Tonemapping Operators", Uncharted 2, GDC 2010) with his
/// constants; 0 at 0.
inline double hable_filmic(double x) {
    constexpr double a = 0.15, b = 0.50, c = 0.10, d = 0.20, e = 0.02, f = 0.30;
    return (x * (a * x + c * b) + d * e) / (x * (a * x + b) + d * f) - e / f;
}

/// Applies the tone curve to one linear channel value (after exposure); result in [0,1].
/// clamp: min(x, 1) (the default; highlights clip). reinhard: x / (1 + x).
/// aces: Narkowicz's 2015 fit of the ACES filmic curve (white above about 10).
/// filmic: Hable's curve of 2x (his exposure bias) over its value at the white point 11.2,
/// clamped to 1. The compressive curves are evaluated in double: consecutive floats then
/// never map to decreasing values (in float, x / (1 + x) drops where 1 + x rounds up).
inline float apply_tone_curve(float x, ToneCurve curve) {
    if (!(x > 0.0f)) return 0.0f;
    if (std::isinf(x)) return 1.0f;
    const double xd = x;
    double y = 0.0;
    switch (curve) {
        case ToneCurve::clamp:
            return x < 1.0f ? x : 1.0f;
        case ToneCurve::reinhard:
            y = xd / (1.0 + xd);
            break;
        case ToneCurve::aces:
            // 1 from x = 7.25 on (the limit is 2.51 / 2.43 > 1); the squares would overflow.
            y = xd > 1e6 ? 1.0 : (xd * (2.51 * xd + 0.03)) / (xd * (2.43 * xd + 0.59) + 0.14);
            break;
        case ToneCurve::filmic: {
            constexpr double kWhite = 11.2;
            y = 2.0 * xd >= kWhite ? 1.0 : hable_filmic(2.0 * xd) / hable_filmic(kWhite);
            break;
        }
    }
    return y < 0.0 ? 0.0f : (y > 1.0 ? 1.0f : float(y));
}

/// Linear channel value -> 8-bit sRGB code value with exposure and tone curve; NaN -> 0.
inline uint8_t tonemap_to_srgb8(float linear, const ToneParams& params) {
    float scaled = linear * std::exp2(params.exposure);
    float encoded = linear_to_srgb(apply_tone_curve(scaled, params.curve));
    return uint8_t(encoded * 255.0f + 0.5f);
}

}  // namespace kdt
