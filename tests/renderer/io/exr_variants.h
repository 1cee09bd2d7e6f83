// OpenEXR files that write_exr() does not make (half or uint channels, grey, tiled, any
// compression), written with the OpenEXR library itself, for the EXR tests and the image
// fuzzer's seed corpus. Header only; depends on OpenEXR.
#pragma once

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include <ImfChannelList.h>
#include <ImfEnvmapAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>
#include <ImfStringAttribute.h>
#include <ImfTiledOutputFile.h>
#include <half.h>

#include "renderer/io/exr_io.h"

namespace kdt::test {

struct ExrVariant {
    int width = 8, height = 4;
    Imf::PixelType type = Imf::HALF;
    Imf::Compression compression = Imf::ZIP_COMPRESSION;
    bool grey = false;    ///< one "Y" channel instead of R, G, B
    int tile_size = 0;    ///< > 0: tiled, with the levels below
    std::string comment;  ///< non-empty: a "comments" string attribute
    int envmap = -1;      ///< >= 0: an "envmap" attribute of this Imf::Envmap value
    Imf::LevelMode levels = Imf::ONE_LEVEL;  ///< tiled: one level, mipmaps or ripmaps
    Imf::LevelRoundingMode rounding = Imf::ROUND_DOWN;
};

/// The value variant v stores in channel c (0..2) of pixel (x, y); exact in half and uint.
inline float exr_variant_value(int x, int y, int c) {
    return float((x * 7 + y * 3 + c * 5) % 23) * 0.25f + float(c);
}

/// Writes variant v into memory and returns the file's bytes. The smaller levels of a tiled
/// file hold the top-left part of the full-size image's values; they come after it in the
/// file, level by level (a ripmap's by y, then x).
inline std::vector<uint8_t> exr_variant(const ExrVariant& v) {
    ExrMemoryOStream sink("exr_variant");
    Imf::Header header(v.width, v.height);
    header.compression() = v.compression;
    const std::vector<std::string> names =
        v.grey ? std::vector<std::string>{"Y"} : std::vector<std::string>{"R", "G", "B"};
    for (const std::string& n : names) header.channels().insert(n, Imf::Channel(v.type));
    if (!v.comment.empty()) header.insert("comments", Imf::StringAttribute(v.comment));
    if (v.envmap >= 0) header.insert("envmap", Imf::EnvmapAttribute(Imf::Envmap(v.envmap)));
    const size_t size = v.type == Imf::HALF ? 2 : 4, count = size_t(v.width * v.height);
    std::vector<std::vector<char>> planes(names.size(), std::vector<char>(count * size));
    Imf::FrameBuffer fb;
    for (size_t c = 0; c < names.size(); ++c) {
        for (int y = 0; y < v.height; ++y) {
            for (int x = 0; x < v.width; ++x) {
                const float f = exr_variant_value(x, y, int(c));
                char* p = &planes[c][(size_t(y * v.width + x)) * size];
                if (v.type == Imf::HALF) {
                    const half h(f);
                    std::memcpy(p, &h, 2);
                } else if (v.type == Imf::FLOAT) {
                    std::memcpy(p, &f, 4);
                } else {
                    const uint32_t u = uint32_t(f);
                    std::memcpy(p, &u, 4);
                }
            }
        }
        fb.insert(names[c], Imf::Slice(v.type, planes[c].data(), size, size * size_t(v.width)));
    }
    if (v.tile_size > 0) {
        header.setTileDescription(Imf::TileDescription(unsigned(v.tile_size), unsigned(v.tile_size),
                                                       v.levels, v.rounding));
        Imf::TiledOutputFile file(sink, header, 0);
        file.setFrameBuffer(fb);
        for (int ly = 0; ly < file.numYLevels(); ++ly) {
            for (int lx = 0; lx < file.numXLevels(); ++lx) {
                if (!file.isValidLevel(lx, ly)) continue;
                file.writeTiles(0, file.numXTiles(lx) - 1, 0, file.numYTiles(ly) - 1, lx, ly);
            }
        }
    } else {
        Imf::OutputFile file(sink, header, 0);
        file.setFrameBuffer(fb);
        file.writePixels(v.height);
    }
    return sink.take();
}

}  // namespace kdt::test
