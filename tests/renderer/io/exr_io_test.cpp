// Tests of renderer/io/exr_io.* through the image API: a round trip with every standard
// compression and the render metadata, files the OpenEXR library writes (PIZ, half, uint,
// grey, tiled), and truncated, corrupted and hostile files of each compression, which must
// throw kdt::Error naming the file (this also runs under ASan+UBSan).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/io/image_io.h"
#include "tests/renderer/io/exr_variants.h"
#include "tests/renderer/io/image_test_util.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

using test::expect_load_error;
using test::ExrVariant;
using test::HashRng;
using test::random_image;
using test::read_bytes;
using test::write_bytes;

class ExrIoTest : public ::testing::Test {
protected:
    void SetUp() override { dir_ = test::temp_dir("exr_io"); }
    void TearDown() override { std::filesystem::remove_all(dir_); }
    std::string path(const std::string& name) const { return (dir_ / name).string(); }
    std::filesystem::path dir_;
};

double mean_value(const ImageRGB& a) {
    double sum = 0.0;
    for (float v : a.rgb) sum += std::abs(double(v));
    return sum / double(a.rgb.size());
}

double mean_abs_difference(const ImageRGB& a, const ImageRGB& b) {
    double sum = 0.0;
    for (size_t i = 0; i < a.rgb.size(); ++i) sum += std::abs(double(a.rgb[i]) - b.rgb[i]);
    return sum / double(a.rgb.size());
}

const ImageMetadata kRenderMetadata = {
    {"Software", "kdtrace 0.1.0"},
    {"kdtrace:camera", "{\"eye\":[0,1,5],\"vfov\":40}"},
    {"kdtrace:command", "kdtrace render scene.json --spp 64 -o out.exr"},
    {"kdtrace:scene_json", "{\n  \"name\": \"caf\xc3\xa9\",\n  \"meshes\": []\n}\n"},
    {"kdtrace:seed", "12345"},
    {"kdtrace:a_key_longer_than_the_31_bytes_of_short_names", std::string("nul\0inside", 10)},
};

TEST_F(ExrIoTest, RoundTripOfEveryCompressionKeepsPixelsAndMetadata) {
    ImageRGB img = random_image(37, 21, 2, 1000.0f);
    img.set(5, 5, Vec3f(-2.0f, 0.0f, 1e-20f));
    ImageMetadata sorted = kRenderMetadata;
    std::sort(sorted.begin(), sorted.end());
    for (size_t c = 0; c < kExrCompressionNames.size(); ++c) {
        const std::string name = kExrCompressionNames[c];
        const std::string file = path(name + ".exr");
        write_exr(file, img, kRenderMetadata, ExrCompression(c));
        ImageMetadata read;
        const ImageRGB back = load_image(file, &read);
        ASSERT_EQ(back.width, img.width) << name;
        ASSERT_EQ(back.height, img.height) << name;
        if (name == "pxr24") {
            // 24-bit floats: 15 stored mantissa bits, rounded.
            for (size_t i = 0; i < img.rgb.size(); ++i) {
                ASSERT_NEAR(back.rgb[i], img.rgb[i], std::abs(img.rgb[i]) * 0x1p-15f) << i;
            }
        } else if (name == "dwaa" || name == "dwab") {
            EXPECT_LT(mean_abs_difference(back, img), 0.02 * mean_value(img)) << name;
        } else {
            EXPECT_EQ(back.rgb, img.rgb) << name;
        }
        EXPECT_EQ(read, sorted) << name;
        EXPECT_EQ(read_exr_metadata(file), sorted) << name;
        const ImageInfo info = read_image_info(file);
        EXPECT_EQ(info.format, "OpenEXR");
        EXPECT_EQ(info.width, 37);
        EXPECT_EQ(info.height, 21);
        EXPECT_EQ(info.encoding.rfind(name + " compression, scanlines", 0), 0u) << info.encoding;
        EXPECT_EQ(info.metadata, sorted);
    }
    // The default is ZIP, which write_image() uses for .exr.
    write_image(path("default.exr"), img, {}, kRenderMetadata);
    EXPECT_EQ(read_image_info(path("default.exr")).encoding.rfind("zip compression", 0), 0u);
}

TEST_F(ExrIoTest, KeysOpenExrCannotStoreAreRefused) {
    const ImageRGB img = random_image(4, 3, 1, 1.0f);
    const ImageMetadata bad[] = {{{"channels", "x"}},
                                 {{"compression", "none"}},
                                 {{"", "empty"}},
                                 {{std::string("nu\0l", 4), "x"}},
                                 {{std::string(256, 'k'), "too long"}},
                                 {{"twice", "1"}, {"twice", "2"}}};
    for (const ImageMetadata& md : bad) {
        try {
            write_exr(path("bad.exr"), img, md);
            ADD_FAILURE() << "key '" << md.back().first << "' accepted";
        } catch (const Error& e) {
            EXPECT_EQ(std::string(e.what()).rfind(path("bad.exr") + ": ", 0), 0u) << e.what();
        }
        EXPECT_FALSE(std::filesystem::exists(path("bad.exr")));
    }
    write_exr(path("ok.exr"), img, {{std::string(255, 'k'), "longest key"}});
    EXPECT_EQ(read_exr_metadata(path("ok.exr")).at(0).second, "longest key");
}

TEST_F(ExrIoTest, ReadsPizHalfUintGreyAndTiledFilesFromTheLibrary) {
    struct Case {
        ExrVariant v;
        const char* encoding;
    } cases[] = {
        {{8, 4, Imf::HALF, Imf::PIZ_COMPRESSION}, "piz compression, scanlines; channels B (half)"},
        {{67, 45, Imf::FLOAT, Imf::PIZ_COMPRESSION}, "piz compression, scanlines"},
        {{9, 40, Imf::HALF, Imf::PIZ_COMPRESSION, true}, "piz compression, scanlines; channels Y"},
        {{10, 7, Imf::HALF, Imf::PIZ_COMPRESSION, false, 4}, "piz compression, 4x4 tiles"},
        {{10, 7, Imf::FLOAT, Imf::ZIP_COMPRESSION, false, 3}, "zip compression, 3x3 tiles"},
        {{8, 4, Imf::UINT, Imf::RLE_COMPRESSION, true}, "rle compression, scanlines; channels Y"},
        {{8, 4, Imf::HALF, Imf::NO_COMPRESSION}, "none compression"},
        {{8, 4, Imf::HALF, Imf::B44_COMPRESSION}, "b44 compression"},
        {{16, 16, Imf::HALF, Imf::DWAB_COMPRESSION}, "dwab compression"},
    };
    for (const Case& c : cases) {
        const std::string file = path("variant.exr");
        write_bytes(file, test::exr_variant(c.v));
        const ImageRGB back = load_image(file);
        ASSERT_EQ(back.width, c.v.width) << c.encoding;
        ASSERT_EQ(back.height, c.v.height) << c.encoding;
        // B44 and DWA are lossy on half channels; the others keep the values exactly.
        const bool lossy =
            c.v.compression == Imf::B44_COMPRESSION || c.v.compression == Imf::DWAB_COMPRESSION;
        ImageRGB want_image(c.v.width, c.v.height);
        for (int y = 0; y < c.v.height; ++y) {
            for (int x = 0; x < c.v.width; ++x) {
                for (int ch = 0; ch < 3; ++ch) {
                    const float want = test::exr_variant_value(x, y, c.v.grey ? 0 : ch);
                    const float got = back.at(x, y)[ch];
                    if (lossy) {
                        want_image
                            .rgb[(size_t(y) * size_t(c.v.width) + size_t(x)) * 3 + size_t(ch)] =
                            want;
                    } else {
                        ASSERT_EQ(got, c.v.type == Imf::UINT ? std::floor(want) : want)
                            << c.encoding << " at " << x << "," << y;
                    }
                }
            }
        }
        if (lossy) {
            EXPECT_LT(mean_abs_difference(back, want_image), 0.1 * mean_value(want_image))
                << c.encoding;
        }
        const std::string encoding = read_image_info(file).encoding;
        EXPECT_NE(encoding.find(c.encoding), std::string::npos) << encoding;
    }
}

/// The message of the kdt::Error that decoding bytes named `name` throws, which must start
/// with the name; "" and a test failure when they decode.
std::string decode_error(const std::vector<uint8_t>& bytes, const std::string& name) {
    try {
        load_image_memory(bytes, name);
    } catch (const Error& e) {
        EXPECT_EQ(std::string(e.what()).rfind(name + ": ", 0), 0u) << e.what();
        return e.what();
    }
    ADD_FAILURE() << "no error for " << name;
    return "";
}

/// Every 1/50th prefix of a good file must throw an Error naming the file; files with a few
/// bytes flipped (seeded) must load or throw one. Decoded from memory: the disk is slow here.
void expect_truncated_and_corrupted_fail(const std::string& name,
                                         const std::vector<uint8_t>& good) {
    for (size_t cut = 0; cut < good.size(); cut += std::max<size_t>(1, good.size() / 50)) {
        SCOPED_TRACE(name + " cut at " + std::to_string(cut));
        decode_error(std::vector<uint8_t>(good.begin(), good.begin() + ptrdiff_t(cut)), name);
    }
    decode_error(std::vector<uint8_t>(good.begin(), good.end() - 1), name);
    HashRng rng(17);
    int failed = 0;
    for (int i = 0; i < 150; ++i) {
        std::vector<uint8_t> bad = good;
        // Past the 8-byte magic and version, so that most inputs reach the decoder.
        for (int k = 0; k < 1 + i % 4; ++k)
            bad[8 + rng.next_u64() % (bad.size() - 8)] ^= uint8_t(1 + rng.next_u64() % 255);
        try {
            const ImageRGB image = load_image_memory(bad, name);
            EXPECT_EQ(image.rgb.size(), image.pixel_count() * 3);
        } catch (const Error& e) {
            EXPECT_EQ(std::string(e.what()).rfind(name + ": ", 0), 0u) << e.what();
            ++failed;
        }
    }
    EXPECT_GT(failed, 0) << name << ": no corruption was noticed";
}

TEST_F(ExrIoTest, TruncatedAndCorruptedFilesOfEveryCompressionAreErrors) {
    const ImageRGB img = random_image(40, 36, 5, 10.0f);
    for (size_t c = 0; c < kExrCompressionNames.size(); ++c) {
        const std::string file = path(std::string(kExrCompressionNames[c]) + ".exr");
        write_exr(file, img, {{"kdtrace:seed", "1"}}, ExrCompression(c));
        expect_truncated_and_corrupted_fail(file, read_bytes(file));
        // And one truncated file from disk.
        const std::vector<uint8_t> good = read_bytes(file);
        write_bytes(file, std::vector<uint8_t>(good.begin(), good.begin() + 100));
        expect_load_error(file);
    }
    ExrVariant tiled_piz{24, 20, Imf::HALF, Imf::PIZ_COMPRESSION, false, 8};
    expect_truncated_and_corrupted_fail("tiled_piz.exr", test::exr_variant(tiled_piz));
}

/// The message of the kdt::Error read_image_info(file) throws, "" when it throws none.
std::string info_error(const std::string& file) {
    try {
        read_image_info(file);
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

// `info` reads an EXR's pixels too: a file cut short behind an intact header (the offset
// table points past its end) is an error, as load_image() gives, for channels of any name
// and sampling -- not the header printed as if the file were fine.
TEST_F(ExrIoTest, InfoOnAFileTruncatedBehindItsHeaderIsAnError) {
    const ImageRGB img = random_image(40, 36, 5, 10.0f);
    for (size_t c = 0; c < kExrCompressionNames.size(); ++c) {
        const std::string file = path(std::string(kExrCompressionNames[c]) + ".exr");
        write_exr(file, img, {{"kdtrace:seed", "1"}}, ExrCompression(c));
        EXPECT_EQ(info_error(file), "") << file;
        const std::vector<uint8_t> good = read_bytes(file);
        for (const size_t cut : {good.size() - 1, good.size() * 3 / 4}) {
            write_bytes(file, std::vector<uint8_t>(good.begin(), good.begin() + ptrdiff_t(cut)));
            EXPECT_EQ(info_error(file).rfind(file + ": corrupt OpenEXR file: ", 0), 0u)
                << file << " cut at " << cut << ": " << info_error(file);
        }
    }
    // Channels load_image() does not read: a depth channel and 2x2 subsampled chroma.
    const std::string file = path("zchroma.exr");
    {
        const int w = 16, h = 12;
        Imf::Header header(w, h);
        header.compression() = Imf::NO_COMPRESSION;
        header.channels().insert("Z", Imf::Channel(Imf::FLOAT));
        header.channels().insert("BY", Imf::Channel(Imf::HALF, 2, 2));
        std::vector<float> z(size_t(w * h), 1.5f);
        std::vector<half> by(size_t(w * h / 4), half(0.25f));
        Imf::FrameBuffer fb;
        fb.insert("Z", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(z.data()), sizeof(float),
                                  sizeof(float) * w));
        fb.insert("BY", Imf::Slice(Imf::HALF, reinterpret_cast<char*>(by.data()), sizeof(half),
                                   sizeof(half) * (w / 2), 2, 2));
        Imf::OutputFile out(file.c_str(), header);
        out.setFrameBuffer(fb);
        out.writePixels(h);
    }
    EXPECT_EQ(info_error(file), "");
    EXPECT_NE(read_image_info(file).encoding.find("channels BY (half) Z (float)"),
              std::string::npos);
    const std::vector<uint8_t> good = read_bytes(file);
    write_bytes(file, std::vector<uint8_t>(good.begin(), good.end() - 1));
    EXPECT_EQ(info_error(file).rfind(file + ": corrupt OpenEXR file: ", 0), 0u) << info_error(file);
}

// The library decodes the full-size level of a mipmapped or ripmapped file only: a file cut
// short in its smaller levels is still refused, by load_image() (an --env map) and by `info`,
// naming the level, as every other file cut short is.
TEST_F(ExrIoTest, MipmapAndRipmapFilesCutShortInAnyLevelAreErrors) {
    for (const Imf::LevelMode levels : {Imf::MIPMAP_LEVELS, Imf::RIPMAP_LEVELS}) {
        for (const Imf::LevelRoundingMode rounding : {Imf::ROUND_DOWN, Imf::ROUND_UP}) {
            ExrVariant v{13, 6, Imf::HALF, Imf::ZIP_COMPRESSION, false, 4};
            v.levels = levels;
            v.rounding = rounding;
            const std::string name = std::string(levels == Imf::MIPMAP_LEVELS ? "mip" : "rip") +
                                     (rounding == Imf::ROUND_UP ? "_up" : "_down") + ".exr";
            SCOPED_TRACE(name);
            const std::vector<uint8_t> good = test::exr_variant(v);
            const ImageRGB whole = load_image_memory(good, name);
            ASSERT_EQ(whole.width, 13);
            ASSERT_EQ(whole.height, 6);
            EXPECT_EQ(whole.at(12, 5)[1], test::exr_variant_value(12, 5, 1));
            const std::string file = path(name);
            write_bytes(file, good);
            EXPECT_EQ(info_error(file), "");
            // The last tile in the file is that of the 1x1 level; every cut from a quarter of
            // the file on leaves the full-size level whole in some of them.
            const std::string last =
                levels == Imf::MIPMAP_LEVELS
                    ? (rounding == Imf::ROUND_UP ? "mipmap level 4 (1x1)" : "mipmap level 3 (1x1)")
                    : (rounding == Imf::ROUND_UP ? "ripmap level 4,3 (1x1)"
                                                 : "ripmap level 3,2 (1x1)");
            EXPECT_NE(decode_error(std::vector<uint8_t>(good.begin(), good.end() - 1), name)
                          .find(": truncated OpenEXR file: " + last +
                                " has a tile that runs past "
                                "the end of the file (the file has " +
                                std::to_string(good.size() - 1) + " bytes)"),
                      std::string::npos);
            for (size_t cut = good.size() / 4; cut < good.size(); ++cut) {
                SCOPED_TRACE("cut at " + std::to_string(cut));
                const std::vector<uint8_t> part(good.begin(), good.begin() + ptrdiff_t(cut));
                decode_error(part, name);
                if (cut % 16 != 0 && cut != good.size() - 1) continue;  // the disk is slow
                write_bytes(file, part);
                EXPECT_EQ(info_error(file).rfind(file + ": ", 0), 0u) << info_error(file);
            }
        }
    }
}

/// Offset of the value of the header attribute `name` in an EXR file's bytes.
size_t attribute_value(const std::vector<uint8_t>& bytes, const std::string& name) {
    size_t pos = 8;
    while (bytes.at(pos) != 0) {
        const std::string n(reinterpret_cast<const char*>(&bytes[pos]));
        pos += n.size() + 1;
        pos += std::strlen(reinterpret_cast<const char*>(&bytes[pos])) + 1;
        uint32_t size = 0;
        std::memcpy(&size, &bytes.at(pos), 4);
        pos += 4;
        if (n == name) return pos;
        pos += size;
    }
    ADD_FAILURE() << "no attribute " << name;
    return 0;
}

// Headers that ask for more than the file can hold are refused before anything is allocated
// for them (the fuzzers' rss limit and the ASan build would see a large allocation).
TEST_F(ExrIoTest, HostileHeadersAreRefusedBeforeAllocating) {
    write_exr(path("ok.exr"), random_image(4, 3, 9, 1.0f));
    const std::vector<uint8_t> good = read_bytes(path("ok.exr"));
    auto with_window = [&](std::vector<uint8_t> bytes, int32_t max_x, int32_t max_y) {
        const size_t at = attribute_value(bytes, "dataWindow");
        std::memcpy(&bytes[at + 8], &max_x, 4);
        std::memcpy(&bytes[at + 12], &max_y, 4);
        return bytes;
    };
    write_bytes(path("huge.exr"), with_window(good, 59999, 59999));
    std::string msg = expect_load_error(path("huge.exr"));
    EXPECT_NE(msg.find("60000x60000 is out of range"), std::string::npos) << msg;
    write_bytes(path("wide.exr"), with_window(good, 2000000000, 0));
    expect_load_error(path("wide.exr"));
    write_bytes(path("negative.exr"), with_window(good, -5, 2));
    expect_load_error(path("negative.exr"));
    // 4000x4000 pixels in 1x1 tiles: an offset table of 128 MB in a file of a few hundred bytes.
    ExrVariant tiny_tiles{2, 2, Imf::HALF, Imf::NO_COMPRESSION, false, 1};
    write_bytes(path("tiles.exr"), with_window(test::exr_variant(tiny_tiles), 3999, 3999));
    msg = expect_load_error(path("tiles.exr"));
    EXPECT_NE(msg.find("offset table of 16000000 blocks does not fit"), std::string::npos) << msg;
    // Tiles far larger than the image (the library buffers a row of them).
    std::vector<uint8_t> big_tiles = test::exr_variant(tiny_tiles);
    const uint32_t huge_tile = 60000;
    std::memcpy(&big_tiles[attribute_value(big_tiles, "tiles")], &huge_tile, 4);
    write_bytes(path("big_tiles.exr"), big_tiles);
    msg = expect_load_error(path("big_tiles.exr"));
    EXPECT_NE(msg.find("tiles of 60000x1 are larger than the 2x2 image"), std::string::npos) << msg;
    // The same for scanlines: 60000 lines of ZIP blocks.
    write_bytes(path("lines.exr"), with_window(good, 3, 59999));
    msg = expect_load_error(path("lines.exr"));
    EXPECT_NE(msg.find("offset table of 3750 blocks does not fit"), std::string::npos) << msg;
    // Not an OpenEXR feature we read: multi-part or deep (version flags).
    std::vector<uint8_t> multi = good;
    multi[5] |= 0x10;
    write_bytes(path("multi.exr"), multi);
    msg = expect_load_error(path("multi.exr"));
    EXPECT_NE(msg.find("multi-part"), std::string::npos) << msg;
    // An attribute value running past the end of the file.
    std::vector<uint8_t> past(good.begin(), good.begin() + 8);
    for (char ch : std::string("channels\0chlist\0\xff\xff\0\0", 20)) past.push_back(uint8_t(ch));
    write_bytes(path("past.exr"), past);
    msg = expect_load_error(path("past.exr"));
    EXPECT_NE(msg.find("attribute 'channels' runs past the end of the file"), std::string::npos)
        << msg;
}

// Found by the image fuzzer: a channel list one byte longer than its stated size (the
// library reads a channel list to its end, whatever the size) put the library's reading out
// of step with the stated sizes, and it then allocated 1.9 GB for an attribute.
TEST_F(ExrIoTest, ChannelListLongerThanItsSizeIsAnError) {
    const std::string file =
        std::string(KDT_SOURCE_DIR) + "/tests/fuzz/corpus/image/regress_chlist_size.exr";
    const std::string msg = expect_load_error(file);
    EXPECT_NE(msg.find("malformed attribute 'channels' of type chlist (54 bytes)"),
              std::string::npos)
        << msg;
    // A fixed-size type with another size.
    write_exr(path("ok.exr"), random_image(4, 3, 9, 1.0f));
    std::vector<uint8_t> bytes = read_bytes(path("ok.exr"));
    const size_t at = attribute_value(bytes, "dataWindow");
    bytes[at - 4] = 12;
    write_bytes(path("box.exr"), bytes);
    EXPECT_NE(
        expect_load_error(path("box.exr")).find("malformed attribute 'dataWindow' of type box2i"),
        std::string::npos);
}

// The seed corpus of the image fuzzer, and the reproducers kept in it, must load or fail
// cleanly (a regression test of whatever the fuzzer found).
TEST_F(ExrIoTest, FuzzCorpusLoadsOrFailsNamingTheFile) {
    const auto dir = std::filesystem::path(KDT_SOURCE_DIR) / "tests/fuzz/corpus/image";
    int exr = 0;
    for (const auto& entry : std::filesystem::directory_iterator(dir)) {
        const std::string file = entry.path().string();
        if (entry.path().extension() != ".exr") continue;
        ++exr;
        try {
            const ImageRGB image = load_image(file);
            EXPECT_EQ(image.rgb.size(), image.pixel_count() * 3) << file;
        } catch (const Error& e) {
            EXPECT_EQ(std::string(e.what()).rfind(file + ": ", 0), 0u) << e.what();
        }
    }
    EXPECT_GE(exr, 4);
}

}  // namespace
}  // namespace kdt
