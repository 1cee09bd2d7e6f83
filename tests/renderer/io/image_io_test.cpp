// Tests of renderer/io/image_io.*: round trips (PFM exact, PNG within quantisation, HDR
// within RGBE precision), metadata read back, and broken files that must throw kdt::Error
// naming the file instead of crashing, hanging or allocating absurdly. OpenEXR: exr_io_test.
#include "renderer/io/image_io.h"

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>

#include <gtest/gtest.h>
#include <zlib.h>

#include "renderer/core/color.h"
#include "renderer/core/error.h"
#include "tests/renderer/io/image_test_util.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

using test::expect_load_error;
using test::HashRng;
using test::random_image;
using test::read_bytes;
using test::write_bytes;

void write_text(const std::filesystem::path& p, const std::string& s) {
    write_bytes(p, std::vector<uint8_t>(s.begin(), s.end()));
}

class ImageIoTest : public ::testing::Test {
protected:
    void SetUp() override { dir_ = test::temp_dir("image_io"); }
    void TearDown() override { std::filesystem::remove_all(dir_); }
    std::string path(const std::string& name) const { return (dir_ / name).string(); }
    // The error of read_image_info() / load_image() on `png` written to a file, or "".
    std::string info_error(const std::vector<uint8_t>& png) const {
        write_bytes(path("p.png"), png);
        return test::error_of_call([&] { read_image_info(path("p.png")); });
    }
    std::string load_error(const std::vector<uint8_t>& png) const {
        write_bytes(path("p.png"), png);
        return test::error_of_call([&] { load_image(path("p.png")); });
    }
    std::filesystem::path dir_;
};

TEST_F(ImageIoTest, PfmRoundTripIsExactAndBottomUp) {
    ImageRGB img = random_image(7, 3, 1, 100.0f);
    img.set(0, 0, Vec3f(-1.5f, 1e-30f, 3e30f));
    write_pfm(path("a.pfm"), img);
    ImageRGB back = load_image(path("a.pfm"));
    ASSERT_EQ(back.width, 7);
    ASSERT_EQ(back.height, 3);
    EXPECT_EQ(back.rgb, img.rgb);
    // The first stored row is the bottom one (y = 2).
    auto bytes = read_bytes(path("a.pfm"));
    std::string header = "PF\n7 3\n-1\n";
    ASSERT_EQ(std::string(bytes.begin(), bytes.begin() + ptrdiff_t(header.size())), header);
    float first;
    std::memcpy(&first, &bytes[header.size()], 4);
    EXPECT_EQ(first, img.at(0, 2).x);
}

TEST_F(ImageIoTest, PfmBigEndianGreyAndScale) {
    // Grey "Pf", positive scale = big-endian, |scale| = 2 multiplies (as pbrt reads it).
    std::vector<uint8_t> bytes;
    std::string header = "Pf\n2 1\n2.0\n";
    bytes.assign(header.begin(), header.end());
    for (float v : {1.5f, -4.0f}) {
        uint32_t bits;
        std::memcpy(&bits, &v, 4);
        for (int b = 3; b >= 0; --b) bytes.push_back(uint8_t(bits >> (8 * b)));
    }
    write_bytes(path("g.pfm"), bytes);
    ImageRGB img = load_image(path("g.pfm"));
    ASSERT_EQ(img.width, 2);
    EXPECT_EQ(img.at(0, 0), Vec3f(3.0f));
    EXPECT_EQ(img.at(1, 0), Vec3f(-8.0f));
}

// A PNG's text metadata is bounded in all (64 MiB inflated), so that a small file of many
// compressed chunks cannot take gigabytes; going past it is said as such, not as corruption.
TEST_F(ImageIoTest, PngTextMetadataIsBoundedInAll) {
    write_png(path("small.png"), ImageRGB(2, 2), {}, {{"kdtrace:params", "{}"}});
    const std::vector<uint8_t> base = read_bytes(path("small.png"));
    // A zTXt chunk of `mib` MiB of zeros (a few KB compressed).
    auto ztxt = [](const std::string& key, size_t mib) {
        const std::vector<uint8_t> zeros(mib << 20, 0);
        uLongf size = compressBound(uLong(zeros.size()));
        std::vector<uint8_t> z(size);
        EXPECT_EQ(compress2(z.data(), &size, zeros.data(), uLong(zeros.size()), 9), Z_OK);
        std::vector<uint8_t> body(key.begin(), key.end());
        body.push_back(0);
        body.push_back(0);  // deflate
        body.insert(body.end(), z.begin(), z.begin() + long(size));
        std::vector<uint8_t> chunk;
        const uint32_t n = uint32_t(body.size());
        for (int b = 3; b >= 0; --b) chunk.push_back(uint8_t(n >> (8 * b)));
        for (char c : std::string("zTXt")) chunk.push_back(uint8_t(c));
        chunk.insert(chunk.end(), body.begin(), body.end());
        const uint32_t crc = uint32_t(crc32(0L, chunk.data() + 4, uInt(chunk.size() - 4)));
        for (int b = 3; b >= 0; --b) chunk.push_back(uint8_t(crc >> (8 * b)));
        return chunk;
    };
    auto with = [&](const std::string& name, const std::vector<std::vector<uint8_t>>& chunks) {
        std::vector<uint8_t> png(base.begin(), base.end() - 12);  // all but IEND
        for (const auto& c : chunks) png.insert(png.end(), c.begin(), c.end());
        png.insert(png.end(), base.end() - 12, base.end());
        write_bytes(path(name), png);
        return test::error_of_call([&] { read_png_metadata(path(name)); });
    };
    EXPECT_EQ(with("one.png", {ztxt("junk", 8)}), "");
    EXPECT_NE(with("many.png", {ztxt("a", 40), ztxt("b", 40)}).find("many.png: byte "),
              std::string::npos);
    EXPECT_NE(with("many2.png", {ztxt("a", 40), ztxt("b", 40)})
                  .find("text metadata larger than 64 MiB in all"),
              std::string::npos);
    EXPECT_NE(with("big.png", {ztxt("a", 65)}).find("text metadata larger than 64 MiB in all"),
              std::string::npos);
}

TEST_F(ImageIoTest, PngRoundTripWithinQuantisationAndMetadata) {
    ImageRGB img = random_image(31, 9, 3, 1.0f);
    img.set(0, 0, Vec3f(0.0f, 1.0f, 5.0f));  // 5 clamps to 1
    ImageMetadata md = {{"kdtrace.seed", "7"},
                        {"kdtrace.params", "{\"spp\": 16,\n \"max_depth\": 8}"},
                        {"Comment", "caf\xc3\xa9 (UTF-8 goes into iTXt)"}};
    write_png(path("a.png"), img, {}, md);
    ImageMetadata read;
    ImageRGB back = load_image(path("a.png"), &read);  // decoded by stb_image, not by us
    ASSERT_EQ(back.width, 31);
    ASSERT_EQ(back.height, 9);
    EXPECT_EQ(read, md);
    EXPECT_EQ(read_png_metadata(path("a.png")), md);
    for (size_t i = 0; i < img.rgb.size(); ++i) {
        float expect = linear_to_srgb(std::min(img.rgb[i], 1.0f));
        ASSERT_NEAR(linear_to_srgb(back.rgb[i]), expect, 0.5f / 255.0f + 1e-5f) << i;
    }
    // Exposure is in stops: 0.25 at +1 stop is written as 0.5.
    ImageRGB quarter(2, 2);
    for (float& v : quarter.rgb) v = 0.25f;
    ToneParams tone;
    tone.exposure = 1.0f;
    write_png(path("e.png"), quarter, tone);
    EXPECT_NEAR(load_image(path("e.png")).rgb[0], 0.5f, 0.004f);
    EXPECT_THROW(write_png(path("k.png"), quarter, {}, {{"", "v"}}), Error);
    EXPECT_THROW(write_png(path("k.png"), quarter, {}, {{std::string(80, 'k'), "v"}}), Error);
}

TEST_F(ImageIoTest, ToneCurves) {
    EXPECT_EQ(tonemap_to_srgb8(0.0f, {}), 0);
    EXPECT_EQ(tonemap_to_srgb8(1.0f, {}), 255);
    EXPECT_EQ(tonemap_to_srgb8(std::nanf(""), {}), 0);
    EXPECT_EQ(tonemap_to_srgb8(srgb_to_linear(128.0f / 255.0f), {}), 128);
    ToneParams reinhard{0.0f, ToneCurve::reinhard};
    EXPECT_EQ(tonemap_to_srgb8(1.0f, reinhard), tonemap_to_srgb8(0.5f, {}));
    ToneParams aces{0.0f, ToneCurve::aces};
    EXPECT_LT(tonemap_to_srgb8(1.0f, aces), 255);
    EXPECT_EQ(tonemap_to_srgb8(1e6f, aces), 255);
    for (int i = 0; i < 256; ++i) {
        float x = float(i) / 255.0f;
        EXPECT_NEAR(srgb_to_linear(linear_to_srgb(x)), x, 1e-6f);
    }
}

// Every curve maps 0, negatives and NaN to 0, never decreases, stays in [0,1] and reaches 1
// (at infinity at the latest); the compressive ones keep highlights below white where the
// clamp clips them.
TEST_F(ImageIoTest, EveryToneCurveIsMonotoneFromZeroToOne) {
    static_assert(kToneCurveNames.size() == size_t(ToneCurve::filmic) + 1);
    for (size_t c = 0; c < kToneCurveNames.size(); ++c) {
        const ToneCurve curve = ToneCurve(c);
        SCOPED_TRACE(kToneCurveNames[c]);
        EXPECT_EQ(apply_tone_curve(0.0f, curve), 0.0f);
        EXPECT_EQ(apply_tone_curve(-1.0f, curve), 0.0f);
        EXPECT_EQ(apply_tone_curve(std::nanf(""), curve), 0.0f);
        EXPECT_EQ(apply_tone_curve(kInfinity, curve), 1.0f);
        EXPECT_EQ(apply_tone_curve(std::numeric_limits<float>::max(), curve), 1.0f);
        float prev = 0.0f;
        uint8_t prev8 = 0;
        for (float x = 1e-12f; x < 1e30f; x *= 1.0005f) {
            const float y = apply_tone_curve(x, curve);
            ASSERT_GE(y, prev) << "at " << x;
            ASSERT_LE(y, 1.0f) << "at " << x;
            const uint8_t y8 = tonemap_to_srgb8(x, {0.0f, curve});
            ASSERT_GE(y8, prev8) << "at " << x;
            prev = y;
            prev8 = y8;
        }
        EXPECT_GT(apply_tone_curve(1e-6f, curve), 0.0f);
        EXPECT_EQ(prev8, 255);
        if (curve != ToneCurve::clamp) {
            EXPECT_LT(tonemap_to_srgb8(1.0f, {0.0f, curve}), 255);
        }
    }
    // Names are distinct (the CLI and metadata spell curves by them).
    for (size_t i = 0; i < kToneCurveNames.size(); ++i) {
        for (size_t j = 0; j < i; ++j) EXPECT_STRNE(kToneCurveNames[i], kToneCurveNames[j]);
    }
}

// The default curve, clamp, gives bit for bit the PNG values the writer gave before tone
// curves existed: radiance * 2^exposure clamped to [0,1], sRGB-encoded, rounded.
TEST_F(ImageIoTest, ClampCurveMatchesThePlainClampBitwise) {
    auto plain = [](float linear, float exposure) {
        const float scaled = linear * std::exp2(exposure);
        const float clamped = !(scaled > 0.0f) ? 0.0f : (scaled < 1.0f ? scaled : 1.0f);
        return uint8_t(linear_to_srgb(clamped) * 255.0f + 0.5f);
    };
    HashRng rng(31);
    for (float exposure : {-3.0f, 0.0f, 1.5f}) {
        for (int i = 0; i < 200000; ++i) {
            const float x = std::ldexp(rng.next(), int(rng.next_u64() % 40) - 30);
            ASSERT_EQ(tonemap_to_srgb8(x, {exposure, ToneCurve::clamp}), plain(x, exposure))
                << x << " at exposure " << exposure;
        }
    }
    const ImageRGB img = random_image(17, 5, 4, 4.0f);
    write_png(path("default.png"), img);
    write_png(path("clamp.png"), img, {0.0f, ToneCurve::clamp});
    EXPECT_EQ(read_bytes(path("default.png")), read_bytes(path("clamp.png")));
    write_image(path("aces.png"), img, {0.0f, ToneCurve::aces});
    EXPECT_NE(read_bytes(path("default.png")), read_bytes(path("aces.png")));
    // Linear formats ignore the tone parameters.
    write_image(path("a.pfm"), img, {2.0f, ToneCurve::filmic});
    EXPECT_EQ(load_image(path("a.pfm")).rgb, img.rgb);
}

// What `kdtrace info` prints: size, format, encoding and the metadata, for every format.
TEST_F(ImageIoTest, ImageInfoOfEveryFormat) {
    const ImageRGB img = random_image(7, 3, 12, 2.0f);
    const ImageMetadata md = {{"kdtrace:spp", "4"}, {"kdtrace:command", "kdtrace render"}};
    write_png(path("a.png"), img, {}, md);
    ImageInfo info = read_image_info(path("a.png"));
    EXPECT_EQ(info.format, "PNG");
    EXPECT_EQ(info.width, 7);
    EXPECT_EQ(info.height, 3);
    EXPECT_EQ(info.encoding, "8-bit sRGB");
    EXPECT_EQ(info.metadata, md);
    write_hdr(path("a.hdr"), img);
    info = read_image_info(path("a.hdr"));
    EXPECT_EQ(info.format, "Radiance HDR");
    EXPECT_EQ(info.width, 7);
    EXPECT_TRUE(info.metadata.empty());
    write_pfm(path("a.pfm"), img);
    info = read_image_info(path("a.pfm"));
    EXPECT_EQ(info.format, "PFM");
    EXPECT_EQ(info.height, 3);
    EXPECT_EQ(info.encoding, "colour 32-bit float");
    write_text(dir_ / "bad.png", "\x89PNG\r\n\x1a\nshort");
    EXPECT_THROW(read_image_info(path("bad.png")), Error);
}

TEST_F(ImageIoTest, HdrRoundTripWithinRgbePrecision) {
    ImageRGB img = random_image(40, 12, 4, 50.0f);
    write_hdr(path("a.hdr"), img);
    {  // trailing blanks on the resolution line are accepted (as stb_image does)
        auto bytes = read_bytes(path("a.hdr"));
        std::string text(bytes.begin(), bytes.end());
        auto at = text.find("+X 40\n");
        ASSERT_NE(at, std::string::npos);
        text.replace(at, 6, "+X 40  \n");
        write_text(dir_ / "blank.hdr", text);
        EXPECT_EQ(load_image(path("blank.hdr")).width, 40);
    }
    ImageRGB back = load_image(path("a.hdr"));
    ASSERT_EQ(back.width, 40);
    ASSERT_EQ(back.height, 12);
    for (size_t p = 0; p < img.pixel_count(); ++p) {
        float m = std::max({img.rgb[3 * p], img.rgb[3 * p + 1], img.rgb[3 * p + 2]});
        for (int c = 0; c < 3; ++c)
            ASSERT_NEAR(back.rgb[3 * p + c], img.rgb[3 * p + c], m / 128.0f);
    }
    write_image(path("b.PFM"), img);
    EXPECT_EQ(load_image(path("b.PFM")).rgb, img.rgb);
    EXPECT_THROW(write_image(path("c.tiff"), img), Error);
}

TEST_F(ImageIoTest, LoadsTheSharedProbes) {
    const auto grace_file = test::grace_probe();
    if (grace_file.empty()) GTEST_SKIP() << test::kNoGraceProbe;
    ImageRGB grace = load_image(grace_file.string());
    EXPECT_EQ(grace.width, 256);
    EXPECT_EQ(grace.height, 128);
    float max = 0.0f;
    for (float v : grace.rgb) max = std::max(max, v);
    EXPECT_GT(max, 100.0f) << "Grace's windows are very bright";
    // Round trip through our writers.
    write_exr(path("grace.exr"), grace);
    EXPECT_EQ(load_image(path("grace.exr")).rgb, grace.rgb);
    write_hdr(path("grace.hdr"), grace);
    EXPECT_EQ(load_image(path("grace.hdr")).rgb, grace.rgb) << "RGBE values re-encode exactly";
}

TEST_F(ImageIoTest, MissingEmptyAndUnknownFiles) {
    std::string msg = expect_load_error(dir_ / "missing.hdr");
    EXPECT_NE(msg.find("cannot open"), std::string::npos) << msg;
    write_text(dir_ / "empty.exr", "");
    expect_load_error(dir_ / "empty.exr");
    write_text(dir_ / "text.hdr", "hello world\n");
    expect_load_error(dir_ / "text.hdr");
    EXPECT_THROW(write_pfm((dir_ / "no" / "dir.pfm").string(), ImageRGB(1, 1)), Error);
    ImageRGB inconsistent(2, 2);
    inconsistent.rgb.pop_back();
    EXPECT_THROW(write_pfm(path("x.pfm"), inconsistent), Error);
}

// A render checks its output before it starts, so hours of work are not lost to a typo;
// the write goes through a temporary file, so a failed write never truncates an old image.
TEST_F(ImageIoTest, OutputIsCheckedBeforehandAndReplacedWhole) {
    auto error_of = [](const std::string& p) {
        try {
            check_image_output(p);
        } catch (const Error& e) {
            EXPECT_NE(std::string(e.what()).find(p), std::string::npos) << e.what();
            return std::string(e.what());
        }
        return std::string();
    };
    EXPECT_EQ(error_of(path("ok.png")), "");
    EXPECT_EQ(error_of(path("ok.EXR")), "");
    EXPECT_NE(error_of(path("x.bmp")).find("unknown image format '.bmp'"), std::string::npos);
    EXPECT_NE(error_of(path("x")).find("unknown image format"), std::string::npos);
    EXPECT_NE(error_of(path("missing/x.pfm")).find("no directory"), std::string::npos);
    std::filesystem::create_directory(dir_ / "d.png");
    EXPECT_NE(error_of(path("d.png")).find("is a directory"), std::string::npos);
    write_text(dir_ / "file", "x");
    EXPECT_NE(error_of(path("file/x.png")).find("no directory"), std::string::npos);
    try {  // not error_of(): the message shortens so long a path
        check_image_output(path(std::string(300, 'a') + ".png"));
        ADD_FAILURE() << "a 304-byte file name passed";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("file name too long: 304 bytes"), std::string::npos)
            << e.what();
    }
    EXPECT_TRUE(std::filesystem::exists(dir_ / "file"));  // checking wrote nothing
    EXPECT_FALSE(std::filesystem::exists(dir_ / "ok.png"));

    // Replacing an image leaves the new one and no temporary file behind.
    write_pfm(path("a.pfm"), random_image(3, 2, 1, 1.0f));
    const ImageRGB second = random_image(2, 5, 2, 1.0f);
    write_image(path("a.pfm"), second);
    EXPECT_EQ(load_image(path("a.pfm")).rgb, second.rgb);
    EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir_),
                            std::filesystem::directory_iterator()),
              3);  // d.png, file, a.pfm
    // A write whose last step fails (a directory in the way of the rename) is an error
    // naming the file, and leaves neither a temporary file nor a changed target behind.
    try {
        write_image(path("d.png"), second);
        ADD_FAILURE() << "no error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("d.png: cannot replace the file"), std::string::npos)
            << e.what();
    }
    EXPECT_TRUE(std::filesystem::is_directory(dir_ / "d.png"));
    EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir_),
                            std::filesystem::directory_iterator()),
              3);
}

TEST_F(ImageIoTest, BrokenHdrHeaders) {
    const std::string head = "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n";
    auto bin = [](const char* bytes, size_t n) { return std::string(bytes, n); };
    struct Case {
        std::string text, expect;
    };
    std::vector<Case> cases = {
        {head + "-Y 100000 +X 100000\n", "too large"},
        {head + "-Y 60000 +X 60000\n", "too large"},
        {head + "-Y 0 +X 16\n", "invalid image size"},
        {head + "+Y 4 +X 4\n", "resolution"},
        {head + "-Y 4 +X 4 junk\n", "resolution"},
        {"#?RADIANCE\nFORMAT=32-bit_rle_xyze\n\n-Y 1 +X 1\nabcd", "unsupported pixel format"},
        {"#?RADIANCE\n\n-Y 1 +X 1\nabcd", "FORMAT"},
        {"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n", "truncated header"},
        {head + "-Y 2 +X 4\n" + std::string(31, 'x'), "truncated"},  // flat data, 1 byte short
        {head + "-Y 2 +X 16\n" + bin("\x02\x02\x00\x11", 4), "length 17"},      // RLE width wrong
        {head + "-Y 2 +X 16\n" + bin("\x02\x02\x00\x10\x90", 5), "truncated"},  // run, no value
        // Zero-length runs forever: stb_image alone would spin at the end of the data.
        {head + "-Y 1 +X 16\n" + bin("\x02\x02\x00\x10", 4) + std::string(200, '\0'), "truncated"},
    };
    for (size_t i = 0; i < cases.size(); ++i) {
        auto p = dir_ / ("bad" + std::to_string(i) + ".hdr");
        write_text(p, cases[i].text);
        std::string msg = expect_load_error(p);
        EXPECT_NE(msg.find(cases[i].expect), std::string::npos) << i << ": " << msg;
    }
}

TEST_F(ImageIoTest, BrokenPfmFiles) {
    std::vector<std::pair<std::string, std::string>> cases = {
        {"PF\n100000 100000\n-1\n", "too large"},
        {"PF\n-3 2\n-1\n", "invalid image size"},
        {"PF\n3 2\n0\n", "scale"},
        {"PF\n3 2\nnan\n", "scale"},
        {"PF\n1 1\n-1e39\n" + std::string(12, '\0'), "byte 7: scale '-1e39' is beyond float range"},
        {"PF\n3 x\n-1\n", "height"},
        {"PF\n3 2\n-1\n" + std::string(71, '\0'), "truncated pixel data"},
        {"PF\n3", "truncated PFM header"},
        {"PX\n3 2\n-1\n", "unrecognised"},
    };
    for (size_t i = 0; i < cases.size(); ++i) {
        auto p = dir_ / ("bad" + std::to_string(i) + ".pfm");
        write_text(p, cases[i].first);
        std::string msg = expect_load_error(p);
        EXPECT_NE(msg.find(cases[i].second), std::string::npos) << i << ": " << msg;
    }
    // A NaN pixel is named.
    ImageRGB img(4, 3);
    img.set(2, 1, Vec3f(0.0f, 0.0f, std::nanf("")));
    write_pfm(path("nan.pfm"), img);
    std::string msg = expect_load_error(dir_ / "nan.pfm");
    EXPECT_NE(msg.find("pixel 6: (x 2, y 1) channel B is NaN"), std::string::npos) << msg;
    img.set(2, 1, Vec3f(kInfinity, 0.0f, 0.0f));
    write_pfm(path("inf.pfm"), img);
    msg = expect_load_error(dir_ / "inf.pfm");
    EXPECT_NE(msg.find("infinite"), std::string::npos) << msg;
}

// Every prefix of a valid file, and files with corrupted bytes, must either load or throw
// kdt::Error; never crash or hang (this also runs under ASan+UBSan).
void truncate_and_corrupt(const std::filesystem::path& dir, const std::string& name,
                          const std::vector<uint8_t>& good, bool every_prefix_fails) {
    auto p = dir / ("cut_" + name);
    std::vector<size_t> cuts;
    for (size_t c = 0; c < good.size(); c += std::max<size_t>(1, good.size() / 37))
        cuts.push_back(c);
    cuts.push_back(good.size() - 1);
    for (size_t cut : cuts) {
        write_bytes(p, std::vector<uint8_t>(good.begin(), good.begin() + ptrdiff_t(cut)));
        if (every_prefix_fails) {
            EXPECT_THROW(load_image(p.string()), Error) << name << " cut at " << cut;
        } else {
            try {
                load_image(p.string());
            } catch (const Error&) {
            }
        }
    }
    HashRng rng(99);
    for (int i = 0; i < 60; ++i) {
        std::vector<uint8_t> bad = good;
        for (int k = 0; k < 3; ++k)
            bad[rng.next_u64() % bad.size()] ^= uint8_t(1 + rng.next_u64() % 255);
        write_bytes(p, bad);
        try {
            load_image(p.string());
        } catch (const Error&) {
        }
    }
}

TEST_F(ImageIoTest, TruncatedAndCorruptedFilesThrow) {
    ImageRGB img = random_image(24, 10, 5, 10.0f);
    write_hdr(path("g.hdr"), img);
    truncate_and_corrupt(dir_, "g.hdr", read_bytes(path("g.hdr")), true);
    write_pfm(path("g.pfm"), img);
    truncate_and_corrupt(dir_, "g.pfm", read_bytes(path("g.pfm")), true);
    write_png(path("g.png"), img, {}, {{"k", "v"}});
    truncate_and_corrupt(dir_, "g.png", read_bytes(path("g.png")), true);
    write_exr(path("g.exr"), img, {{"k", "v"}});
    truncate_and_corrupt(dir_, "g.exr", read_bytes(path("g.exr")), true);
}

// Found by tests/fuzz/image_fuzzer: a header line starting with a NUL byte ends the header
// for stb_image (it reads lines as C strings) but did not for our check, so the two read
// different resolution lines and stb_image returned a 0-pixel-wide image. Header lines are
// now read as stb_image reads them, and the decoded size must match the checked one.
TEST_F(ImageIoTest, HdrHeaderLineWithNulIsReadAsStbImageReadsIt) {
    const std::string file =
        std::string(KDT_SOURCE_DIR) + "/tests/fuzz/corpus/image/regress_nul_header_line.hdr";
    std::string msg;
    try {
        load_image(file);
    } catch (const Error& e) {
        msg = e.what();
    }
    EXPECT_EQ(msg.rfind(file + ": byte 139: unsupported resolution line '-Y 2 +X '", 0), 0u) << msg;
    // The same with a clean header: a NUL-led line ends it, then the resolution follows.
    std::vector<unsigned char> ok = {'#', '?', 'R', 'A', 'D', 'I', 'A', 'N', 'C', 'E', '\n'};
    for (char c : std::string("FORMAT=32-bit_rle_rgbe\n")) ok.push_back((unsigned char)c);
    ok.push_back(0);
    for (char c : std::string("junk\n-Y 1 +X 2\n")) ok.push_back((unsigned char)c);
    for (int i = 0; i < 2; ++i) {
        for (unsigned char b : {128, 128, 128, 129}) ok.push_back(b);  // (1, 1, 1) * 2^(129-136)
    }
    write_bytes(path("nul.hdr"), ok);
    const ImageRGB image = load_image(path("nul.hdr"));
    ASSERT_EQ(image.width, 2);
    ASSERT_EQ(image.height, 1);
    EXPECT_GT(image.rgb[0], 0.0f);
}

// A PNG with the given IHDR fields and zlib stream (one IDAT chunk), chunk CRCs correct.
std::vector<uint8_t> make_png(uint32_t width, uint32_t height, uint8_t depth, uint8_t color,
                              uint8_t interlace, const std::vector<uint8_t>& zlib_stream,
                              const std::vector<uint8_t>& palette = {}) {
    std::vector<uint8_t> out = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    auto be32 = [&](uint32_t v) {
        for (int s = 24; s >= 0; s -= 8) out.push_back(uint8_t(v >> s));
    };
    auto chunk = [&](const char* type, const std::vector<uint8_t>& body) {
        be32(uint32_t(body.size()));
        const size_t at = out.size();
        out.insert(out.end(), type, type + 4);
        out.insert(out.end(), body.begin(), body.end());
        be32(uint32_t(crc32(0L, &out[at], uInt(body.size() + 4))));
    };
    std::vector<uint8_t> ihdr;
    for (uint32_t v : {width, height})
        for (int s = 24; s >= 0; s -= 8) ihdr.push_back(uint8_t(v >> s));
    ihdr.insert(ihdr.end(), {depth, color, 0, 0, interlace});
    chunk("IHDR", ihdr);
    if (!palette.empty()) chunk("PLTE", palette);
    chunk("IDAT", zlib_stream);
    chunk("IEND", {});
    return out;
}

std::vector<uint8_t> zlib_of(const std::vector<uint8_t>& raw) {
    uLongf size = compressBound(uLong(raw.size()));
    std::vector<uint8_t> packed(size);
    EXPECT_EQ(compress2(packed.data(), &size, raw.data(), uLong(raw.size()), 6), Z_OK);
    packed.resize(size);
    return packed;
}

// `kdtrace info` checks a PNG's pixel data without decoding it (read_image_info() streams the
// IDAT data through zlib): broken data is an error as it is for load_image(), with the row or
// the truncation named; bytes after the last row are accepted as stb_image accepts them.
TEST_F(ImageIoTest, ImageInfoChecksPngPixelDataAsTheDecodeDoes) {
    // 5x4 RGB 8-bit: rows of 1 + 15 bytes; 3x3 grey 1-bit interlaced: passes 2 and 3 hold no
    // pixels, 1, 4, 5 and 7 one row of 1 + 1 bytes, 6 two such rows.
    std::vector<uint8_t> raw(4 * 16, 7);
    for (size_t y = 0; y < 4; ++y) raw[y * 16] = uint8_t(y);
    EXPECT_EQ(info_error(make_png(5, 4, 8, 2, 0, zlib_of(raw))), "");
    const ImageInfo info = read_image_info(path("p.png"));
    EXPECT_EQ(info.width, 5);
    EXPECT_EQ(info.height, 4);
    const std::vector<uint8_t> interlaced(2 * 6, 0);
    EXPECT_EQ(info_error(make_png(3, 3, 1, 0, 1, zlib_of(interlaced))), "");
    EXPECT_EQ(load_error(make_png(3, 3, 1, 0, 1, zlib_of(interlaced))), "");
    EXPECT_NE(info_error(make_png(3, 3, 1, 0, 1, zlib_of({0, 0, 0, 0})))
                  .find("ends in row 0 of "
                        "interlace pass 5"),
              std::string::npos);

    std::vector<uint8_t> bad = raw;
    bad[2 * 16] = 9;
    EXPECT_EQ(
        info_error(make_png(5, 4, 8, 2, 0, zlib_of(bad))),
        path("p.png") + ": byte 33: cannot decode PNG: row 2 has filter type 9 (0-4 allowed)");
    EXPECT_NE(load_error(make_png(5, 4, 8, 2, 0, zlib_of(bad))), "");
    bad.assign(raw.begin(), raw.end() - 1);
    const std::vector<uint8_t> short_png = make_png(5, 4, 8, 2, 0, zlib_of(bad));
    EXPECT_EQ(info_error(short_png), path("p.png") + ": byte " +
                                         std::to_string(short_png.size() - 12) +
                                         ": cannot decode PNG: image data ends in row 3 of 5x4");
    EXPECT_NE(load_error(make_png(5, 4, 8, 2, 0, zlib_of(bad))), "");
    bad = raw;
    bad.insert(bad.end(), 40, 0);
    EXPECT_EQ(info_error(make_png(5, 4, 8, 2, 0, zlib_of(bad))), "");
    EXPECT_EQ(load_error(make_png(5, 4, 8, 2, 0, zlib_of(bad))), "");
    // A zlib stream cut short, or with a wrong checksum.
    std::vector<uint8_t> z = zlib_of(raw);
    z.resize(z.size() - 6);
    EXPECT_NE(info_error(make_png(5, 4, 8, 2, 0, z)).find("zlib stream in IDAT ends early"),
              std::string::npos);
    z = zlib_of(raw);
    z.back() ^= 1;
    EXPECT_NE(info_error(make_png(5, 4, 8, 2, 0, z))
                  .find("cannot decode PNG: corrupt zlib stream in IDAT: incorrect data check"),
              std::string::npos);
    EXPECT_NE(info_error(make_png(5, 4, 3, 2, 0, zlib_of(raw))).find("bit depth 3"),
              std::string::npos);
    EXPECT_NE(info_error(make_png(5, 4, 8, 3, 0, zlib_of(raw))).find("without PLTE"),
              std::string::npos);
    // Whatever read_image_info() accepts, load_image() decodes: corrupted IDAT bytes with
    // their CRC put right.
    HashRng rng(7);
    const std::vector<uint8_t> good = make_png(5, 4, 8, 2, 0, zlib_of(raw));
    const size_t idat = 8 + 25, idat_size = good.size() - idat - 12 - 12;
    for (int i = 0; i < 200; ++i) {
        std::vector<uint8_t> png = good;
        png[idat + 8 + rng.next_u64() % (idat_size - 8)] ^= uint8_t(1 + rng.next_u64() % 255);
        const uLong crc = crc32(0L, &png[idat + 4], uInt(idat_size - 8 + 4));
        for (int k = 0; k < 4; ++k)
            png[idat + idat_size - 4 + size_t(k)] = uint8_t(crc >> (24 - 8 * k));
        if (info_error(png).empty()) {
            EXPECT_EQ(load_error(png), "") << i;
        }
    }
}

// A palette image's indices are checked once the row filters are undone, by info and by
// loading alike: stb_image reads an index past the palette from memory it never set.
TEST_F(ImageIoTest, PaletteIndicesPastThePaletteAreRefused) {
    const std::vector<uint8_t> two = {255, 0, 0, 0, 0, 255};  // 2 entries
    // 3x2, 8-bit indices. Row 0, Sub: 1, 0, 255 -> 1, 1, 0; row 1, Up: 0, 255, 1 -> 1, 0, 1.
    const std::vector<uint8_t> good = {1, 1, 0, 255, 2, 0, 255, 1};
    EXPECT_EQ(info_error(make_png(3, 2, 8, 3, 0, zlib_of(good), two)), "");
    EXPECT_EQ(load_error(make_png(3, 2, 8, 3, 0, zlib_of(good), two)), "");
    // Row 1, Up: 0, 1, 1 -> 1, 2, 1: index 2.
    const std::vector<uint8_t> bad = {1, 1, 0, 255, 2, 0, 1, 1};
    EXPECT_NE(info_error(make_png(3, 2, 8, 3, 0, zlib_of(bad), two))
                  .find("row 1: palette index 2 past the palette's 2 entries"),
              std::string::npos);
    EXPECT_NE(load_error(make_png(3, 2, 8, 3, 0, zlib_of(bad), two)).find("palette index 2"),
              std::string::npos);
    // 2-bit indices 1, 0, 1 and two padding bits set: the padding is no index.
    EXPECT_EQ(info_error(make_png(3, 1, 2, 3, 0, zlib_of({0, 0x47}), two)), "");
    EXPECT_NE(info_error(make_png(3, 1, 2, 3, 0, zlib_of({0, 0x4b}), two)).find("palette index 2"),
              std::string::npos);
    // A palette image without entries, and a depth its colour type does not allow.
    EXPECT_NE(load_error(make_png(3, 1, 2, 3, 0, zlib_of({0, 0x47}))).find("without PLTE"),
              std::string::npos);
    EXPECT_NE(load_error(make_png(3, 1, 1, 2, 0, zlib_of({0, 0}))).find("bit depth 1"),
              std::string::npos);
}

// An empty IDAT chunk before the data is valid PNG; stb_image would copy it from a null
// pointer (UBSan reports it), so it is dropped before decoding: the same image.
TEST_F(ImageIoTest, EmptyFirstIdatLoadsAsWithout) {
    const std::vector<uint8_t> raw = {0, 10, 20, 30, 40, 50, 60, 0, 70, 80, 90, 100, 110, 120};
    const std::vector<uint8_t> plain = make_png(2, 2, 8, 2, 0, zlib_of(raw));
    std::vector<uint8_t> with_empty = plain;
    const size_t idat = 8 + 12 + 13;  // after the signature and IHDR
    std::vector<uint8_t> empty = {0, 0, 0, 0, 'I', 'D', 'A', 'T'};
    const uint32_t crc = uint32_t(crc32(0L, &empty[4], 4));
    for (int k = 0; k < 4; ++k) empty.push_back(uint8_t(crc >> (24 - 8 * k)));
    with_empty.insert(with_empty.begin() + ptrdiff_t(idat), empty.begin(), empty.end());
    write_bytes(path("plain.png"), plain);
    write_bytes(path("empty.png"), with_empty);
    const ImageRGB a = load_image(path("plain.png")), b = load_image(path("empty.png"));
    EXPECT_EQ(a.rgb, b.rgb);
    EXPECT_EQ(b.width, 2);
}

#ifndef KDT_NO_ADDRESS_LIMIT
// Prints the size and encoding read_image_info() finds (or its error) under
// test::run_capped() with 64 MiB to spare. For a child process only.
[[noreturn]] void info_capped(const std::string& file) {
    test::run_capped(size_t(64) << 20, [&] {
        const ImageInfo info = read_image_info(file);
        std::fprintf(stderr, "%dx%d %s\n", info.width, info.height, info.encoding.c_str());
    });
}
#endif

// read_image_info() on a 11000x11000 PNG of 350 KB (zero rows) in a child process whose
// address space is capped 64 MiB above what it uses: decoding it would take 1.8 GB.
TEST_F(ImageIoTest, ImageInfoOfALargePngHoldsNoImage) {
#ifdef KDT_NO_ADDRESS_LIMIT
    GTEST_SKIP() << "sanitizers reserve more address space than any limit allows";
#else
    constexpr uint32_t kSide = 11000;
    const std::vector<uint8_t> row(1 + 3 * size_t(kSide), 0);
    std::vector<uint8_t> packed(16 << 20);
    z_stream zs{};
    ASSERT_EQ(deflateInit(&zs, 1), Z_OK);
    zs.next_out = packed.data();
    zs.avail_out = uInt(packed.size());
    for (uint32_t y = 0; y < kSide; ++y) {
        zs.next_in = const_cast<Bytef*>(row.data());
        zs.avail_in = uInt(row.size());
        ASSERT_EQ(deflate(&zs, y + 1 == kSide ? Z_FINISH : Z_NO_FLUSH),
                  y + 1 == kSide ? Z_STREAM_END : Z_OK);
        ASSERT_EQ(zs.avail_in, 0u);
    }
    packed.resize(zs.total_out);
    deflateEnd(&zs);
    write_bytes(path("big.png"), make_png(kSide, kSide, 8, 2, 0, packed));
    GTEST_FLAG_SET(death_test_style, "fast");
    EXPECT_EXIT(info_capped(path("big.png")), ::testing::ExitedWithCode(0),
                "^11000x11000 8-bit sRGB\n$");
#endif
}

}  // namespace
}  // namespace kdt
