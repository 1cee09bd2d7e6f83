// Tests of renderer/io/image_io.*: round trips (PFM and float EXR exact, PNG within
// quantisation, HDR within RGBE precision), metadata read back, and broken files that must
// throw kdt::Error naming the file instead of crashing, hanging or allocating absurdly.
#include "renderer/io/image_io.h"

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>

#include <gtest/gtest.h>

#include "renderer/core/color.h"
#include "renderer/core/error.h"
#include "tests/test_util.h"

#if __has_include(<tinyexr.h>)
#include <tinyexr.h>
#endif

namespace kdt {
namespace {

using test::HashRng;
using test::read_bytes;
using test::write_bytes;

ImageRGB random_image(int w, int h, uint64_t seed, float scale) {
    ImageRGB img(w, h);
    HashRng rng(seed);
    for (float& v : img.rgb) v = scale * rng.next();
    return img;
}

void write_text(const std::filesystem::path& p, const std::string& s) {
    write_bytes(p, std::vector<uint8_t>(s.begin(), s.end()));
}

/// load_image must throw kdt::Error whose message names the file; returns the message.
std::string expect_load_error(const std::filesystem::path& p) {
    try {
        load_image(p.string());
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find(p.string()), std::string::npos) << e.what();
        return e.what();
    }
    ADD_FAILURE() << "no error for " << p;
    return "";
}

class ImageIoTest : public ::testing::Test {
protected:
    void SetUp() override { dir_ = test::temp_dir("image_io"); }
    void TearDown() override { std::filesystem::remove_all(dir_); }
    std::string path(const std::string& name) const { return (dir_ / name).string(); }
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

TEST_F(ImageIoTest, ExrRoundTripIsExactWithMetadata) {
    ImageRGB img = random_image(33, 17, 2, 1000.0f);
    img.set(5, 5, Vec3f(-2.0f, 0.0f, 1e-20f));
    ImageMetadata md = {{"kdtrace.camera", "{\"eye\":[0,1,5],\"vfov\":40}"},
                        {"kdtrace.seed", "12345"},
                        {"kdtrace.command", "kdtrace render scene.json --spp 64 -o out.exr"}};
    write_exr(path("a.exr"), img, md);
    ImageMetadata read;
    ImageRGB back = load_image(path("a.exr"), &read);
    ASSERT_EQ(back.width, 33);
    ASSERT_EQ(back.height, 17);
    EXPECT_EQ(back.rgb, img.rgb);
    EXPECT_EQ(read, md);
    EXPECT_EQ(read_exr_metadata(path("a.exr")), md);
    EXPECT_THROW(write_exr(path("b.exr"), img, {{"channels", "x"}}), Error);
}

#if __has_include(<tinyexr.h>)
TEST_F(ImageIoTest, ExrHalfRgbaAndSingleChannelFilesFromTinyexr) {
    // Files written by tinyexr's own SaveEXR: half-float RGBA (alpha dropped) and one channel.
    ImageRGB img = random_image(9, 5, 6, 4.0f);
    std::vector<float> rgba(img.pixel_count() * 4, 0.25f);
    for (size_t i = 0; i < img.pixel_count(); ++i) {
        for (int c = 0; c < 3; ++c) rgba[i * 4 + size_t(c)] = img.rgb[i * 3 + size_t(c)];
    }
    const char* err = nullptr;
    ASSERT_EQ(SaveEXR(rgba.data(), 9, 5, 4, 1, path("half.exr").c_str(), &err), TINYEXR_SUCCESS);
    ImageRGB back = load_image(path("half.exr"));
    ASSERT_EQ(back.width, 9);
    for (size_t i = 0; i < img.rgb.size(); ++i) {
        ASSERT_NEAR(back.rgb[i], img.rgb[i], img.rgb[i] / 1024.0f + 1e-6f) << "half precision";
    }
    std::vector<float> grey(img.pixel_count());
    for (size_t i = 0; i < grey.size(); ++i) grey[i] = float(i);
    ASSERT_EQ(SaveEXR(grey.data(), 9, 5, 1, 0, path("grey.exr").c_str(), &err), TINYEXR_SUCCESS);
    back = load_image(path("grey.exr"));
    EXPECT_EQ(back.at(4, 2), Vec3f(22.0f));
}

// Found by tests/fuzz/image_fuzzer: a PIZ block whose bitmap range runs past the end of the
// file made tinyexr's decoder read out of bounds. PIZ files are now refused up front.
TEST_F(ImageIoTest, ExrPizCompressionIsRefusedNamingTheFile) {
    std::vector<float> planes[3];
    unsigned char* ptrs[3];
    EXRChannelInfo channels[3];
    std::memset(channels, 0, sizeof(channels));
    int types[3] = {TINYEXR_PIXELTYPE_FLOAT, TINYEXR_PIXELTYPE_FLOAT, TINYEXR_PIXELTYPE_FLOAT};
    for (int c = 0; c < 3; ++c) {
        planes[c].assign(8 * 4, 0.5f);
        ptrs[c] = reinterpret_cast<unsigned char*>(planes[c].data());
        channels[c].name[0] = "BGR"[c];
    }
    EXRHeader header;
    InitEXRHeader(&header);
    header.num_channels = 3;
    header.channels = channels;
    header.pixel_types = types;
    header.requested_pixel_types = types;
    header.compression_type = TINYEXR_COMPRESSIONTYPE_PIZ;
    EXRImage image;
    InitEXRImage(&image);
    image.num_channels = 3;
    image.width = 8;
    image.height = 4;
    image.images = ptrs;
    const char* err = nullptr;
    ASSERT_EQ(SaveEXRImageToFile(&image, &header, path("piz.exr").c_str(), &err), TINYEXR_SUCCESS);
    const std::string message = expect_load_error(path("piz.exr"));
    EXPECT_NE(message.find("PIZ-compressed OpenEXR is not supported"), std::string::npos)
        << message;
}

// Found by tests/fuzz/image_fuzzer: a chunkCount attribute of 1.7e9 made tinyexr allocate a
// 13 GB offset table before reading it. The table must fit in the file.
TEST_F(ImageIoTest, ExrChunkCountBeyondTheFileIsAnError) {
    write_exr(path("ok.exr"), random_image(4, 3, 9, 1.0f));
    std::vector<uint8_t> bytes = read_bytes(path("ok.exr"));
    // A chunkCount attribute (name, type, size 4, value) inserted as the header's first.
    const char attr[] = "chunkCount\0int";
    std::vector<uint8_t> insert(attr, attr + sizeof(attr));
    for (uint32_t v : {4u, 0x7fffffffu}) {
        for (int b = 0; b < 4; ++b) insert.push_back(uint8_t(v >> (8 * b)));
    }
    bytes.insert(bytes.begin() + 8, insert.begin(), insert.end());
    write_bytes(path("chunks.exr"), bytes);
    const std::string message = expect_load_error(path("chunks.exr"));
    EXPECT_NE(message.find("offset table of 2147483647 blocks does not fit"), std::string::npos)
        << message;
}

// Found by tests/fuzz/image_fuzzer: tinyexr reads 9 bytes of a "tiles" attribute whatever
// its size (it only asserts).
TEST_F(ImageIoTest, ExrMalformedAttributesAreErrors) {
    const ImageRGB image = random_image(4, 3, 9, 1.0f);
    write_exr(path("ok.exr"), image);
    const std::vector<uint8_t> good = read_bytes(path("ok.exr"));
    // `attribute` is name, type and value; the size is filled in. Inserted as the first.
    auto with_attribute = [&](const std::string& attribute, const std::string& file) {
        const size_t name_and_type =
            std::strlen(attribute.c_str()) + 1 +
            std::strlen(attribute.c_str() + std::strlen(attribute.c_str()) + 1) + 1;
        const uint32_t size = uint32_t(attribute.size() - name_and_type);
        std::vector<uint8_t> insert(attribute.begin(), attribute.begin() + long(name_and_type));
        for (int b = 0; b < 4; ++b) insert.push_back(uint8_t(size >> (8 * b)));
        insert.insert(insert.end(), attribute.begin() + long(name_and_type), attribute.end());
        std::vector<uint8_t> bytes = good;
        bytes.insert(bytes.begin() + 8, insert.begin(), insert.end());
        write_bytes(file, bytes);
    };
    struct Case {
        std::string attribute;
        const char* expect;
    } cases[] = {
        {std::string("tiles\0tiledesc\0", 15) + "abc", "malformed attribute 'tiles' (3 bytes)"},
        {std::string("compression\0compression\0", 24), "malformed attribute 'compression'"},
    };
    int i = 0;
    for (const Case& c : cases) {
        const std::string file = path("attr" + std::to_string(i++) + ".exr");
        with_attribute(c.attribute, file);
        const std::string message = expect_load_error(file);
        EXPECT_NE(message.find(c.expect), std::string::npos) << message;
    }
    // OpenEXR writes string attributes without a terminating NUL; tinyexr terminates "name"
    // and "type" itself, so such a file is valid and loads. The offset table (after the
    // header's final NUL; the first offset points past the table) moves with the insert.
    const std::string type_attr = std::string("type\0string\0", 12) + "scanlineimage";
    with_attribute(type_attr, path("type.exr"));
    std::vector<uint8_t> typed_bytes = read_bytes(path("type.exr"));
    size_t pos = 8;
    while (typed_bytes.at(pos) != 0) {
        pos += std::strlen(reinterpret_cast<const char*>(&typed_bytes[pos])) + 1;
        pos += std::strlen(reinterpret_cast<const char*>(&typed_bytes[pos])) + 1;
        uint32_t size = 0;
        std::memcpy(&size, &typed_bytes.at(pos), 4);
        pos += 4 + size;
    }
    const size_t table = pos + 1, shift = type_attr.size() + 4;
    uint64_t first = 0;
    std::memcpy(&first, &typed_bytes.at(table), 8);
    const size_t chunks = (size_t(first) + shift - table) / 8;
    for (size_t c = 0; c < chunks; ++c) {
        uint64_t offset = 0;
        std::memcpy(&offset, &typed_bytes.at(table + 8 * c), 8);
        offset += shift;
        std::memcpy(&typed_bytes.at(table + 8 * c), &offset, 8);
    }
    write_bytes(path("type.exr"), typed_bytes);
    const ImageRGB typed = load_image(path("type.exr"));
    ASSERT_EQ(typed.width, image.width);
    ASSERT_EQ(typed.height, image.height);
    EXPECT_EQ(typed.rgb, image.rgb);
    // A value running past the end of the file.
    const char tail[] = "channels\0chlist\0\xff\xff\0\0";
    std::string past(good.begin(), good.begin() + 8);
    past.append(tail, sizeof(tail) - 1);
    write_bytes(path("past.exr"), std::vector<uint8_t>(past.begin(), past.end()));
    const std::string message = expect_load_error(path("past.exr"));
    EXPECT_NE(message.find("attribute 'channels' runs past the end of the file"), std::string::npos)
        << message;
}

TEST_F(ImageIoTest, ExrTiledFileFromTinyexr) {
    // A 10x7 float RGB image in 4x4 tiles (edge tiles partial), written with tinyexr.
    const int w = 10, h = 7, ts = 4, tx = 3, ty = 2;
    ImageRGB img = random_image(w, h, 8, 3.0f);
    std::vector<EXRTile> tiles(tx * ty);
    std::vector<std::vector<float>> planes(tiles.size() * 3);
    std::vector<std::array<unsigned char*, 3>> ptrs(tiles.size());
    for (int t = 0; t < tx * ty; ++t) {
        EXRTile& tile = tiles[size_t(t)];
        std::memset(&tile, 0, sizeof(tile));
        tile.offset_x = t % tx;
        tile.offset_y = t / tx;
        tile.width = std::min(ts, w - tile.offset_x * ts);
        tile.height = std::min(ts, h - tile.offset_y * ts);
        for (int c = 0; c < 3; ++c) {
            auto& plane = planes[size_t(t * 3 + c)];
            plane.assign(ts * ts, 0.0f);
            for (int j = 0; j < tile.height; ++j) {
                for (int i = 0; i < tile.width; ++i) {
                    // Channels are stored B, G, R.
                    plane[size_t(j * ts + i)] =
                        img.at(tile.offset_x * ts + i, tile.offset_y * ts + j)[2 - c];
                }
            }
            ptrs[size_t(t)][size_t(c)] = reinterpret_cast<unsigned char*>(plane.data());
        }
        tile.images = ptrs[size_t(t)].data();
    }
    EXRChannelInfo channels[3];
    std::memset(channels, 0, sizeof(channels));
    channels[0].name[0] = 'B';
    channels[1].name[0] = 'G';
    channels[2].name[0] = 'R';
    int types[3] = {TINYEXR_PIXELTYPE_FLOAT, TINYEXR_PIXELTYPE_FLOAT, TINYEXR_PIXELTYPE_FLOAT};
    EXRHeader header;
    InitEXRHeader(&header);
    header.num_channels = 3;
    header.channels = channels;
    header.pixel_types = types;
    header.requested_pixel_types = types;
    header.tiled = 1;
    header.data_window = {0, 0, w - 1, h - 1};
    header.display_window = header.data_window;
    header.tile_size_x = ts;
    header.tile_size_y = ts;
    header.tile_level_mode = TINYEXR_TILE_ONE_LEVEL;
    header.compression_type = TINYEXR_COMPRESSIONTYPE_ZIP;
    EXRImage image;
    InitEXRImage(&image);
    image.num_channels = 3;
    image.width = w;
    image.height = h;
    image.tiles = tiles.data();
    image.num_tiles = tx * ty;
    const char* err = nullptr;
    int ret = SaveEXRImageToFile(&image, &header, path("tiled.exr").c_str(), &err);
    if (ret != TINYEXR_SUCCESS) {
        std::string message = err ? err : "";
        FreeEXRErrorMessage(err);
        GTEST_SKIP() << "this tinyexr cannot write tiled files: " << message;
    }
    ImageRGB back = load_image(path("tiled.exr"));
    ASSERT_EQ(back.width, w);
    ASSERT_EQ(back.height, h);
    EXPECT_EQ(back.rgb, img.rgb);
}
#endif

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
    auto data = test::shared_data_dir();
    if (data.empty() || !std::filesystem::exists(data / "probes" / "grace.hdr")) {
        GTEST_SKIP() << "../shared/data/probes not found (set KDT_SHARED_DATA)";
    }
    ImageRGB grace = load_image((data / "probes" / "grace.hdr").string());
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

// Found by tests/fuzz/image_fuzzer: an uncompressed block ending at the end of the file made
// tinyexr read up to 3 bytes past the buffer (the ASan build sees it). Decoded from a padded
// copy now: the file loads or fails with an error naming it, and nothing is read past it.
TEST_F(ImageIoTest, ExrBlockEndingAtTheEndOfTheFileIsReadInBounds) {
    const std::string file =
        std::string(KDT_SOURCE_DIR) + "/tests/fuzz/corpus/image/regress_block_at_end.exr";
    try {
        const ImageRGB image = load_image(file);
        EXPECT_GT(image.width, 0);
        EXPECT_GT(image.height, 0);
    } catch (const Error& e) {
        EXPECT_EQ(std::string(e.what()).rfind(file, 0), 0u) << e.what();
    }
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

}  // namespace
}  // namespace kdt
