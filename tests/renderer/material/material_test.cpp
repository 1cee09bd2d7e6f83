#include "renderer/material/material.h"

#include <cmath>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/core/sampler.h"

namespace kdt {
namespace {

Material make(MaterialType type, Vec3f albedo = Vec3f(1.0f), float roughness = 0.3f) {
    MaterialDesc d;
    d.type = type;
    d.albedo = albedo;
    d.roughness = roughness;
    return compile_material(d);
}

Vec3f dir_from_angles(float theta, float phi) {
    return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

// Integral over the sphere of pdf, by uniform sphere sampling.
double integrate_pdf(const Material& m, const Vec3f& wo, DiffuseSampling ds) {
    Pcg32 rng(5);
    const int n = 200000;
    double sum = 0.0;
    for (int i = 0; i < n; ++i) {
        const Vec3f wi = sample_uniform_sphere({rng.next_float(), rng.next_float()});
        sum += bsdf_pdf(m, wo, wi, ds) * 4.0 * kPi;
    }
    return sum / n;
}

TEST(Material, PdfsIntegrateToOne) {
    const Vec3f wo = dir_from_angles(0.6f, 0.3f);
    EXPECT_NEAR(integrate_pdf(make(MaterialType::diffuse), wo, DiffuseSampling::cosine), 1.0, 0.01);
    EXPECT_NEAR(integrate_pdf(make(MaterialType::diffuse), wo, DiffuseSampling::uniform), 1.0,
                0.01);
    // The GGX pdf loses the mass of reflections below the horizon; rough alpha, near normal.
    const double g = integrate_pdf(make(MaterialType::conductor, Vec3f(1.0f), 0.3f), wo,
                                   DiffuseSampling::cosine);
    EXPECT_GT(g, 0.85);
    EXPECT_LT(g, 1.01);
}

TEST(Material, SampleWeightsMatchEvalOverPdf) {
    for (MaterialType t : {MaterialType::diffuse, MaterialType::conductor}) {
        for (DiffuseSampling ds : {DiffuseSampling::cosine, DiffuseSampling::uniform}) {
            const Material m = make(t, Vec3f(0.7f, 0.5f, 0.3f));
            const Vec3f wo = dir_from_angles(0.8f, 1.0f);
            Pcg32 rng(9);
            for (int i = 0; i < 1000; ++i) {
                BsdfSample s;
                if (!bsdf_sample(m, wo, {rng.next_float(), rng.next_float()}, rng.next_float(), s,
                                 ds))
                    continue;
                const float pdf = bsdf_pdf(m, wo, s.wi, ds);
                ASSERT_GT(pdf, 0.0f);
                EXPECT_NEAR(pdf, s.pdf_solid_angle, 1e-3f * pdf);
                const Vec3f f = bsdf_eval(m, wo, s.wi, ds);
                EXPECT_NEAR(f.x / pdf, s.weight.x, 1e-3f * (1.0f + s.weight.x));
            }
        }
    }
}

TEST(Material, DiffuseAlbedoIsPreserved) {
    // Directional albedo of a Lambertian surface is exactly its albedo for both samplers.
    const Material m = make(MaterialType::diffuse, Vec3f(0.6f));
    const Vec3f wo = dir_from_angles(1.2f, 0.0f);
    for (DiffuseSampling ds : {DiffuseSampling::cosine, DiffuseSampling::uniform}) {
        double sum = 0.0;
        const int n = 4096;
        for (int i = 0; i < n; ++i) {
            BsdfSample s;
            ASSERT_TRUE(bsdf_sample(m, wo, sobol_2d(uint32_t(i), 77), 0.5f, s, ds));
            sum += s.weight.x;
        }
        EXPECT_NEAR(sum / n, 0.6, ds == DiffuseSampling::cosine ? 1e-5 : 5e-3);
    }
}

TEST(Material, MirrorReflectsExactly) {
    const Material m = make(MaterialType::mirror, Vec3f(0.9f));
    const Vec3f wo = glm::normalize(Vec3f(0.3f, -0.2f, 0.8f));
    BsdfSample s;
    ASSERT_TRUE(bsdf_sample(m, wo, {0.1f, 0.2f}, 0.3f, s));
    EXPECT_TRUE(s.delta);
    EXPECT_FLOAT_EQ(s.wi.x, -wo.x);
    EXPECT_FLOAT_EQ(s.wi.y, -wo.y);
    EXPECT_FLOAT_EQ(s.wi.z, wo.z);
    EXPECT_EQ(s.weight, Vec3f(0.9f));
    EXPECT_EQ(bsdf_eval(m, wo, s.wi), Vec3f(0.0f));
}

TEST(Material, DielectricFresnelAndSnell) {
    EXPECT_NEAR(fresnel_dielectric(1.0f, 1.5f), 0.04f, 1e-6f);
    EXPECT_FLOAT_EQ(fresnel_dielectric(0.1f, 1.0f / 1.5f), 1.0f);  // total internal reflection
    const Material m = make(MaterialType::dielectric);
    const float theta = 0.5f;
    const Vec3f wo = dir_from_angles(theta, 0.0f);
    BsdfSample s;
    ASSERT_TRUE(bsdf_sample(m, wo, {0.5f, 0.5f}, 0.99f, s));  // u1 above F: refraction
    EXPECT_LT(s.wi.z, 0.0f);
    const float sin_t = std::sqrt(1.0f - s.wi.z * s.wi.z);
    EXPECT_NEAR(std::sin(theta), 1.5f * sin_t, 1e-5f);
    EXPECT_NEAR(s.weight.x, 1.0f / (1.5f * 1.5f), 1e-6f);
    ASSERT_TRUE(bsdf_sample(m, wo, {0.5f, 0.5f}, 0.0f, s));  // reflection
    EXPECT_GT(s.wi.z, 0.0f);
    // From inside, the refracted direction leaves upwards.
    const Vec3f wo_inside(std::sin(0.3f), 0.0f, -std::cos(0.3f));
    ASSERT_TRUE(bsdf_sample(m, wo_inside, {0.5f, 0.5f}, 0.99f, s));
    EXPECT_GT(s.wi.z, 0.0f);
}

TEST(Material, RejectsBadValues) {
    MaterialDesc d;
    d.albedo = Vec3f(-1.0f);
    EXPECT_THROW(compile_material(d), Error);
    d = MaterialDesc{};
    d.type = MaterialType::dielectric;
    d.ior = std::nanf("");
    EXPECT_THROW(compile_material(d), Error);
}

TEST(Material, SamplingHelpersStayOnTheirDomain) {
    Pcg32 rng(3);
    for (int i = 0; i < 1000; ++i) {
        const Vec2f u(rng.next_float(), rng.next_float());
        EXPECT_NEAR(glm::length(sample_cosine_hemisphere(u)), 1.0f, 1e-5f);
        EXPECT_GE(sample_cosine_hemisphere(u).z, 0.0f);
        EXPECT_NEAR(glm::length(sample_uniform_sphere(u)), 1.0f, 1e-5f);
        Vec3f n = sample_uniform_sphere(u), t, b;
        make_basis(n, t, b);
        EXPECT_NEAR(glm::dot(t, n), 0.0f, 1e-5f);
        EXPECT_NEAR(glm::dot(b, n), 0.0f, 1e-5f);
        EXPECT_NEAR(glm::dot(t, b), 0.0f, 1e-5f);
    }
}

}  // namespace
}  // namespace kdt
