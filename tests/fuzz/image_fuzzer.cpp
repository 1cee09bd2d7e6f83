// libFuzzer target for the image loaders (Radiance HDR via stb_image, OpenEXR via the
// OpenEXR library, PFM, PNG via stb_image and our chunk walker): any input must load or
// throw a kdt::Error naming the file, never crash, leak, hang or trip a sanitizer. OpenEXR
// is Debian's (uninstrumented) shared library. Built by tests/fuzz/tests.cmake; OpenEXR
// seeds by tests/fuzz/exr_seeds.cpp.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <vector>

#include "renderer/core/error.h"
#include "renderer/io/exr_io.h"
#include "renderer/io/image_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::vector<uint8_t> bytes(data, data + size);
    kdt::ImageMetadata metadata;
    try {
        kdt::ImageRGB image = kdt::load_image_memory(bytes, "fuzz.img", &metadata);
        if (image.width < 1 || image.height < 1) __builtin_trap();
        if (image.rgb.size() != image.pixel_count() * 3) __builtin_trap();
        for (float v : image.rgb) {
            if (!std::isfinite(v)) __builtin_trap();
        }
    } catch (const kdt::Error& e) {
        if (std::strncmp(e.what(), "fuzz.img: ", 10) != 0) {
            std::fprintf(stderr, "error without the file name: %s\n", e.what());
            __builtin_trap();
        }
    }
    // The paths of `kdtrace info`: the header, then every channel's pixels decoded.
    if (kdt::is_exr(bytes)) {
        try {
            const kdt::ImageInfo info = kdt::read_exr_info(bytes, "fuzz.img");
            if (info.width < 1 || info.height < 1) __builtin_trap();
        } catch (const kdt::Error& e) {
            if (std::strncmp(e.what(), "fuzz.img: ", 10) != 0) __builtin_trap();
        }
        try {
            kdt::check_exr_pixels(bytes, "fuzz.img");
        } catch (const kdt::Error& e) {
            if (std::strncmp(e.what(), "fuzz.img: ", 10) != 0) __builtin_trap();
        }
    }
    return 0;
}
