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
enum class ToneCurve : uint8_t { clamp, reinhard, aces };
inline constexpr std::array<const char*, 3> kToneCurveNames = {"clamp", "reinhard", "aces"};

/// Parameters of 8-bit output. exposure is in stops: radiance is multiplied by 2^exposure.
struct ToneParams {
    float exposure = 0.0f;
    ToneCurve curve = ToneCurve::clamp;
};

/// Applies the tone curve to one linear channel value (after exposure); result in [0,1].
/// reinhard: x / (1 + x); aces: Narkowicz's 2015 fit of the ACES filmic curve.
inline float apply_tone_curve(float x, ToneCurve curve) {
    if (!(x > 0.0f)) return 0.0f;
    switch (curve) {
        case ToneCurve::clamp:
            return x < 1.0f ? x : 1.0f;
        case ToneCurve::reinhard:
            return std::isinf(x) ? 1.0f : x / (1.0f + x);
        case ToneCurve::aces: {
            if (std::isinf(x)) return 1.0f;
            float y = (x * (2.51f * x + 0.03f)) / (x * (2.43f * x + 0.59f) + 0.14f);
            return y < 0.0f ? 0.0f : (y > 1.0f ? 1.0f : y);
        }
    }
    return 0.0f;
}

/// Linear channel value -> 8-bit sRGB code value with exposure and tone curve; NaN -> 0.
inline uint8_t tonemap_to_srgb8(float linear, const ToneParams& params) {
    float scaled = linear * std::exp2(params.exposure);
    float encoded = linear_to_srgb(apply_tone_curve(scaled, params.curve));
    return uint8_t(encoded * 255.0f + 0.5f);
}

}  // namespace kdt
