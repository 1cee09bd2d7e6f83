// The real display path (ui/display.*: PBO upload and the tone-mapping fragment shader) in an
// offscreen OSMesa GL 3.3 core context, checked against the CPU tone map of the PNG writer.
#include "ui/display.h"

#include <cmath>
#include <cstdlib>

#include <gtest/gtest.h>

#include "tests/ui/osmesa_context.h"

namespace kdt::ui {
namespace {

constexpr int kW = 24, kH = 6;

// Radiance values across the curves' ranges: zero, the sRGB toe, mid-tones, above 1, large.
std::vector<float> known_image(float scale) {
    const float values[] = {0.0f,  1e-4f, 0.001f, 0.0031f, 0.004f, 0.01f, 0.05f, 0.1f,
                            0.18f, 0.25f, 0.33f,  0.5f,    0.6f,   0.75f, 0.9f,  0.99f,
                            1.0f,  1.2f,  1.5f,   2.0f,    4.0f,   10.0f, 1e3f,  1e6f};
    std::vector<float> rgb(size_t(kW) * kH * 3);
    for (int y = 0; y < kH; ++y) {
        for (int x = 0; x < kW; ++x) {
            const size_t i = (size_t(y) * kW + size_t(x)) * 3;
            // Each row and channel a different mix, so a row or channel swap shows.
            rgb[i] = values[size_t(x)] * scale;
            rgb[i + 1] = values[size_t((x + y) % kW)] * scale;
            rgb[i + 2] = values[size_t((x + 3 * y + 5) % kW)] * scale;
        }
    }
    return rgb;
}

TEST(FilmDisplay, ShaderMatchesTheCpuToneMapOfPngOutput) {
    test::OffscreenGL gl(kW, kH);
    ASSERT_TRUE(gl.ok()) << "OSMesa could not create a GL 3.3 core context";
    FilmDisplay display;
    display.init();
    int checked = 0;
    for (float scale : {1.0f, 0.37f}) {
        const std::vector<float> img = known_image(scale);
        display.upload(kW, kH, img.data());  // the second upload reuses the texture
        for (ToneCurve curve : {ToneCurve::clamp, ToneCurve::reinhard, ToneCurve::aces}) {
            for (float exposure : {0.0f, 1.5f, -2.0f}) {
                ToneParams tone;
                tone.exposure = exposure;
                tone.curve = curve;
                display.draw(0, 0, kW, kH, tone, DisplayMode::radiance);
                const std::vector<uint8_t> px = gl.read_rgb();
                ASSERT_EQ(gl_errors("draw"), "");
                for (size_t i = 0; i < img.size(); ++i) {
                    const int cpu = tonemap_to_srgb8(img[i], tone);
                    // Float pow on the GPU rounds differently in the last bits: one code.
                    ASSERT_LE(std::abs(int(px[i]) - cpu), 1)
                        << "pixel " << i / 3 << " channel " << i % 3 << " value " << img[i]
                        << " curve " << int(curve) << " exposure " << exposure;
                    ++checked;
                }
            }
        }
    }
    EXPECT_EQ(checked, 2 * 9 * kW * kH * 3);
}

TEST(FilmDisplay, DirectModeShowsValuesAndALowResolutionImageFillsTheViewport) {
    test::OffscreenGL gl(kW, kH);
    ASSERT_TRUE(gl.ok());
    FilmDisplay display;
    display.init();
    // A 2x1 image (left red, right blue) stretched over the viewport: left and right ends.
    const float two[] = {1.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.5f};
    display.upload(2, 1, two);
    display.draw(0, 0, kW, kH, ToneParams{}, DisplayMode::direct);
    const std::vector<uint8_t> px = gl.read_rgb();
    EXPECT_EQ(gl_errors("draw"), "");
    EXPECT_EQ(px[0], 255);  // top-left: red
    EXPECT_EQ(px[2], 0);
    const size_t right = (size_t(kW) - 1) * 3;
    EXPECT_EQ(px[right], 0);  // top-right: blue at 0.5, shown as is (no sRGB curve)
    EXPECT_NEAR(px[right + 2], 128, 1);
}

TEST(FilmDisplay, TheToneMappedImageFollowsUploadsAndRedrawsTheSameWithoutOne) {
    test::OffscreenGL gl(kW, kH);
    ASSERT_TRUE(gl.ok());
    FilmDisplay display;
    display.init();
    ToneParams tone;
    tone.curve = ToneCurve::reinhard;
    const std::vector<float> a = known_image(1.0f), b = known_image(0.37f);
    auto check = [&](const std::vector<float>& img, const char* what) {
        const std::vector<uint8_t> px = gl.read_rgb();
        ASSERT_EQ(gl_errors(what), "");
        for (size_t i = 0; i < img.size(); ++i)
            ASSERT_LE(std::abs(int(px[i]) - tonemap_to_srgb8(img[i], tone)), 1) << what << i;
    };
    display.upload(kW, kH, a.data());
    display.draw(0, 0, kW, kH, tone, DisplayMode::radiance);
    check(a, "first draw");
    // Same image and tone: drawn from the cached tone map, over a cleared framebuffer.
    glClearColor(0.0f, 1.0f, 0.0f, 1.0f);
    glClear(GL_COLOR_BUFFER_BIT);
    display.draw(0, 0, kW, kH, tone, DisplayMode::radiance);
    check(a, "redraw");
    // A new upload with the same tone is shown, not the cached image.
    display.upload(kW, kH, b.data());
    display.draw(0, 0, kW, kH, tone, DisplayMode::radiance);
    check(b, "after upload");
}

TEST(Screenshot, SrgbCodesDecodedToLinearEncodeBackToThemselves) {
    // Viewer::screenshot writes window pixels through the PNG writer's tone map.
    for (int c = 0; c < 256; ++c) {
        EXPECT_EQ(tonemap_to_srgb8(srgb_to_linear(float(c) / 255.0f), ToneParams{}), c) << c;
    }
}

}  // namespace
}  // namespace kdt::ui
