// Tests of ImageEnvironment's sampling grid (S x S cells per pixel, weighted by the bilinear
// reconstruction): on a map with a single bright texel, sample() agrees with pdf() and eval(),
// the pdf integrates to one and is positive exactly where eval() is, and the estimator of the
// map's power has a much lower variance than with one cell per pixel.
#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include "renderer/core/color.h"
#include "renderer/core/error.h"
#include "renderer/io/image_io.h"
#include "renderer/light/image_environment.h"
#include "renderer/light/mapping.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

using test::HashRng;

/// A black map with one bright texel: at the seam (x 0) for lat-long, off centre for angular.
ImageEnvironment single_texel(EnvMapping mapping, int cells_per_pixel = 0) {
    const bool latlong = mapping == EnvMapping::latlong;
    ImageRGB img(32, latlong ? 16 : 32);
    if (latlong) {
        img.set(0, 6, Vec3f(900.0f, 1000.0f, 800.0f));
    } else {
        img.set(20, 11, Vec3f(900.0f, 1000.0f, 800.0f));
    }
    return ImageEnvironment(img, mapping, 0.0f, 1.0f, "", cells_per_pixel);
}

/// Midpoint-rule integrals over the sphere, as integrals over the image with the Jacobian,
/// on a grid of `per_pixel`^2 points per pixel (never on a sampling-cell edge for S <= 16).
struct SphereIntegrals {
    double pdf = 0.0;           ///< of pdf
    double power = 0.0;         ///< of f = luminance(eval)
    double second = 0.0;        ///< of f^2 / pdf (where f > 0)
    int positive_mismatch = 0;  ///< points where (f > 0) != (pdf > 0)
    int uncovered = 0;          ///< points where f > 0 but pdf = 0 (a biased estimate)
};

SphereIntegrals integrate(const ImageEnvironment& env, int per_pixel) {
    SphereIntegrals r;
    const int nu = env.image().width * per_pixel, nv = env.image().height * per_pixel;
    for (int y = 0; y < nv; ++y) {
        for (int x = 0; x < nu; ++x) {
            auto d = env.dir_from_uv({(x + 0.5f) / float(nu), (y + 0.5f) / float(nv)});
            if (!d) continue;
            const double j = env_jacobian(env.mapping(), *d) / (double(nu) * nv);
            const double f = luminance(env.eval(*d)), p = env.pdf(*d);
            r.pdf += p * j;
            r.power += f * j;
            if (f > 0.0 && p > 0.0) r.second += f * f / p * j;
            r.positive_mismatch += (f > 0.0) != (p > 0.0) ? 1 : 0;
            r.uncovered += f > 0.0 && !(p > 0.0) ? 1 : 0;
        }
    }
    return r;
}

class SingleTexelTest : public ::testing::TestWithParam<EnvMapping> {};

TEST_P(SingleTexelTest, SampleAgreesWithPdfAndEval) {
    ImageEnvironment env = single_texel(GetParam());
    EXPECT_EQ(env.sampling_cells_per_pixel(), 8);
    HashRng rng(11);
    int zero = 0, black = 0;
    for (int i = 0; i < 100000; ++i) {
        EnvSample s = env.sample(rng.next2());
        if (!(s.pdf_solid_angle > 0.0f)) {
            ++zero;
            continue;
        }
        ASSERT_FLOAT_EQ(env.pdf(s.dir), s.pdf_solid_angle);
        ASSERT_EQ(env.eval(s.dir), s.radiance);
        black += luminance(s.radiance) > 0.0f ? 0 : 1;
    }
    // Each cell lies inside one bilinear patch, so no cell is partly black: only float
    // rounding at the support's edge can give a black or zero-pdf sample.
    EXPECT_LE(zero, 2);
    EXPECT_LE(black, 2);
}

TEST_P(SingleTexelTest, PdfIntegratesToOneAndIsPositiveExactlyWhereEvalIs) {
    // Negative: a cell per 2 x 2, 3 x 3 or 5 x 5 pixels (the grids of maps above 8192 x
    // 4096), whose cell edges do not fall on pixel edges for 3 and 5.
    for (int cells : {0, 1, 2, -2, -3, -5}) {
        ImageEnvironment env = single_texel(GetParam(), cells);
        SphereIntegrals r = integrate(env, 64);
        // Cells of 3 or 5 pixels end between the midpoint rule's points: a coarser check
        // (the exact one is MapTest.CellsOfSeveralPixelsSampleExactly's table sum).
        EXPECT_NEAR(r.pdf, 1.0, cells < -2 ? 5e-3 : 1e-3) << "cells per pixel " << cells;
        EXPECT_EQ(r.uncovered, 0) << "cells per pixel " << cells;
        if (cells == 0 || cells == 2) {  // with S = 1 and coarser the density also covers
            EXPECT_EQ(r.positive_mismatch, 0) << cells;  // black parts of cells
        }
    }
}

TEST_P(SingleTexelTest, FinerGridLowersTheVarianceOfThePowerEstimate) {
    // Relative variance of f/pdf under the sampling density: int f^2/p / (int f)^2 - 1.
    // With one cell per pixel, pdf is flat where the bilinear bump rises from 0 to its
    // peak; with 8 cells it follows the bump to within 1/8 pixel.
    auto relvar = [&](int cells) {
        SphereIntegrals r = integrate(single_texel(GetParam(), cells), 64);
        return r.second / (r.power * r.power) - 1.0;
    };
    const double coarse = relvar(1), s2 = relvar(2), s4 = relvar(4), fine = relvar(0);
    EXPECT_GT(coarse, 0.5);  // the bump is far from flat over a pixel
    EXPECT_LT(s2, coarse);
    EXPECT_LT(s4, s2);
    EXPECT_LT(fine, s4);
    EXPECT_LT(fine, 0.1 * coarse) << "S=1 " << coarse << ", S=8 " << fine;
}

INSTANTIATE_TEST_SUITE_P(Mappings, SingleTexelTest,
                         ::testing::Values(EnvMapping::latlong, EnvMapping::angular),
                         [](const ::testing::TestParamInfo<EnvMapping>& param_info) {
                             return std::string(kEnvMappingNames[size_t(param_info.param)]);
                         });

// MIS compensation: sample_mis() / pdf_mis() follow the map minus its mean luminance over
// the sphere. On a map of a dim sky (luminance 1) with a bright patch (100): the density is
// zero in the sky and positive on the patch, integrates to one, and sample_mis() agrees with
// pdf_mis() and eval().
ImageEnvironment sky_with_patch(EnvMapping mapping) {
    const bool latlong = mapping == EnvMapping::latlong;
    ImageRGB img(32, latlong ? 16 : 32);
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) img.set(x, y, Vec3f(1.0f));
    for (int y = 10; y < 13; ++y)
        for (int x = 18; x < 21; ++x) img.set(x, latlong ? y - 4 : y, Vec3f(100.0f));
    return ImageEnvironment(img, mapping, 0.0f, 1.0f);
}

class MisCompensationTest : public ::testing::TestWithParam<EnvMapping> {};

TEST_P(MisCompensationTest, DensityIsZeroBelowTheMeanAndIntegratesToOne) {
    const ImageEnvironment env = sky_with_patch(GetParam());
    const bool latlong = GetParam() == EnvMapping::latlong;
    const int per_pixel = 16;
    const int nu = env.image().width * per_pixel, nv = env.image().height * per_pixel;
    double integral = 0.0;
    for (int y = 0; y < nv; ++y) {
        for (int x = 0; x < nu; ++x) {
            auto d = env.dir_from_uv({(x + 0.5f) / float(nu), (y + 0.5f) / float(nv)});
            if (!d) continue;
            integral += env.pdf_mis(*d) * env_jacobian(env.mapping(), *d) / (double(nu) * nv);
        }
    }
    EXPECT_NEAR(integral, 1.0, 1e-3);
    // Texel centres: the sky far from the patch, and the patch's middle texel.
    const float w = float(env.image().width), h = float(env.image().height);
    auto centre = [&](int x, int y) { return *env.dir_from_uv({(x + 0.5f) / w, (y + 0.5f) / h}); };
    const Vec3f sky = centre(4, latlong ? 4 : 16), patch = centre(19, latlong ? 7 : 11);
    EXPECT_EQ(env.pdf_mis(sky), 0.0f);
    EXPECT_GT(env.pdf(sky), 0.0f);
    // On the patch the compensated density is the larger one: the sky's share moved there.
    EXPECT_GT(env.pdf_mis(patch), env.pdf(patch));
}

TEST_P(MisCompensationTest, SampleAgreesWithPdfAndEval) {
    const ImageEnvironment env = sky_with_patch(GetParam());
    HashRng rng(5);
    int zero = 0;
    for (int i = 0; i < 100000; ++i) {
        const EnvSample s = env.sample_mis(rng.next2());
        if (!(s.pdf_solid_angle > 0.0f)) {
            ++zero;
            continue;
        }
        ASSERT_FLOAT_EQ(env.pdf_mis(s.dir), s.pdf_solid_angle);
        ASSERT_EQ(env.eval(s.dir), s.radiance);
        // Only directions brighter than the mean are drawn.
        ASSERT_GT(luminance(s.radiance), 1.0f);
    }
    EXPECT_LE(zero, 2);
}

TEST_P(MisCompensationTest, AUniformMapLeavesEverythingToBsdfSampling) {
    ImageRGB img(16, GetParam() == EnvMapping::latlong ? 8 : 16);
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) img.set(x, y, Vec3f(0.5f));
    const ImageEnvironment env(img, GetParam(), 0.0f, 1.0f);
    EXPECT_TRUE(env.mis_distribution().empty());
    EXPECT_FALSE(env.distribution().empty());
    EXPECT_EQ(env.sample_mis({0.3f, 0.6f}).pdf_solid_angle, 0.0f);
    EXPECT_EQ(env.pdf_mis(Vec3f(0.0f, 1.0f, 0.0f)), 0.0f);
}

INSTANTIATE_TEST_SUITE_P(Mappings, MisCompensationTest,
                         ::testing::Values(EnvMapping::latlong, EnvMapping::angular),
                         [](const ::testing::TestParamInfo<EnvMapping>& param_info) {
                             return std::string(kEnvMappingNames[size_t(param_info.param)]);
                         });

TEST(Environment, SamplingCellsPerPixelAreCheckedAndFollowTheMapSize) {
    ImageRGB img(8, 4);
    img.set(1, 1, Vec3f(1.0f));
    for (int bad : {-1, -65, 3, 5, 18}) {
        EXPECT_THROW(ImageEnvironment(img, EnvMapping::latlong, 0.0f, 1.0f, "m.hdr", bad), Error)
            << bad;
    }
    EXPECT_EQ(ImageEnvironment(img, EnvMapping::latlong, 0.0f, 1.0f).sampling_cells_per_pixel(), 8);
    EXPECT_EQ(ImageEnvironment(ImageRGB(512, 256), EnvMapping::latlong, 0.0f, 1.0f)
                  .sampling_cells_per_pixel(),
              4);
    EXPECT_EQ(ImageEnvironment(ImageRGB(1024, 512), EnvMapping::latlong, 0.0f, 1.0f)
                  .sampling_cells_per_pixel(),
              2);
    const ImageEnvironment big(ImageRGB(2048, 1024), EnvMapping::latlong, 0.0f, 1.0f);
    EXPECT_EQ(big.sampling_cells_per_pixel(), 1);
    EXPECT_EQ(big.sampling_pixels_per_cell(), 1);
    EXPECT_EQ(big.sampling_grid_width(), 2048);
    const ImageEnvironment coarse(ImageRGB(37, 19), EnvMapping::latlong, 0.0f, 1.0f, "", -4);
    EXPECT_EQ(coarse.sampling_cells_per_pixel(), 1);
    EXPECT_EQ(coarse.sampling_pixels_per_cell(), 4);
    EXPECT_EQ(coarse.sampling_grid_width(), 10);
    EXPECT_EQ(coarse.sampling_grid_height(), 5);
    // Maps beyond 8192 x 4096 pixels: a cell per T x T pixels, within 2^25 cells.
    EXPECT_EQ(automatic_sampling_pixels_per_cell(8192, 4096), 1);
    EXPECT_EQ(automatic_sampling_pixels_per_cell(8193, 4096), 2);
    EXPECT_EQ(automatic_sampling_pixels_per_cell(16384, 8192), 2);
    EXPECT_EQ(automatic_sampling_pixels_per_cell(32768, 16384), 4);
    EXPECT_EQ(automatic_sampling_pixels_per_cell(1 << 30, 1), 32);
}

}  // namespace
}  // namespace kdt
