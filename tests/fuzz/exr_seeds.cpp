// Writes the OpenEXR seeds of the image fuzzer's corpus: float RGB with the render metadata
// in each lossless compression (PIZ, ZIP, RLE, none) through write_exr(), and files our
// writer does not make (half PIZ tiles, uint grey RLE, half ZIPS, half B44) through the
// OpenEXR library. Run from the repository root after building the `fuzz` preset:
//   build/fuzz/tests/exr_seeds tests/fuzz/corpus/image
#include <cstdio>
#include <filesystem>
#include <string>

#include "renderer/core/error.h"
#include "renderer/io/image_io.h"
#include "tests/renderer/io/exr_variants.h"
#include "tests/test_util.h"

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: exr_seeds <image corpus directory>\n");
        return 2;
    }
    namespace fs = std::filesystem;
    try {
        const fs::path dir = argv[1];
        fs::create_directories(dir);
        kdt::ImageRGB image(6, 5);
        for (int y = 0; y < 5; ++y) {
            for (int x = 0; x < 6; ++x)
                image.set(x, y, kdt::Vec3f(0.5f * float(x), float(y), 3.0f));
        }
        const kdt::ImageMetadata metadata = {{"kdtrace:seed", "7"},
                                             {"kdtrace:command", "kdtrace render -o a.exr"}};
        for (kdt::ExrCompression c : {kdt::ExrCompression::piz, kdt::ExrCompression::zip,
                                      kdt::ExrCompression::rle, kdt::ExrCompression::none}) {
            const std::string name = kdt::kExrCompressionNames[size_t(c)];
            kdt::write_exr((dir / ("float_" + name + "_meta.exr")).string(), image, metadata, c);
        }
        using kdt::test::ExrVariant;
        const std::pair<const char*, ExrVariant> variants[] = {
            {"half_piz_tiled.exr", {9, 7, Imf::HALF, Imf::PIZ_COMPRESSION, false, 4}},
            {"half_piz_grey.exr", {8, 33, Imf::HALF, Imf::PIZ_COMPRESSION, true}},
            {"uint_rle_grey_tiled.exr", {5, 4, Imf::UINT, Imf::RLE_COMPRESSION, true, 2}},
            {"half_zips.exr", {8, 4, Imf::HALF, Imf::ZIPS_COMPRESSION}},
            {"half_b44.exr", {8, 8, Imf::HALF, Imf::B44_COMPRESSION}},
        };
        for (const auto& [name, v] : variants)
            kdt::test::write_bytes(dir / name, kdt::test::exr_variant(v));
    } catch (const std::exception& e) {
        std::fprintf(stderr, "exr_seeds: %s\n", e.what());
        return 1;
    }
    return 0;
}
