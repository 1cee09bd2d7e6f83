// Tests of renderer/light/environment.*: the constant light, pdfs that integrate to one,
// sample() agreeing with pdf() and eval(), importance vs uniform sampling on the Grace
// Cathedral probe (statistical, fixed seeds), and bad input.
#include "renderer/light/environment.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <functional>
#include <utility>

#include <gtest/gtest.h>

#include "renderer/material/material.h"

#include "renderer/core/error.h"
#include "renderer/io/image_io.h"
#include "renderer/light/image_environment.h"
#include "renderer/light/mapping.h"
#include "tests/renderer/io/exr_variants.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

using test::HashRng;

/// Running mean and standard error.
struct Stat {
    double sum = 0.0, sum2 = 0.0;
    uint64_t n = 0;
    void add(double x) {
        sum += x;
        sum2 += x * x;
        ++n;
    }
    double mean() const { return sum / double(n); }
    double std_error() const {
        double m = mean();
        return std::sqrt(std::max(0.0, sum2 / double(n) - m * m) / double(n));
    }
};

/// A test map: a smooth strictly positive sky plus a small bright "sun" and a black band.
ImageRGB test_latlong(int w, int h, bool with_zeros) {
    ImageRGB img(w, h);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            Vec3f d = latlong_dir_from_uv({(x + 0.5f) / w, (y + 0.5f) / h});
            Vec3f c(0.2f + 0.1f * d.y, 0.3f + 0.1f * d.x, 0.25f);
            if (glm::dot(d, glm::normalize(Vec3f(0.3f, 0.8f, -0.5f))) > 0.97f)
                c = Vec3f(300, 250, 200);
            if (with_zeros && y > h * 5 / 8 && y < h * 6 / 8) c = Vec3f(0.0f);
            img.set(x, y, c);
        }
    }
    return img;
}

TEST(Environment, ConstantColour) {
    EnvironmentDesc desc;
    desc.color = Vec3f(0.5f, 1.0f, 2.0f);
    desc.intensity = 2.0f;
    auto env = make_environment_light(desc);
    EXPECT_TRUE(env->is_constant());
    EXPECT_EQ(env->eval(Vec3f(0, 1, 0)), Vec3f(1.0f, 2.0f, 4.0f));
    EXPECT_FLOAT_EQ(env->pdf(Vec3f(1, 0, 0)), 1.0f / (4.0f * kPi));
    HashRng rng(1);
    Vec3d mean(0.0);
    const int n = 100000;
    for (int i = 0; i < n; ++i) {
        EnvSample s = env->sample(rng.next2());
        ASSERT_NEAR(glm::length(s.dir), 1.0f, 1e-5f);
        ASSERT_FLOAT_EQ(s.pdf_solid_angle, 1.0f / (4.0f * kPi));
        ASSERT_EQ(s.radiance, Vec3f(1.0f, 2.0f, 4.0f));
        mean += Vec3d(s.dir);
    }
    mean /= double(n);
    // Uniform on the sphere: each coordinate has mean 0 and variance 1/3.
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean[c], 0.0, 5.0 * std::sqrt(1.0 / 3.0 / n));
}

class MapTest : public ::testing::TestWithParam<EnvMapping> {
protected:
    /// cells: as ImageEnvironment's cells_per_pixel (negative: a cell per -cells pixels).
    ImageEnvironment make(bool with_zeros, float rotation = 30.0f, int cells = 0) const {
        ImageRGB ll = test_latlong(128, 64, with_zeros);
        if (GetParam() == EnvMapping::latlong) {
            return ImageEnvironment(ll, EnvMapping::latlong, rotation, 1.5f, "", cells);
        }
        return ImageEnvironment(latlong_to_angular(ll, 96, 2), EnvMapping::angular, rotation, 1.5f,
                                "", cells);
    }
};

TEST_P(MapTest, PdfIntegratesToOneOverTheSphere) {
    ImageEnvironment env = make(true);
    HashRng rng(2);
    Stat s;
    for (int i = 0; i < 400000; ++i)
        s.add(4.0 * M_PI * env.pdf(sample_uniform_sphere(rng.next2())));
    EXPECT_NEAR(s.mean(), 1.0, 4.0 * s.std_error() + 1e-3) << "se " << s.std_error();

    // Exact: the density table integrates to one over the image (weighted by coverage).
    double sum = 0.0;
    const ImageRGB& img = env.image();
    const int sub = env.sampling_cells_per_pixel();
    EXPECT_EQ(sub, 8);
    for (int y = 0; y < img.height * sub; ++y) {
        for (int x = 0; x < img.width * sub; ++x) sum += env.density_uv(x, y) * env.coverage(x, y);
    }
    EXPECT_NEAR(sum / double(img.pixel_count() * size_t(sub * sub)), 1.0, 1e-5);
}

TEST_P(MapTest, SampleAgreesWithPdfAndEval) {
    ImageEnvironment env = make(true);
    HashRng rng(3);
    int zero_pdf = 0, black = 0;
    const int n = 50000;
    for (int i = 0; i < n; ++i) {
        EnvSample s = env.sample(rng.next2());
        if (s.pdf_solid_angle == 0.0f) {
            ++zero_pdf;
            continue;
        }
        ASSERT_NEAR(glm::length(s.dir), 1.0f, 1e-5f);
        ASSERT_FLOAT_EQ(env.pdf(s.dir), s.pdf_solid_angle);
        ASSERT_EQ(env.eval(s.dir), s.radiance);
        black += luminance(s.radiance) > 0.0f ? 0 : 1;
    }
    EXPECT_LE(zero_pdf, 2);  // only float rounding at a cell edge next to a black cell
    // Each sampling cell lies inside one bilinear patch, so none is partly black: samples
    // land where eval() is positive, up to float rounding at the black band's edges.
    EXPECT_LE(black, 2);
}

TEST_P(MapTest, SamplesFollowThePdf) {
    // With a strictly positive map the support is the whole sphere, so for any region R,
    // E[1_R(d) / pdf(d)] over sampled d equals the solid angle of R. Regions: the octants.
    ImageEnvironment env = make(false, -71.0f);
    HashRng rng(4);
    Stat octant[8];
    const int n = 400000;
    for (int i = 0; i < n; ++i) {
        EnvSample s = env.sample(rng.next2());
        ASSERT_GT(s.pdf_solid_angle, 0.0f);
        int o = (s.dir.x > 0) + 2 * (s.dir.y > 0) + 4 * (s.dir.z > 0);
        for (int k = 0; k < 8; ++k) octant[k].add(k == o ? 1.0 / s.pdf_solid_angle : 0.0);
    }
    for (int k = 0; k < 8; ++k) {
        EXPECT_NEAR(octant[k].mean(), M_PI / 2, 4.0 * octant[k].std_error() + 2e-3)
            << "octant " << k << " se " << octant[k].std_error();
    }
}

// The grid of maps above 8192 x 4096 pixels, a cell per T x T pixels (T = 3: cell edges off
// pixel edges), on the small test map: sample() agrees with pdf() and eval(), the density
// table integrates to one, every direction where the map is positive has a positive pdf,
// and E[1_R / pdf] is the solid angle of each octant.
TEST_P(MapTest, CellsOfSeveralPixelsSampleExactly) {
    for (const int t : {2, 3}) {
        const ImageEnvironment env = make(true, 30.0f, -t);
        ASSERT_EQ(env.sampling_pixels_per_cell(), t);
        double sum = 0.0;
        const int gw = env.sampling_grid_width(), gh = env.sampling_grid_height();
        for (int y = 0; y < gh; ++y) {
            for (int x = 0; x < gw; ++x) sum += env.density_uv(x, y) * env.coverage(x, y);
        }
        EXPECT_NEAR(sum / (double(gw) * gh), 1.0, 1e-5) << t;
        HashRng rng(uint32_t(20 + t));
        for (int i = 0; i < 20000; ++i) {
            const EnvSample s = env.sample(rng.next2());
            if (s.pdf_solid_angle == 0.0f) continue;
            ASSERT_FLOAT_EQ(env.pdf(s.dir), s.pdf_solid_angle) << t;
            ASSERT_EQ(env.eval(s.dir), s.radiance) << t;
        }
        int uncovered = 0, positive = 0;
        for (int i = 0; i < 200000; ++i) {
            const Vec3f d = sample_uniform_sphere(rng.next2());
            if (!(luminance(env.eval(d)) > 0.0f)) continue;
            ++positive;
            uncovered += env.pdf(d) > 0.0f ? 0 : 1;
        }
        EXPECT_GT(positive, 100000) << t;
        EXPECT_EQ(uncovered, 0) << t;
        const ImageEnvironment full = make(false, -71.0f, -t);
        Stat octant[8];
        for (int i = 0; i < 200000; ++i) {
            const EnvSample s = full.sample(rng.next2());
            ASSERT_GT(s.pdf_solid_angle, 0.0f);
            const int o = (s.dir.x > 0) + 2 * (s.dir.y > 0) + 4 * (s.dir.z > 0);
            for (int k = 0; k < 8; ++k) octant[k].add(k == o ? 1.0 / s.pdf_solid_angle : 0.0);
        }
        for (int k = 0; k < 8; ++k) {
            EXPECT_NEAR(octant[k].mean(), M_PI / 2, 4.0 * octant[k].std_error() + 2e-3)
                << "T " << t << " octant " << k;
        }
    }
}

INSTANTIATE_TEST_SUITE_P(Mappings, MapTest,
                         ::testing::Values(EnvMapping::latlong, EnvMapping::angular),
                         [](const ::testing::TestParamInfo<EnvMapping>& param_info) {
                             return std::string(kEnvMappingNames[size_t(param_info.param)]);
                         });

TEST(Environment, AngularRimPixelsAreSampledExactly) {
    // Only a ring near the rim (-z) is lit, so pixels cut by the unit circle carry much of
    // the power: E[1/pdf] must equal the solid angle of the lit part of the disk.
    const int size = 48;
    ImageRGB img(size, size);
    for (int y = 0; y < size; ++y) {
        for (int x = 0; x < size; ++x) {
            float a = 2.0f * (x + 0.5f) / size - 1.0f, b = 1.0f - 2.0f * (y + 0.5f) / size;
            if (a * a + b * b > 0.8f * 0.8f) img.set(x, y, Vec3f(1.0f + 0.5f * a, 1.0f, 1.0f));
        }
    }
    ImageEnvironment env(img, EnvMapping::angular, 0.0f, 1.0f);
    // Reference: the solid angle where eval() is positive, by a fine midpoint rule with the
    // Jacobian (the support of the pdf: no point of it is missed, none is added).
    const int sub = 64;
    double omega = 0.0;
    for (int y = 0; y < size; ++y) {
        for (int x = 0; x < size; ++x) {
            for (int sy = 0; sy < sub; ++sy) {
                for (int sx = 0; sx < sub; ++sx) {
                    Vec2f uv((x + (sx + 0.5f) / sub) / size, (y + (sy + 0.5f) / sub) / size);
                    auto d = angular_dir_from_uv(uv);
                    if (d && luminance(env.eval(*d)) > 0.0f) omega += angular_jacobian(*d);
                }
            }
        }
    }
    omega /= double(size) * size * sub * sub;
    HashRng rng(5);
    Stat s;
    for (int i = 0; i < 400000; ++i) {
        EnvSample e = env.sample(rng.next2());
        s.add(e.pdf_solid_angle > 0.0f ? 1.0 / e.pdf_solid_angle : 0.0);
    }
    EXPECT_NEAR(s.mean(), omega, 4.0 * s.std_error() + 2e-3 * omega)
        << "se " << s.std_error() << " omega " << omega;
}

TEST(Environment, BlackMapHasZeroPdf) {
    ImageEnvironment env(ImageRGB(16, 8), EnvMapping::latlong, 0.0f, 1.0f);
    EnvSample s = env.sample({0.3f, 0.7f});
    EXPECT_EQ(s.pdf_solid_angle, 0.0f);
    EXPECT_EQ(s.radiance, Vec3f(0.0f));
    EXPECT_EQ(env.pdf(Vec3f(0, 1, 0)), 0.0f);
}

// Estimates of the total power (integral of luminance over the sphere) and the irradiance
// about a few normals, importance-sampled and uniformly sampled, against each other and a
// deterministic quadrature; on the Grace Cathedral probe (tiny bright windows).
struct Estimates {
    std::vector<Stat> is, uni;
};

void compare_on_probe(const ImageEnvironment& env, const std::string& label, double ref_tol) {
    const std::vector<Vec3f> normals = {Vec3f(0, 1, 0), Vec3f(0, -1, 0), Vec3f(1, 0, 0),
                                        glm::normalize(Vec3f(1, 1, 1)), Vec3f(0, 0, -1)};
    const size_t k = normals.size() + 1;  // [0] = power, then irradiance per normal
    auto integrand = [&](const Vec3f& d, double l, size_t j) {
        return j == 0 ? l : l * std::max(0.0f, glm::dot(normals[j - 1], d));
    };
    // Reference: midpoint rule on a sub-pixel grid of the image.
    const ImageRGB& img = env.image();
    const int sub = img.width >= 512 ? 2 : 6;
    std::vector<double> ref(k, 0.0);
    for (int y = 0; y < img.height * sub; ++y) {
        for (int x = 0; x < img.width * sub; ++x) {
            Vec2f uv((x + 0.5f) / (img.width * sub), (y + 0.5f) / (img.height * sub));
            auto d = env.dir_from_uv(uv);
            if (!d) continue;
            Vec3f map_dir = *env_dir_from_uv(env.mapping(), uv);
            double w =
                env_jacobian(env.mapping(), map_dir) / (double(img.width) * img.height * sub * sub);
            double l = luminance(env.eval(*d));
            for (size_t j = 0; j < k; ++j) ref[j] += integrand(*d, l, j) * w;
        }
    }
    std::vector<Stat> is(k), uni(k);
    HashRng rng_is(42), rng_u(43);
    for (int i = 0; i < (1 << 16); ++i) {
        EnvSample s = env.sample(rng_is.next2());
        double l = luminance(s.radiance);
        for (size_t j = 0; j < k; ++j) {
            is[j].add(s.pdf_solid_angle > 0.0f ? integrand(s.dir, l, j) / s.pdf_solid_angle : 0.0);
        }
    }
    for (int i = 0; i < (1 << 20); ++i) {
        Vec3f d = sample_uniform_sphere(rng_u.next2());
        double l = luminance(env.eval(d));
        for (size_t j = 0; j < k; ++j) uni[j].add(4.0 * M_PI * integrand(d, l, j));
    }
    for (size_t j = 0; j < k; ++j) {
        std::string what = j == 0 ? "power"
                                  : "irradiance n=(" + std::to_string(normals[j - 1].x) + "," +
                                        std::to_string(normals[j - 1].y) + "," +
                                        std::to_string(normals[j - 1].z) + ")";
        std::printf("[%s] %-42s ref %.5f | IS 2^16: %.5f +- %.5f | uniform 2^20: %.5f +- %.5f\n",
                    label.c_str(), what.c_str(), ref[j], is[j].mean(), is[j].std_error(),
                    uni[j].mean(), uni[j].std_error());
        double se = std::sqrt(is[j].std_error() * is[j].std_error() +
                              uni[j].std_error() * uni[j].std_error());
        EXPECT_NEAR(is[j].mean(), uni[j].mean(), 4.0 * se) << label << " " << what;
        EXPECT_NEAR(is[j].mean(), ref[j], 4.0 * is[j].std_error() + ref_tol * ref[j]) << what;
        EXPECT_NEAR(uni[j].mean(), ref[j], 4.0 * uni[j].std_error() + ref_tol * ref[j]) << what;
    }
    // Importance sampling must pay off on this probe: per-sample variance of the power
    // estimate far below uniform sampling's.
    double var_is = is[0].std_error() * is[0].std_error() * double(is[0].n);
    double var_u = uni[0].std_error() * uni[0].std_error() * double(uni[0].n);
    EXPECT_LT(var_is, 0.01 * var_u) << label;
}

TEST(Environment, ImportanceAndUniformSamplingAgreeOnGrace) {
    const auto grace = test::grace_probe();
    if (grace.empty()) GTEST_SKIP() << test::kNoGraceProbe;
    EnvironmentDesc desc;
    desc.file = grace.string();
    desc.rotation_degrees = 123.0f;
    auto light = make_environment_light(desc);
    auto* env = dynamic_cast<const ImageEnvironment*>(light.get());
    ASSERT_NE(env, nullptr);
    EXPECT_EQ(env->image().width, 256);
    EXPECT_EQ(env->image().height, 128);
    compare_on_probe(*env, "grace latlong", 1e-3);

    // The same probe converted to an angular map with our own conversion.
    ImageEnvironment ang(latlong_to_angular(env->image(), 512, 2), EnvMapping::angular, 45.0f,
                         1.0f);
    compare_on_probe(ang, "grace angular", 3e-3);
}

/// Nearest-pixel radiance of a map at image coordinates uv (what eval() returned before the
/// lookup became bilinear).
Vec3f nearest_pixel(const ImageRGB& img, const Vec2f& uv) {
    return img.at(std::clamp(int(uv.x * float(img.width)), 0, img.width - 1),
                  std::clamp(int(uv.y * float(img.height)), 0, img.height - 1));
}

// Bilinear lookup must not change what a diffuse plane lit by the map receives: its
// irradiance estimated by importance sampling of the bilinear map (what the path tracer
// does at a diffuse hit) equals the nearest-pixel map's exact irradiance (a fine midpoint
// rule) within noise and the small blur of the interpolation; for a constant map it is
// pi L (analytic).
void expect_plane_irradiance_unchanged(const ImageEnvironment& env, const std::string& label) {
    const ImageRGB& img = env.image();
    const std::vector<Vec3f> normals = {Vec3f(0, 1, 0), glm::normalize(Vec3f(0.3f, 0.8f, -0.5f)),
                                        Vec3f(-1, 0, 0), Vec3f(0, -1, 0)};
    const int sub = 4;
    for (const Vec3f& n : normals) {
        double nearest = 0.0;
        for (int y = 0; y < img.height * sub; ++y) {
            for (int x = 0; x < img.width * sub; ++x) {
                Vec2f uv((x + 0.5f) / float(img.width * sub), (y + 0.5f) / float(img.height * sub));
                auto d = env.dir_from_uv(uv);
                if (!d) continue;
                const double cos = std::max(0.0f, glm::dot(n, *d));
                const double j = env_jacobian(env.mapping(), *env_dir_from_uv(env.mapping(), uv));
                nearest += luminance(nearest_pixel(img, uv)) * env.intensity() * cos * j;
            }
        }
        nearest /= double(img.width) * img.height * sub * sub;
        HashRng rng(77);
        Stat is;
        for (int i = 0; i < (1 << 17); ++i) {
            EnvSample s = env.sample(rng.next2());
            is.add(s.pdf_solid_angle > 0.0f
                       ? luminance(s.radiance) * std::max(0.0f, glm::dot(n, s.dir)) /
                             s.pdf_solid_angle
                       : 0.0);
        }
        std::printf("[%s] n=(%.2f,%.2f,%.2f) nearest-pixel %.5f | bilinear IS %.5f +- %.5f\n",
                    label.c_str(), n.x, n.y, n.z, nearest, is.mean(), is.std_error());
        EXPECT_NEAR(is.mean(), nearest, 4.0 * is.std_error() + 5e-3 * nearest) << label;
    }
}

TEST_P(MapTest, ProbeLitDiffusePlaneIsUnchangedByBilinearLookup) {
    expect_plane_irradiance_unchanged(make(true), kEnvMappingNames[size_t(GetParam())]);
    ImageRGB constant(32, GetParam() == EnvMapping::latlong ? 16 : 32);
    for (float& v : constant.rgb) v = 0.7f;
    ImageEnvironment env(constant, GetParam(), 10.0f, 2.0f);
    HashRng rng(78);
    Stat is;
    for (int i = 0; i < (1 << 16); ++i) {
        EnvSample s = env.sample(rng.next2());
        ASSERT_NEAR(luminance(s.radiance), 1.4f, 1e-5f);
        is.add(luminance(s.radiance) * std::max(0.0f, s.dir.y) / s.pdf_solid_angle);
    }
    EXPECT_NEAR(is.mean(), M_PI * 1.4, 4.0 * is.std_error() + 1e-4) << "pi L";
    const auto grace_file = test::grace_probe();
    if (GetParam() == EnvMapping::latlong && !grace_file.empty()) {
        ImageEnvironment grace(load_image(grace_file.string()), EnvMapping::latlong, 0.0f, 1.0f);
        expect_plane_irradiance_unchanged(grace, "grace");
    }
}

// The camera sees the map through eval(): along a line of directions, neighbouring
// lookups must differ by no more than the interpolation slope allows (a nearest-pixel
// lookup jumps by whole pixel differences at every pixel edge: the "texel blocks").
TEST_P(MapTest, LookupsAreContinuousAcrossPixels) {
    const int w = 16, h = GetParam() == EnvMapping::latlong ? 8 : 16;
    ImageRGB img(w, h);
    HashRng pixels(9);
    for (float& v : img.rgb) v = pixels.next();
    ImageEnvironment env(img, GetParam(), 0.0f, 1.0f);
    // Lines of directions: a circle of latitude through the lat-long seam, a great circle
    // through both poles, and one tilted circle.
    const Vec3f axes[] = {Vec3f(0, 1, 0), Vec3f(1, 0, 0), glm::normalize(Vec3f(0.2f, 0.9f, 0.4f))};
    const int steps = 20000;
    for (const Vec3f& axis : axes) {
        const Vec3f a = glm::normalize(glm::cross(axis, Vec3f(0.3f, -0.2f, 0.93f)));
        const Vec3f b = glm::cross(axis, a);
        const float tilt = 0.4f;  // the circle at 0.4 rad from the great circle
        float max_jump = 0.0f, nearest_jump = 0.0f;
        Vec3f prev(0.0f), prev_nearest(0.0f);
        for (int i = 0; i <= steps; ++i) {
            const float t = 2.0f * kPi * float(i) / float(steps);
            const Vec3f d = glm::normalize(std::cos(tilt) * (std::cos(t) * a + std::sin(t) * b) +
                                           std::sin(tilt) * axis);
            const Vec3f v = env.eval(d);
            const Vec3f v_nearest = nearest_pixel(img, env.uv_from_dir(d));
            if (i > 0) {
                for (int c = 0; c < 3; ++c) {
                    max_jump = std::max(max_jump, std::abs(v[c] - prev[c]));
                    nearest_jump = std::max(nearest_jump, std::abs(v_nearest[c] - prev_nearest[c]));
                }
            }
            prev = v;
            prev_nearest = v_nearest;
        }
        // A step of 2 pi / 20000 moves at most ~0.01 pixels away from the poles and the
        // angular rim (values differ by at most 1 between neighbours); the poles and the rim
        // (-z, where all of the rim is one direction) allow somewhat more.
        EXPECT_LT(max_jump, 0.05f) << "axis " << axis.x << "," << axis.y << "," << axis.z;
        EXPECT_GT(nearest_jump, 0.3f) << "the test map must show texel blocks without bilinear";
    }
}

// Rotations are taken modulo 360 before the trigonometry: whole turns give the lookups of 0
// bit for bit (720 differed from 0 by the float error of cos and sin of 4 pi), and a
// negative angle those of the same angle plus 360.
TEST_P(MapTest, WholeTurnsOfRotationAreExactlyNone) {
    const auto same = [&](float a, float b) {
        const ImageEnvironment ea = make(false, a), eb = make(false, b);
        HashRng rng(13);
        for (int i = 0; i < 2000; ++i) {
            const Vec2f u = rng.next2();
            const Vec3f d = sample_uniform_sphere(rng.next2());
            const EnvSample sa = ea.sample(u), sb = eb.sample(u);
            const Vec3f va = ea.eval(d), vb = eb.eval(d);
            const Vec2f uva = ea.uv_from_dir(d), uvb = eb.uv_from_dir(d);
            // Bitwise, and -0 apart from +0.
            if (std::memcmp(&va, &vb, sizeof va) != 0 || std::memcmp(&uva, &uvb, sizeof uva) != 0 ||
                std::memcmp(&sa.dir, &sb.dir, sizeof sa.dir) != 0 ||
                std::memcmp(&sa.radiance, &sb.radiance, sizeof sa.radiance) != 0 ||
                sa.pdf_solid_angle != sb.pdf_solid_angle || ea.pdf(d) != eb.pdf(d)) {
                ADD_FAILURE() << a << " and " << b << " degrees differ at lookup " << i;
                return;
            }
        }
    };
    same(720.0f, 0.0f);
    same(36000.0f, 0.0f);
    same(-360.0f, 0.0f);
    same(-36000.0f, 0.0f);
    same(-90.0f, 270.0f);
    same(390.0f, 30.0f);
    same(-0.5f, 359.5f);
}

/// The message of the kdt::Error that building the light throws ("" and a failure if none).
std::string env_error(const std::function<void()>& build) {
    try {
        build();
    } catch (const Error& e) {
        return e.what();
    }
    ADD_FAILURE() << "no error";
    return "";
}

// Issue 29: radiance that overflows, and negative or non-finite texels, are refused when
// the light is built, naming the file, the texel and the count (they rendered black with
// "non-finite dropped" or without a word).
TEST(Environment, OverflowingNegativeAndNonFiniteRadianceIsRefused) {
    auto dir = test::temp_dir("env_overflow");
    auto probe = [&](const std::string& name, float value, int bad_x = -1, float bad = 0.0f) {
        ImageRGB img(8, 4);
        for (float& v : img.rgb) v = value;
        if (bad_x >= 0) img.set(bad_x, 2, Vec3f(0.5f, bad, 0.5f));
        const std::string file = (dir / name).string();
        write_pfm(file, img);
        return file;
    };
    struct Case {
        std::string file;
        float intensity;
        const char* expect;
    } cases[] = {
        {probe("huge.pfm", 3.4e38f), 1.0f, "(x 0, y 0) has a channel 3.4e+38 times intensity 1"},
        {probe("big.pfm", 1e20f), 1e11f, "is radiance 1e+31, above the limit 1e+30"},
        {probe("one.pfm", 1.0f), 3e38f, "times intensity 3e+38 is radiance 3e+38"},
        {probe("minus.pfm", -1.0f), 1.0f,
         "(x 0, y 0) is negative (-1, -1, -1); 32 of 32 texels have a negative channel"},
        {probe("dip.pfm", 1.0f, 5, -1e-6f), 1.0f,
         "(x 5, y 2) is negative (0.5, -1e-06, 0.5); 1 of 32 texels"},
    };
    for (const Case& c : cases) {
        EnvironmentDesc desc;
        desc.file = c.file;
        desc.intensity = c.intensity;
        const std::string msg = env_error([&] { make_environment_light(desc); });
        EXPECT_EQ(msg.rfind(c.file + ": ", 0), 0u) << msg;
        EXPECT_NE(msg.find(c.expect), std::string::npos) << msg;
    }
    // Just inside the limit is accepted.
    EnvironmentDesc ok;
    ok.file = probe("limit.pfm", 1e15f);
    ok.intensity = 1e15f;
    EXPECT_NO_THROW(make_environment_light(ok));
    // NaN and infinite texels in memory (files with them are refused by the loader).
    for (float bad : {std::nanf(""), kInfinity}) {
        ImageRGB img(8, 4);
        img.set(6, 1, Vec3f(1.0f, bad, 1.0f));
        img.set(7, 3, Vec3f(bad));
        EnvironmentDesc desc;
        desc.file = "mem.exr";
        const std::string msg = env_error([&] { make_environment_light(desc, img); });
        EXPECT_NE(msg.find("mem.exr: pixel 14: (x 6, y 1) is " +
                           std::string(std::isnan(bad) ? "NaN" : "infinite") +
                           "; 2 of 32 texels are not finite"),
                  std::string::npos)
            << msg;
    }
    // A NaN texel in a file: the loader names it.
    ImageRGB nan_img(8, 4);
    nan_img.set(2, 3, Vec3f(std::nanf("")));
    const std::string nan_file = (dir / "nan.pfm").string();
    write_pfm(nan_file, nan_img);
    EnvironmentDesc nan_desc;
    nan_desc.file = nan_file;
    const std::string msg = env_error([&] { make_environment_light(nan_desc); });
    EXPECT_NE(msg.find("(x 2, y 3) channel R is NaN"), std::string::npos) << msg;
    // Constant colours: the colour times the intensity.
    for (auto [colour, intensity] :
         {std::pair{3e38f, 1.0f}, std::pair{1e20f, 1e20f}, std::pair{1.0f, 3e38f}}) {
        EnvironmentDesc desc;
        desc.color = Vec3f(0.5f, colour, 0.5f);
        desc.intensity = intensity;
        const std::string m = env_error([&] { make_environment_light(desc); });
        EXPECT_NE(m.find("environment colour channel"), std::string::npos) << m;
        EXPECT_NE(m.find("above the limit 1e+30"), std::string::npos) << m;
    }
    std::filesystem::remove_all(dir);
}

// Issue 29: `--env-mapping angular` on a 2:1 image warns (through the log callback) that
// it looks lat-long; a square lat-long map warns the other way; matching shapes are quiet.
TEST(Environment, MappingThatContradictsTheImageShapeWarns) {
    EXPECT_NE(
        environment_mapping_warning(EnvMapping::angular, 512, 256).find("looks like a lat-long"),
        std::string::npos);
    EXPECT_NE(
        environment_mapping_warning(EnvMapping::latlong, 64, 64).find("looks like an angular"),
        std::string::npos);
    EXPECT_EQ(environment_mapping_warning(EnvMapping::angular, 64, 64), "");
    EXPECT_EQ(environment_mapping_warning(EnvMapping::latlong, 512, 256), "");
    EXPECT_EQ(environment_mapping_warning(EnvMapping::angular, 300, 200), "");
    // Lat-long maps far from 2:1 either way warn as a square one does.
    for (const auto& [w, h] : {std::pair{1, 4096}, std::pair{16, 96}, std::pair{4096, 1},
                               std::pair{299, 200}, std::pair{501, 200}}) {
        EXPECT_NE(environment_mapping_warning(EnvMapping::latlong, w, h).find("far from 2:1"),
                  std::string::npos)
            << w << "x" << h;
    }
    for (const auto& [w, h] : {std::pair{300, 200}, std::pair{500, 200}, std::pair{2048, 1025}})
        EXPECT_EQ(environment_mapping_warning(EnvMapping::latlong, w, h), "") << w << "x" << h;

    auto dir = test::temp_dir("env_warn");
    ImageRGB img(16, 8);
    for (float& v : img.rgb) v = 1.0f;
    EnvironmentDesc desc;
    desc.file = (dir / "sky.pfm").string();
    write_pfm(desc.file, img);
    desc.mapping = EnvMapping::angular;
    std::vector<std::string> lines;
    auto light = make_environment_light(desc, [&](const std::string& l) { lines.push_back(l); });
    EXPECT_NE(light, nullptr);
    ASSERT_EQ(lines.size(), 1u);
    EXPECT_EQ(lines[0], "warning: " + desc.file +
                            ": mapping angular for a 16x8 image, which looks like a lat-long map "
                            "(2:1); angular maps are square");
    desc.mapping = EnvMapping::latlong;
    lines.clear();
    make_environment_light(desc, [&](const std::string& l) { lines.push_back(l); });
    EXPECT_TRUE(lines.empty());
    std::filesystem::remove_all(dir);
}

TEST(Environment, BadInputThrows) {
    EnvironmentDesc desc;
    desc.file = "/nonexistent/probe.hdr";
    try {
        make_environment_light(desc);
        FAIL() << "no exception";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("/nonexistent/probe.hdr"), std::string::npos);
    }

    auto dir = test::temp_dir("env_bad");
    desc.file = (dir / "broken.hdr").string();
    std::ofstream(desc.file, std::ios::binary)
        << "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 4 +X 4\nabc";
    EXPECT_THROW(make_environment_light(desc), Error);

    ImageRGB nan_img(4, 2);
    nan_img.set(3, 1, Vec3f(0.0f, std::nanf(""), 0.0f));
    desc.file = "in-memory";
    try {
        make_environment_light(desc, nan_img);
        FAIL() << "no exception";
    } catch (const Error& e) {
        EXPECT_EQ(e.where().element, "pixel");
        EXPECT_EQ(e.where().index, 7);
        EXPECT_NE(std::string(e.what()).find("NaN"), std::string::npos) << e.what();
    }

    ImageRGB neg(4, 2);
    // Huge but allowed pixels must not overflow the sampling weights.
    for (EnvMapping m : {EnvMapping::latlong, EnvMapping::angular}) {
        ImageRGB huge(8, 8);
        for (float& v : huge.rgb) v = 1.0f;
        huge.set(3, 3, Vec3f(kMaxEnvironmentRadiance));
        ImageEnvironment env(huge, m, 0.0f, 1.0f);
        EnvSample s = env.sample({0.5f, 0.5f});
        EXPECT_GT(s.pdf_solid_angle, 0.0f);
        EXPECT_TRUE(std::isfinite(s.pdf_solid_angle));
        // The brightest pixel takes all samples; its interpolated values stay finite.
        EXPECT_GT(s.radiance.x, 1e28f);
        EXPECT_TRUE(is_finite(s.radiance));
    }

    EXPECT_THROW(ImageEnvironment(neg, EnvMapping::latlong, 0.0f, -1.0f), Error);
    EXPECT_THROW(ImageEnvironment(neg, EnvMapping::latlong, kInfinity, 1.0f), Error);
    EnvironmentDesc bad_colour;
    bad_colour.color = Vec3f(1.0f, std::nanf(""), 1.0f);
    EXPECT_THROW(make_environment_light(bad_colour), Error);
    bad_colour.color = Vec3f(-1.0f);
    EXPECT_THROW(make_environment_light(bad_colour), Error);
    std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace kdt

namespace kdt {
namespace {

// OpenEXR's envmap attribute: a cube-face map is refused, naming the attribute, rather than
// read as a lat-long strip; a lat-long one (or none) loads.
TEST(Environment, OpenExrCubeFaceMapsAreRefused) {
    auto dir = test::temp_dir("env_cube");
    auto write = [&](const std::string& name, int width, int height, int envmap) {
        test::ExrVariant v;
        v.width = width;
        v.height = height;
        v.envmap = envmap;
        const std::vector<uint8_t> bytes = test::exr_variant(v);
        const std::string path = (dir / name).string();
        std::ofstream(path, std::ios::binary)
            .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
        return path;
    };
    EnvironmentDesc desc;
    desc.file = write("cube.exr", 16, 96, Imf::ENVMAP_CUBE);
    std::string m;
    try {
        make_environment_light(desc);
    } catch (const Error& e) {
        m = e.what();
    }
    EXPECT_NE(m.find("cube.exr: its envmap attribute says 'cube'"), std::string::npos) << m;
    for (const int envmap : {int(Imf::ENVMAP_LATLONG), -1}) {
        desc.file = write("latlong.exr", 16, 8, envmap);
        EXPECT_NE(make_environment_light(desc), nullptr);
    }
    std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace kdt
