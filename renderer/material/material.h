// Materials the scenes need: Lambertian diffuse, perfect mirror, smooth dielectric,
// emissive (a black emitter), and a rough GGX conductor. BSDF evaluation, sampling and pdf
// in a local shading frame whose +z is the shading normal. Depends on core only.
// Every material except the dielectric is two-sided: the caller flips the frame so that
// wo.z >= 0. The dielectric keeps the geometric orientation: wo.z > 0 is outside.
#pragma once

#include <array>
#include <cstdint>

#include "renderer/core/math.h"

namespace kdt {

enum class MaterialType : uint8_t { diffuse, mirror, dielectric, emissive, conductor };
inline constexpr std::array<const char*, 5> kMaterialTypeNames = {"diffuse", "mirror", "dielectric",
                                                                  "emissive", "conductor"};

/// A material as a scene file gives it (the editable form). Every material is two-sided.
/// Unused fields are ignored by the type (material_uses()).
struct MaterialDesc {
    MaterialType type = MaterialType::diffuse;
    Vec3f albedo{0.8f};      ///< diffuse reflectance; tint of mirror and conductor
    float ior = 1.5f;        ///< dielectric index of refraction (outside is 1)
    Vec3f emission{0.0f};    ///< emissive radiance
    float roughness = 0.2f;  ///< conductor: GGX alpha

    bool operator==(const MaterialDesc&) const = default;
};

/// The fields of a MaterialDesc besides its type, as scene files name them.
enum class MaterialField : uint8_t { albedo, ior, emission, roughness };
inline constexpr std::array<const char*, 4> kMaterialFieldNames = {"albedo", "ior", "emission",
                                                                   "roughness"};

/// True when materials of `type` use `field`; the others ignore it (a scene file giving it
/// gets a warning, and scene writers leave it out).
constexpr bool material_uses(MaterialType type, MaterialField field) {
    switch (field) {
        case MaterialField::albedo:
            return type == MaterialType::diffuse || type == MaterialType::mirror ||
                   type == MaterialType::conductor;
        case MaterialField::ior:
            return type == MaterialType::dielectric;
        case MaterialField::emission:
            return type == MaterialType::emissive;
        case MaterialField::roughness:
            return type == MaterialType::conductor;
    }
    return false;
}

/// How the diffuse BSDF samples directions: cosine-weighted (default) or uniform over the
/// hemisphere (the naive baseline of `kdtrace bench converge`).
enum class DiffuseSampling : uint8_t { cosine, uniform };
inline constexpr std::array<const char*, 2> kDiffuseSamplingNames = {"cosine", "uniform"};

/// A compiled material: the fields of MaterialDesc the type uses, validated.
struct Material {
    MaterialType type = MaterialType::diffuse;
    Vec3f albedo{0.8f};
    float ior = 1.5f;
    Vec3f emission{0.0f};  ///< radiance emitted from both sides; any type may carry it
    float alpha = 0.2f;    ///< conductor GGX alpha, clamped to >= 1e-3
};

/// Converts a scene material; throws kdt::Error for non-finite or negative values.
Material compile_material(const MaterialDesc& desc);

/// True when the BSDF is a Dirac delta (no next-event estimation, no MIS).
inline bool is_delta(const Material& m) {
    return m.type == MaterialType::mirror || m.type == MaterialType::dielectric;
}
/// True when the material scatters no light at all (pure emitter).
inline bool is_black(const Material& m) { return m.type == MaterialType::emissive; }

/// A sampled incident direction. weight = f * |cos(wi)| / pdf (pdf omitted for deltas).
struct BsdfSample {
    Vec3f wi{0.0f, 0.0f, 1.0f};  ///< local frame, unit
    Vec3f weight{0.0f};
    float pdf_solid_angle = 0.0f;  ///< for deltas: the discrete probability of the lobe
    bool delta = false;
};

/// f(wo, wi) * |cos(wi)| in the local frame (0 for delta BSDFs and for wrong hemispheres).
Vec3f bsdf_eval(const Material& m, const Vec3f& wo, const Vec3f& wi,
                DiffuseSampling diffuse = DiffuseSampling::cosine);
/// Solid-angle pdf of bsdf_sample() producing wi (0 for delta BSDFs).
float bsdf_pdf(const Material& m, const Vec3f& wo, const Vec3f& wi,
               DiffuseSampling diffuse = DiffuseSampling::cosine);
/// Samples wi given wo; u2 picks the direction, u1 the lobe (dielectric). Returns false
/// when the material absorbs (black, or the sample falls below the surface).
bool bsdf_sample(const Material& m, const Vec3f& wo, const Vec2f& u2, float u1, BsdfSample& out,
                 DiffuseSampling diffuse = DiffuseSampling::cosine);

/// Unpolarised Fresnel reflectance of a smooth dielectric; cos_i >= 0 on the incident
/// side, eta = n_transmitted / n_incident. Returns 1 for total internal reflection.
float fresnel_dielectric(float cos_i, float eta);

/// Orthonormal basis with n as third axis (Duff et al. 2017, branchless).
void make_basis(const Vec3f& n, Vec3f& t, Vec3f& b);
/// Cosine-weighted direction on the +z hemisphere (Malley's method, concentric disk).
Vec3f sample_cosine_hemisphere(const Vec2f& u);
/// Uniform direction on the +z hemisphere.
Vec3f sample_uniform_hemisphere(const Vec2f& u);
/// Uniform direction on the unit sphere.
Vec3f sample_uniform_sphere(const Vec2f& u);

}  // namespace kdt
