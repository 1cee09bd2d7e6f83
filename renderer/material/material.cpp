#include "renderer/material/material.h"

#include <cmath>
#include <string>

#include "renderer/core/error.h"

namespace kdt {

namespace {

bool valid_color(const Vec3f& c) {
    return is_finite(c) && c.x >= 0.0f && c.y >= 0.0f && c.z >= 0.0f;
}

// GGX (Trowbridge-Reitz) normal distribution, isotropic (Walter et al. 2007, eq. 33).
float ggx_d(float cos_m, float alpha) {
    if (cos_m <= 0.0f) return 0.0f;
    const float a2 = alpha * alpha;
    const float c2 = cos_m * cos_m;
    const float d = c2 * (a2 - 1.0f) + 1.0f;
    return a2 / (kPi * d * d);
}

// Smith masking for GGX (Walter et al. 2007, eq. 34).
float ggx_g1(float cos_v, float alpha) {
    const float c2 = cos_v * cos_v;
    if (c2 <= 0.0f) return 0.0f;
    const float tan2 = (1.0f - c2) / c2;
    return 2.0f / (1.0f + std::sqrt(1.0f + alpha * alpha * tan2));
}

Vec3f schlick(const Vec3f& f0, float cos_i) {
    const float m = glm::clamp(1.0f - cos_i, 0.0f, 1.0f);
    const float m5 = m * m * m * m * m;
    return f0 + (Vec3f(1.0f) - f0) * m5;
}

Vec3f reflect_local(const Vec3f& wo) { return {-wo.x, -wo.y, wo.z}; }

}  // namespace

Material compile_material(const MaterialDesc& desc) {
    const char* type = kMaterialTypeNames[size_t(desc.type)];
    if (!valid_color(desc.albedo)) {
        throw Error(std::string("material ") + type + ": albedo must be finite and >= 0");
    }
    if (!valid_color(desc.emission)) {
        throw Error(std::string("material ") + type + ": emission must be finite and >= 0");
    }
    if (desc.type == MaterialType::dielectric && !(desc.ior > 0.0f && std::isfinite(desc.ior))) {
        throw Error("material dielectric: ior must be finite and > 0 (got " +
                    std::to_string(desc.ior) + ")");
    }
    if (desc.type == MaterialType::conductor &&
        !(desc.roughness >= 0.0f && std::isfinite(desc.roughness))) {
        throw Error("material conductor: roughness must be finite and >= 0");
    }
    Material m;
    m.type = desc.type;
    m.albedo = desc.albedo;
    m.ior = desc.ior;
    m.emission = desc.type == MaterialType::emissive ? desc.emission : Vec3f(0.0f);
    m.alpha = std::max(desc.roughness, 1e-3f);
    return m;
}

void make_basis(const Vec3f& n, Vec3f& t, Vec3f& b) {
    const float sign = std::copysign(1.0f, n.z);
    const float a = -1.0f / (sign + n.z);
    const float c = n.x * n.y * a;
    t = Vec3f(1.0f + sign * n.x * n.x * a, sign * c, -sign * n.x);
    b = Vec3f(c, sign + n.y * n.y * a, -n.y);
}

Vec3f sample_cosine_hemisphere(const Vec2f& u) {
    // Concentric disk mapping (Shirley & Chiu 1997), lifted to the hemisphere.
    const float sx = 2.0f * u.x - 1.0f, sy = 2.0f * u.y - 1.0f;
    if (sx == 0.0f && sy == 0.0f) return {0.0f, 0.0f, 1.0f};
    float r, phi;
    if (std::abs(sx) > std::abs(sy)) {
        r = sx;
        phi = 0.25f * kPi * (sy / sx);
    } else {
        r = sy;
        phi = 0.5f * kPi - 0.25f * kPi * (sx / sy);
    }
    const float x = r * std::cos(phi), y = r * std::sin(phi);
    return {x, y, std::sqrt(std::max(0.0f, 1.0f - x * x - y * y))};
}

Vec3f sample_uniform_hemisphere(const Vec2f& u) {
    const float z = u.x;
    const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
    const float phi = 2.0f * kPi * u.y;
    return {r * std::cos(phi), r * std::sin(phi), z};
}

Vec3f sample_uniform_sphere(const Vec2f& u) {
    const float z = 1.0f - 2.0f * u.x;
    const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
    const float phi = 2.0f * kPi * u.y;
    return {r * std::cos(phi), r * std::sin(phi), z};
}

float fresnel_dielectric(float cos_i, float eta) {
    cos_i = glm::clamp(cos_i, 0.0f, 1.0f);
    const float sin2_t = (1.0f - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.0f) return 1.0f;
    const float cos_t = std::sqrt(1.0f - sin2_t);
    const float r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    const float r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    return 0.5f * (r_par * r_par + r_perp * r_perp);
}

Vec3f bsdf_eval(const Material& m, const Vec3f& wo, const Vec3f& wi, DiffuseSampling) {
    switch (m.type) {
        case MaterialType::diffuse:
            if (wo.z <= 0.0f || wi.z <= 0.0f) return Vec3f(0.0f);
            return m.albedo * (kInvPi * wi.z);
        case MaterialType::conductor: {
            if (wo.z <= 0.0f || wi.z <= 0.0f) return Vec3f(0.0f);
            Vec3f h = wo + wi;
            const float len = glm::length(h);
            if (!(len > 0.0f)) return Vec3f(0.0f);
            h /= len;
            const float d = ggx_d(h.z, m.alpha);
            const float g = ggx_g1(wo.z, m.alpha) * ggx_g1(wi.z, m.alpha);
            const Vec3f f = schlick(m.albedo, glm::dot(wi, h));
            return f * (d * g / (4.0f * wo.z));
        }
        default:
            return Vec3f(0.0f);
    }
}

float bsdf_pdf(const Material& m, const Vec3f& wo, const Vec3f& wi, DiffuseSampling diffuse) {
    switch (m.type) {
        case MaterialType::diffuse:
            if (wo.z <= 0.0f || wi.z <= 0.0f) return 0.0f;
            return diffuse == DiffuseSampling::uniform ? 0.5f * kInvPi : wi.z * kInvPi;
        case MaterialType::conductor: {
            if (wo.z <= 0.0f || wi.z <= 0.0f) return 0.0f;
            Vec3f h = wo + wi;
            const float len = glm::length(h);
            if (!(len > 0.0f)) return 0.0f;
            h /= len;
            const float cos_oh = glm::dot(wo, h);
            if (cos_oh <= 0.0f) return 0.0f;
            // Walter et al. 2007: pdf(m) = D(m) cos(m), Jacobian 1 / (4 |wo.m|).
            return ggx_d(h.z, m.alpha) * h.z / (4.0f * cos_oh);
        }
        default:
            return 0.0f;
    }
}

bool bsdf_sample(const Material& m, const Vec3f& wo, const Vec2f& u2, float u1, BsdfSample& out,
                 DiffuseSampling diffuse) {
    switch (m.type) {
        case MaterialType::diffuse: {
            if (wo.z <= 0.0f) return false;
            if (diffuse == DiffuseSampling::uniform) {
                out.wi = sample_uniform_hemisphere(u2);
                out.pdf_solid_angle = 0.5f * kInvPi;
                out.weight = m.albedo * (2.0f * out.wi.z);
            } else {
                out.wi = sample_cosine_hemisphere(u2);
                out.pdf_solid_angle = out.wi.z * kInvPi;
                out.weight = m.albedo;
            }
            out.delta = false;
            return out.wi.z > 0.0f;
        }
        case MaterialType::mirror:
            if (wo.z <= 0.0f) return false;
            out.wi = reflect_local(wo);
            out.weight = m.albedo;
            out.pdf_solid_angle = 1.0f;
            out.delta = true;
            return true;
        case MaterialType::dielectric: {
            const bool entering = wo.z > 0.0f;
            const float eta = entering ? m.ior : 1.0f / m.ior;  // n_t / n_i
            const float cos_o = std::abs(wo.z);
            const float f = fresnel_dielectric(cos_o, eta);
            out.delta = true;
            if (u1 < f) {
                out.wi = reflect_local(wo);
                out.weight = Vec3f(1.0f);
                out.pdf_solid_angle = f;
                return true;
            }
            // Refraction (Snell); radiance is scaled by 1 / eta^2 (Veach 1997, sec. 5.2).
            const float sin2_t = (1.0f - cos_o * cos_o) / (eta * eta);
            const float cos_t = std::sqrt(std::max(0.0f, 1.0f - sin2_t));
            const Vec3f wt = Vec3f(-wo.x / eta, -wo.y / eta, entering ? -cos_t : cos_t);
            out.wi = glm::normalize(wt);
            out.weight = Vec3f(1.0f / (eta * eta));
            out.pdf_solid_angle = 1.0f - f;
            return true;
        }
        case MaterialType::conductor: {
            if (wo.z <= 0.0f) return false;
            // Sample the GGX normal distribution D(m) cos(m) (Walter et al. 2007, eq. 35).
            const float a2 = m.alpha * m.alpha;
            const float cos2 = (1.0f - u2.x) / (1.0f + (a2 - 1.0f) * u2.x);
            const float cos_m = std::sqrt(std::max(0.0f, cos2));
            const float sin_m = std::sqrt(std::max(0.0f, 1.0f - cos2));
            const float phi = 2.0f * kPi * u2.y;
            const Vec3f h(sin_m * std::cos(phi), sin_m * std::sin(phi), cos_m);
            const float cos_oh = glm::dot(wo, h);
            if (cos_oh <= 0.0f) return false;
            out.wi = 2.0f * cos_oh * h - wo;
            if (out.wi.z <= 0.0f) return false;
            out.pdf_solid_angle = bsdf_pdf(m, wo, out.wi, diffuse);
            if (!(out.pdf_solid_angle > 0.0f)) return false;
            out.weight = bsdf_eval(m, wo, out.wi, diffuse) / out.pdf_solid_angle;
            out.delta = false;
            return true;
        }
        case MaterialType::emissive:
        default:
            return false;
    }
}

}  // namespace kdt
