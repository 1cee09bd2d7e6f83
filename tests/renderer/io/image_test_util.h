// Helpers shared by the image tests (image_io_test, exr_io_test): seeded random images
// and the error a broken file must give. Header only; depends on io and GoogleTest.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/io/image_io.h"
#include "tests/test_util.h"

namespace kdt::test {

/// A w x h image of uniform values in [0, scale), seeded.
inline ImageRGB random_image(int w, int h, uint64_t seed, float scale) {
    ImageRGB img(w, h);
    HashRng rng(seed);
    for (float& v : img.rgb) v = scale * rng.next();
    return img;
}

/// load_image(p) must throw a kdt::Error whose message starts with "p: "; returns the
/// message ("" and a test failure when the file loads).
inline std::string expect_load_error(const std::filesystem::path& p) {
    try {
        load_image(p.string());
    } catch (const Error& e) {
        EXPECT_EQ(std::string(e.what()).rfind(p.string() + ": ", 0), 0u) << e.what();
        return e.what();
    }
    ADD_FAILURE() << "no error for " << p;
    return "";
}

}  // namespace kdt::test
