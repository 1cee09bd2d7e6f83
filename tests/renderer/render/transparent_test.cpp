// --transparent: the environment seen directly is left out and each pixel's coverage becomes
// the alpha of PNG and EXR output, without changing the samples that hit the scene.
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>

#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/io/image_io.h"
#include "renderer/render/session.h"
#include "tests/renderer/integrator/test_scenes.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

// A sphere in the middle of a 24x16 image under a bright constant sky.
std::shared_ptr<const RenderSnapshot> sphere_snapshot() {
    const TraceScene scene = test::make_scene(
        {{test::make_icosphere({0, 0, 0}, 0.6f, 2), test::flat(test::diffuse(0.5f))}},
        std::make_shared<test::ConstantEnv>(Vec3f(2.0f)));
    return compile_snapshot(scene, make_camera({0, 0, 3}, {0, 0, 0}, {0, 1, 0}, 40.0f, 24, 16));
}

Film render(bool transparent) {
    FilmParams fp;
    fp.transparent = transparent;
    RenderSession s(sphere_snapshot(), TraceParams{}, fp);
    StopConditions stop;
    stop.spp = 8;
    run_render(s, stop);
    return s.film();
}

TEST(Transparent, CoverageIsAlphaAndTheSceneKeepsItsSamples) {
    const Film opaque = render(false);
    const Film clear = render(true);
    EXPECT_FALSE(opaque.keeps_coverage());
    EXPECT_TRUE(opaque.coverage().empty());
    ASSERT_TRUE(clear.keeps_coverage());
    const std::vector<float> alpha = clear.coverage();
    ASSERT_EQ(alpha.size(), clear.pixel_count());
    // A corner sees only the sky: transparent and black; the centre only the sphere: opaque,
    // with exactly the opaque render's radiance (the same samples).
    EXPECT_EQ(alpha[0], 0.0f);
    EXPECT_EQ(clear.mean(0, 0), Vec3f(0.0f));
    EXPECT_EQ(opaque.mean(0, 0), Vec3f(2.0f));
    const size_t centre = size_t(8) * 24 + 12;
    EXPECT_EQ(alpha[centre], 1.0f);
    EXPECT_EQ(clear.mean(12, 8), opaque.mean(12, 8));
    // The sphere's rim: partly covered pixels exist, with alpha strictly between 0 and 1.
    bool partial = false;
    for (float a : alpha) partial |= a > 0.0f && a < 1.0f;
    EXPECT_TRUE(partial);
}

TEST(Transparent, PngIsRgbaAndExrHasAnAlphaChannel) {
    const auto dir = test::temp_dir("transparent");
    ImageRGB image(3, 1);
    image.rgb = {0.5f, 0.5f, 0.5f, 0.25f, 0.25f, 0.25f, 0.0f, 0.0f, 0.0f};  // premultiplied
    image.alpha = {1.0f, 0.5f, 0.0f};
    const std::string png = (dir / "a.png").string(), exr = (dir / "a.exr").string();
    write_image(png, image, {}, {});
    const std::vector<unsigned char> bytes = test::read_bytes(png);
    ASSERT_GT(bytes.size(), 26u);
    EXPECT_EQ(bytes[25], 6);  // IHDR colour type: RGBA
    // Straight alpha in PNG: the half-covered pixel has the colour of the full one.
    const ImageRGB back = load_image(png);
    EXPECT_NEAR(back.at(1, 0).x, back.at(0, 0).x, 1e-6f);

    write_image(exr, image, {}, {});
    Imf::InputFile file(exr.c_str());
    ASSERT_NE(file.header().channels().findChannel("A"), nullptr);
    std::vector<float> a(3, -1.0f);
    Imf::FrameBuffer fb;
    fb.insert("A", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(a.data()), sizeof(float),
                              3 * sizeof(float)));
    file.setFrameBuffer(fb);
    file.readPixels(0, 0);
    EXPECT_EQ(a, image.alpha);
    EXPECT_EQ(load_image(exr).rgb, image.rgb);  // RGB stays premultiplied

    // Formats without alpha refuse such an image instead of dropping its transparency.
    EXPECT_NE(test::error_of_call([&] {
                  write_image((dir / "a.pfm").string(), image, {}, {});
              }).find("no alpha channel"),
              std::string::npos);
    image.alpha.pop_back();
    EXPECT_NE(test::error_of_call([&] { write_image(png, image, {}, {}); }), "");
}

}  // namespace
}  // namespace kdt
