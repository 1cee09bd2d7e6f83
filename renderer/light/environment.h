// The environment light: a constant colour or an HDR map (lat-long or angular "light
// probe" mapping) with rotation and intensity, and its importance-sampling distribution.
// Depends on core and io (image loading).
#pragma once

#include <array>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "renderer/core/math.h"

namespace kdt {

enum class EnvMapping : uint8_t { latlong, angular };
inline constexpr std::array<const char*, 2> kEnvMappingNames = {"latlong", "angular"};

/// How a scene describes its environment. file empty = constant colour.
struct EnvironmentDesc {
    Vec3f color{1.0f};  ///< constant radiance when file is empty
    std::string file;   ///< .hdr, .exr or .pfm
    EnvMapping mapping = EnvMapping::latlong;
    float rotation_degrees = 0.0f;  ///< about the world +y axis; modulo 360 (exactly)
    float intensity = 1.0f;         ///< multiplies the map (or the colour)
};

/// A direction sampled from the environment with its radiance and solid-angle pdf.
struct EnvSample {
    Vec3f dir{0.0f, 1.0f, 0.0f};  ///< unit world-space direction towards the light
    Vec3f radiance{0.0f};
    float pdf_solid_angle = 0.0f;  ///< 0 when the map is black
};

/// Immutable once built; safe to query from many threads.
class EnvironmentLight {
public:
    virtual ~EnvironmentLight() = default;
    /// Radiance arriving from unit world direction `dir` (dir points away from the scene).
    virtual Vec3f eval(const Vec3f& dir) const = 0;
    /// Importance-samples a direction from u in [0,1)^2.
    virtual EnvSample sample(const Vec2f& u) const = 0;
    /// Solid-angle pdf with which sample() would return dir.
    virtual float pdf(const Vec3f& dir) const = 0;
    /// True for a constant colour (a furnace); lets the integrator sample cosine-weighted.
    virtual bool is_constant() const = 0;
    /// sample() and pdf() for next-event estimation that multiple importance sampling
    /// combines with BSDF sampling: a map may follow its radiance minus its mean (MIS
    /// compensation, Karlik et al. 2019), leaving directions darker than the mean (pdf 0
    /// here) to BSDF sampling, which takes them at full weight. Unbiased only in such a
    /// combination, with a BSDF sample whose pdf is positive wherever the BSDF is; next-event
    /// estimation alone uses sample() and pdf().
    virtual EnvSample sample_mis(const Vec2f& u) const { return sample(u); }
    virtual float pdf_mis(const Vec3f& dir) const { return pdf(dir); }
};

/// Radiance (colour or brightest texel channel, times intensity) beyond this is refused:
/// the path tracer multiplies radiance by throughputs and divides by pdfs in float, and
/// the film sums samples, so this leaves a factor of 3e8 below FLT_MAX for those products.
inline constexpr float kMaxEnvironmentRadiance = 1e30f;

/// Receives warnings (one line each, without a trailing newline) for the caller to print.
using EnvLog = std::function<void(const std::string&)>;

/// Builds the light; throws kdt::Error for a missing or malformed map file, a colour or
/// intensity that is negative or not finite, texels that are negative or not finite
/// (naming the first one and the count), radiance above kMaxEnvironmentRadiance, and an
/// OpenEXR map whose envmap attribute is not latlong (a cube-face map).
std::shared_ptr<const EnvironmentLight> make_environment_light(const EnvironmentDesc& desc);

/// The same, passing log the mapping warning (environment_mapping_warning) prefixed with
/// "warning: " and the file name, e.g. "warning: probe.hdr: mapping angular for a 512x256
/// image, which looks like a lat-long map (2:1); angular maps are square".
std::shared_ptr<const EnvironmentLight> make_environment_light(const EnvironmentDesc& desc,
                                                               const EnvLog& log);

/// A warning when the image's shape contradicts the mapping (angular for a 2:1 image,
/// lat-long for a square one or any aspect outside [1.5, 2.5]), else "". The map is still
/// used as asked.
std::string environment_mapping_warning(EnvMapping mapping, int width, int height);

}  // namespace kdt
