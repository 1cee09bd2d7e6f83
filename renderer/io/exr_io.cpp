#include "renderer/io/exr_io.h"

#include <algorithm>
#include <cstring>
#include <exception>
#include <limits>
#include <mutex>

#include <ImfChannelList.h>
#include <ImfEnvmapAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIO.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfStringAttribute.h>
#include <ImfTileDescriptionAttribute.h>
#include <ImfVersion.h>

#include "renderer/core/error.h"

namespace kdt {
namespace {

[[noreturn]] void fail(const std::string& path, const std::string& message, int64_t offset = -1) {
    throw_file_error(path, message, offset);
}

/// An IStream over bytes in memory. Reads past the end throw, as the library expects.
class MemoryIStream final : public Imf::IStream {
public:
    MemoryIStream(const std::vector<uint8_t>& data, const std::string& path)
        : Imf::IStream(path.c_str()), data_(data) {}
    bool read(char c[], int n) override {
        if (n < 0 || uint64_t(n) > data_.size() - pos_) {
            throw std::runtime_error("unexpected end of file at byte " + std::to_string(pos_));
        }
        std::memcpy(c, data_.data() + pos_, size_t(n));
        pos_ += uint64_t(n);
        return pos_ < data_.size();
    }
    uint64_t tellg() override { return pos_; }
    void seekg(uint64_t pos) override { pos_ = std::min<uint64_t>(pos, data_.size()); }

private:
    const std::vector<uint8_t>& data_;
    uint64_t pos_ = 0;
};

constexpr Imf::Compression kCompression[] = {
    Imf::NO_COMPRESSION,   Imf::RLE_COMPRESSION,   Imf::ZIPS_COMPRESSION, Imf::ZIP_COMPRESSION,
    Imf::PIZ_COMPRESSION,  Imf::PXR24_COMPRESSION, Imf::B44_COMPRESSION,  Imf::B44A_COMPRESSION,
    Imf::DWAA_COMPRESSION, Imf::DWAB_COMPRESSION};
static_assert(std::size(kCompression) == kExrCompressionNames.size());

std::string compression_name(Imf::Compression c) {
    for (size_t i = 0; i < std::size(kCompression); ++i) {
        if (kCompression[i] == c) return kExrCompressionNames[i];
    }
    return "unknown (" + std::to_string(int(c)) + ")";
}

/// Attributes that describe the file's structure, never free-form metadata.
bool is_structural(const std::string& key) {
    static const char* kReserved[] = {"channels",
                                      "compression",
                                      "dataWindow",
                                      "displayWindow",
                                      "lineOrder",
                                      "pixelAspectRatio",
                                      "screenWindowCenter",
                                      "screenWindowWidth",
                                      "tiles",
                                      "type",
                                      "name",
                                      "chunkCount",
                                      "version",
                                      "view",
                                      "maxSamplesPerPixel"};
    return std::any_of(std::begin(kReserved), std::end(kReserved),
                       [&](const char* r) { return key == r; });
}

/// The library's global limits, set once: headers with larger windows or tiles are refused
/// before anything is allocated for them.
void set_library_limits() {
    static std::once_flag once;
    std::call_once(once, [] {
        Imf::staticInitialize();
        Imf::Header::setMaxImageSize(kMaxImageDimension, kMaxImageDimension);
        Imf::Header::setMaxTileSize(kMaxImageDimension, kMaxImageDimension);
    });
}

/// Bytes that the library reads for an attribute of a fixed-size type whatever its stated
/// size (0: not such a type).
uint32_t fixed_attribute_size(const std::string& type) {
    static const std::pair<const char*, uint32_t> kSizes[] = {{"box2i", 16},
                                                              {"box2f", 16},
                                                              {"v2i", 8},
                                                              {"v2f", 8},
                                                              {"v2d", 16},
                                                              {"v3i", 12},
                                                              {"v3f", 12},
                                                              {"v3d", 24},
                                                              {"float", 4},
                                                              {"int", 4},
                                                              {"double", 8},
                                                              {"compression", 1},
                                                              {"lineOrder", 1},
                                                              {"envmap", 1},
                                                              {"deepImageState", 1},
                                                              {"tiledesc", 9},
                                                              {"rational", 8},
                                                              {"timecode", 8},
                                                              {"keycode", 28},
                                                              {"chromaticities", 32},
                                                              {"m33f", 36},
                                                              {"m44f", 64},
                                                              {"m33d", 72},
                                                              {"m44d", 128}};
    for (const auto& [name, size] : kSizes) {
        if (type == name) return size;
    }
    return 0;
}

/// Walks the header's attributes (name, type, 32-bit size, value; an empty name ends the
/// list) as the library reads them, and refuses what it would read past the stated size or
/// allocate before reading: the library allocates an unknown attribute's stated size
/// (found by the image fuzzer: 1.9e9 bytes asked by a 16 KB file), reads a fixed-size type
/// and a channel list whatever the stated size, and a preview image of the size its own
/// header states. Names and types end within 256 bytes. Returns where the header ends (the
/// byte after the empty name), which is where a single-part file's offset table starts.
size_t check_attribute_sizes(const std::vector<uint8_t>& data, const std::string& path) {
    size_t pos = 8;  // magic and version
    auto text = [&](const char* what, size_t at, size_t end) {
        end = std::min(end, pos + 256);
        const void* nul = pos < end ? std::memchr(&data[pos], 0, end - pos) : nullptr;
        if (!nul) fail(path, std::string("unterminated attribute ") + what, int64_t(at));
        std::string s(reinterpret_cast<const char*>(&data[pos]));
        pos += s.size() + 1;
        return s;
    };
    auto u32 = [&](size_t at) {
        return uint32_t(data[at]) | uint32_t(data[at + 1]) << 8 | uint32_t(data[at + 2]) << 16 |
               uint32_t(data[at + 3]) << 24;
    };
    for (;;) {
        if (pos >= data.size()) fail(path, "truncated OpenEXR header", int64_t(pos));
        if (data[pos] == 0) return pos + 1;
        const size_t at = pos;
        const std::string name = text("name", at, data.size());
        const std::string type = text("type", at, data.size());
        if (data.size() - pos < 4) fail(path, "truncated OpenEXR header", int64_t(pos));
        const uint32_t size = u32(pos);
        pos += 4;
        if (size > data.size() - pos)
            fail(path, "attribute '" + name + "' runs past the end of the file", int64_t(at));
        const size_t end = pos + size;
        auto malformed = [&] {
            fail(path,
                 "malformed attribute '" + name + "' of type " + type + " (" +
                     std::to_string(size) + " bytes)",
                 int64_t(at));
        };
        const uint32_t fixed = fixed_attribute_size(type);
        if (fixed != 0 && size != fixed) malformed();
        if (type == "chlist") {
            // Channels: name, then 16 bytes (type, pLinear and reserved, x and y sampling),
            // until an empty name.
            for (;;) {
                if (pos >= end) malformed();
                if (data[pos] == 0) {
                    ++pos;
                    break;
                }
                text("channel name", at, end);
                if (end - pos < 16) malformed();
                pos += 16;
            }
            if (pos != end) malformed();
        } else if (type == "preview") {
            if (size < 8 || uint64_t(u32(pos)) * u32(pos + 4) * 4 + 8 != size) malformed();
        } else if (type == "idmanifest") {
            // Inflated to a size it states itself; nothing we read needs it.
            fail(path, "attribute '" + name + "' of type idmanifest is not supported", int64_t(at));
        }
        pos = end;
    }
}

/// Reads and checks the header (and the version field before it). Checks what the library
/// would allocate from it: the image size against kMaxImagePixels, and the offset table
/// (8 bytes per block, allocated before it is read) against the file's size. header_end_out
/// (if given) receives where the header ends.
Imf::Header read_header(const std::vector<uint8_t>& data, const std::string& path, int* version_out,
                        size_t* header_end_out = nullptr) {
    set_library_limits();
    if (data.size() < 8)
        fail(path, "truncated OpenEXR file (" + std::to_string(data.size()) + " bytes)");
    int version = int(uint32_t(data[4]) | uint32_t(data[5]) << 8 | uint32_t(data[6]) << 16 |
                      uint32_t(data[7]) << 24);
    if (Imf::getVersion(version) != Imf::EXR_VERSION)
        fail(path, "unsupported OpenEXR version " + std::to_string(Imf::getVersion(version)), 4);
    if (!Imf::supportsFlags(Imf::getFlags(version))) fail(path, "unsupported OpenEXR flags", 4);
    if (Imf::isMultiPart(version) || Imf::isNonImage(version))
        fail(path, "multi-part and deep OpenEXR files are not supported");
    const size_t header_end = check_attribute_sizes(data, path);
    MemoryIStream stream(data, path);
    stream.seekg(8);
    Imf::Header header;
    header.readFrom(stream, version);
    header.sanityCheck(Imf::isTiled(version));
    const Imath::Box2i dw = header.dataWindow();
    const int64_t w = int64_t(dw.max.x) - dw.min.x + 1, h = int64_t(dw.max.y) - dw.min.y + 1;
    if (w < 1 || h < 1 || w > kMaxImageDimension || h > kMaxImageDimension ||
        uint64_t(w) * uint64_t(h) > kMaxImagePixels) {
        fail(path, "image size " + std::to_string(w) + "x" + std::to_string(h) +
                       " is out of range (corrupt file?)");
    }
    uint64_t blocks = 0;
    if (Imf::isTiled(version)) {
        const Imf::TileDescription& t = header.tileDescription();
        // The library buffers a tile, and a row of tiles across the image: tiles larger than
        // both the image and 64x64 pixels serve no purpose and could ask for gigabytes.
        if (int64_t(t.xSize) > std::max<int64_t>(w, 64) ||
            int64_t(t.ySize) > std::max<int64_t>(h, 64)) {
            fail(path, "tiles of " + std::to_string(t.xSize) + "x" + std::to_string(t.ySize) +
                           " are larger than the " + std::to_string(w) + "x" + std::to_string(h) +
                           " image");
        }
        // The first level alone; mipmap and ripmap levels only add to it.
        blocks = ((uint64_t(w) + t.xSize - 1) / t.xSize) * ((uint64_t(h) + t.ySize - 1) / t.ySize);
    } else {
        const int lines = header.compression() == Imf::NO_COMPRESSION ||
                                  header.compression() == Imf::RLE_COMPRESSION ||
                                  header.compression() == Imf::ZIPS_COMPRESSION
                              ? 1
                          : header.compression() == Imf::ZIP_COMPRESSION ||
                                  header.compression() == Imf::PXR24_COMPRESSION
                              ? 16
                          : header.compression() == Imf::DWAB_COMPRESSION ? 256
                                                                          : 32;
        blocks = (uint64_t(h) + uint64_t(lines) - 1) / uint64_t(lines);
    }
    if (blocks > data.size() / 8) {
        fail(path, "offset table of " + std::to_string(blocks) + " blocks does not fit in the " +
                       std::to_string(data.size()) + "-byte file");
    }
    if (version_out) *version_out = version;
    if (header_end_out) *header_end_out = header_end;
    return header;
}

/// floor(log2(n)) or, rounding up, ceil(log2(n)), for n >= 1: how OpenEXR counts levels.
int level_log2(int64_t n, Imf::LevelRoundingMode rounding) {
    int k = 0;
    while ((int64_t(1) << (k + 1)) <= n) ++k;
    return rounding == Imf::ROUND_UP && (int64_t(1) << k) < n ? k + 1 : k;
}

/// The size of level l of an image side of n pixels: n / 2^l rounded, at least 1.
int64_t level_size(int64_t n, int l, Imf::LevelRoundingMode rounding) {
    const int64_t size = rounding == Imf::ROUND_UP ? (n + (int64_t(1) << l) - 1) >> l : n >> l;
    return std::max<int64_t>(size, 1);
}

/// Checks that every tile of every level of a single-part tiled file lies within the file.
/// The library decodes level 0 only, so a file cut short in its smaller mipmap or ripmap
/// levels would otherwise load as if whole; a copy cut short is refused like any other.
/// Reads the offset table (which follows the header) and each tile's 20-byte header
/// (tile x, y, level x, y, data size); decodes nothing.
void check_tiles_present(const std::vector<uint8_t>& data, const std::string& path,
                         const Imf::Header& header, size_t header_end) {
    const Imath::Box2i dw = header.dataWindow();
    const int64_t w = int64_t(dw.max.x) - dw.min.x + 1, h = int64_t(dw.max.y) - dw.min.y + 1;
    const Imf::TileDescription& t = header.tileDescription();
    const Imf::LevelRoundingMode r = t.roundingMode;
    int levels_x = 1, levels_y = 1;
    if (t.mode == Imf::MIPMAP_LEVELS) {
        levels_x = levels_y = level_log2(std::max(w, h), r) + 1;
    } else if (t.mode == Imf::RIPMAP_LEVELS) {
        levels_x = level_log2(w, r) + 1;
        levels_y = level_log2(h, r) + 1;
    }
    auto u32 = [&](size_t at) {
        return uint32_t(data[at]) | uint32_t(data[at + 1]) << 8 | uint32_t(data[at + 2]) << 16 |
               uint32_t(data[at + 3]) << 24;
    };
    size_t entry = header_end;
    // The table lists the tiles level by level (a ripmap's levels by y, then x), each level
    // by rows of tiles.
    for (int ly = 0; ly < levels_y; ++ly) {
        for (int lx = 0; lx < levels_x; ++lx) {
            if (t.mode == Imf::MIPMAP_LEVELS && lx != ly) continue;
            const int64_t lw = level_size(w, lx, r), lh = level_size(h, ly, r);
            const int64_t tiles = ((lw + t.xSize - 1) / t.xSize) * ((lh + t.ySize - 1) / t.ySize);
            auto missing = [&](const std::string& how) {
                const std::string size = std::to_string(lw) + "x" + std::to_string(lh);
                const std::string level =
                    lx == 0 && ly == 0 ? "the full-size image (" + size + ")"
                    : t.mode == Imf::MIPMAP_LEVELS
                        ? "mipmap level " + std::to_string(lx) + " (" + size + ")"
                        : "ripmap level " + std::to_string(lx) + "," + std::to_string(ly) + " (" +
                              size + ")";
                fail(path, "truncated OpenEXR file: " + level + " " + how + " (the file has " +
                               std::to_string(data.size()) + " bytes)");
            };
            for (int64_t i = 0; i < tiles; ++i, entry += 8) {
                if (entry > data.size() || data.size() - entry < 8)
                    missing("is missing from the offset table");
                const uint64_t at = uint64_t(u32(entry)) | uint64_t(u32(entry + 4)) << 32;
                // An offset of 0 is the placeholder a writer leaves until the tile is written.
                if (at < header_end || at > data.size() || data.size() - at < 20)
                    missing("has a tile past the end of the file");
                const uint32_t bytes = u32(size_t(at) + 16);
                if (bytes > data.size() - at - 20)
                    missing("has a tile that runs past the end of the file");
            }
        }
    }
}

/// read_header() and, for a tiled file, check_tiles_present(): the header of a file whose
/// every tile lies within it, for the readers that decode it.
Imf::Header read_whole_file_header(const std::vector<uint8_t>& data, const std::string& path) {
    int version = 0;
    size_t header_end = 0;
    Imf::Header header = read_header(data, path, &version, &header_end);
    if (Imf::isTiled(version)) check_tiles_present(data, path, header, header_end);
    return header;
}

ImageMetadata string_attributes(const Imf::Header& header) {
    ImageMetadata metadata;
    for (auto it = header.begin(); it != header.end(); ++it) {
        const auto* s = dynamic_cast<const Imf::StringAttribute*>(&it.attribute());
        if (s && !is_structural(it.name())) metadata.emplace_back(it.name(), s->value());
    }
    // The standard envmap attribute says how the image maps directions (OpenEXR's
    // Imf::Envmap): environment lights refuse a cube-face map rather than read it as lat-long.
    if (const auto* e = header.findTypedAttribute<Imf::EnvmapAttribute>("envmap")) {
        metadata.emplace_back("envmap", e->value() == Imf::ENVMAP_CUBE      ? "cube"
                                        : e->value() == Imf::ENVMAP_LATLONG ? "latlong"
                                                                            : "unknown");
    }
    return metadata;
}

const char* pixel_type_name(Imf::PixelType t) {
    return t == Imf::HALF ? "half" : t == Imf::FLOAT ? "float" : "uint";
}

/// Runs f, turning whatever the library throws into a kdt::Error naming path; our own
/// errors pass through unchanged.
template <typename F>
auto guarded(const std::string& path, const char* what, F&& f) {
    try {
        return f();
    } catch (const Error&) {
        throw;
    } catch (const std::bad_alloc&) {
        fail(path, std::string(what) + ": out of memory");
    } catch (const std::exception& e) {
        fail(path, std::string(what) + ": " + e.what());
    } catch (...) {
        fail(path, std::string(what) + ": unknown OpenEXR error");
    }
}

ImageRGB decode(const std::vector<uint8_t>& data, const std::string& path,
                ImageMetadata* metadata) {
    const Imf::Header checked = read_whole_file_header(data, path);
    const Imf::ChannelList& channels = checked.channels();
    const char* names[3] = {"R", "G", "B"};
    const Imf::Channel* found[3] = {channels.findChannel("R"), channels.findChannel("G"),
                                    channels.findChannel("B")};
    bool grey = !found[0] && !found[1] && !found[2];
    if (grey) {
        const Imf::Channel* y = channels.findChannel("Y");
        const char* name = "Y";
        if (!y) {
            auto it = channels.begin();
            if (it != channels.end() && ++Imf::ChannelList::ConstIterator(it) == channels.end()) {
                y = &it.channel();
                name = it.name();
            }
        }
        if (!y) fail(path, "no R, G, B or Y channel");
        names[0] = name;
        found[0] = y;
    } else {
        for (int c = 0; c < 3; ++c) {
            if (!found[c])
                fail(path, std::string("has some of R, G, B but no ") + "RGB"[c] + " channel");
        }
    }
    for (int c = 0; c < (grey ? 1 : 3); ++c) {
        if (found[c]->xSampling != 1 || found[c]->ySampling != 1) {
            fail(path, std::string("channel ") + names[c] + " is subsampled (not supported)");
        }
    }
    const Imath::Box2i dw = checked.dataWindow();
    const int w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
    MemoryIStream stream(data, path);
    Imf::InputFile file(stream, 0);
    // The library reads the header again; it must be the one checked above.
    if (file.header().dataWindow() != dw) fail(path, "header read inconsistently");
    // Decoded in bands of about 2^20 pixels, the image growing as they arrive: a header may
    // claim up to kMaxImagePixels with a few corrupt bytes behind it, and decoding then stops
    // at the first band instead of after allocating the whole image.
    ImageRGB image;
    image.width = w;
    image.height = h;
    const int band = std::max(1, (1 << 20) / w);
    const size_t x_stride = 3 * sizeof(float), y_stride = x_stride * size_t(w);
    for (int y0 = 0; y0 < h; y0 += band) {
        const int rows = std::min(band, h - y0);
        const size_t at = image.rgb.size();
        image.rgb.resize(at + size_t(rows) * size_t(w) * 3);
        Imf::FrameBuffer fb;
        for (int c = 0; c < (grey ? 1 : 3); ++c) {
            fb.insert(names[c], Imf::Slice::Make(Imf::FLOAT, image.rgb.data() + at + c,
                                                 Imath::V2i(dw.min.x, dw.min.y + y0), w, rows,
                                                 x_stride, y_stride));
        }
        file.setFrameBuffer(fb);
        file.readPixels(dw.min.y + y0, dw.min.y + y0 + rows - 1);
    }
    if (grey) {
        for (size_t i = 0; i < image.pixel_count(); ++i)
            image.rgb[i * 3 + 1] = image.rgb[i * 3 + 2] = image.rgb[i * 3];
    }
    if (metadata) *metadata = string_attributes(file.header());
    return image;
}

}  // namespace

void throw_file_error(const std::string& path, const std::string& message, int64_t offset) {
    ErrorLocation where;
    where.path = path;
    where.offset = offset;
    throw Error(where, message);
}

void ExrMemoryOStream::write(const char c[], int n) {
    if (pos_ + size_t(n) > data_.size()) data_.resize(pos_ + size_t(n));
    std::memcpy(data_.data() + pos_, c, size_t(n));
    pos_ += size_t(n);
}

bool is_exr(const std::vector<uint8_t>& data) {
    return data.size() >= 4 && Imf::isImfMagic(reinterpret_cast<const char*>(data.data()));
}

ImageRGB load_exr(const std::vector<uint8_t>& data, const std::string& path,
                  ImageMetadata* metadata) {
    return guarded(path, "corrupt OpenEXR file", [&] { return decode(data, path, metadata); });
}

ImageInfo read_exr_info(const std::vector<uint8_t>& data, const std::string& path) {
    return guarded(path, "corrupt OpenEXR header", [&] {
        int version = 0;
        const Imf::Header header = read_header(data, path, &version);
        ImageInfo info;
        info.format = "OpenEXR";
        const Imath::Box2i dw = header.dataWindow();
        info.width = dw.max.x - dw.min.x + 1;
        info.height = dw.max.y - dw.min.y + 1;
        info.encoding = compression_name(header.compression()) + " compression, ";
        if (Imf::isTiled(version)) {
            const Imf::TileDescription& t = header.tileDescription();
            info.encoding += std::to_string(t.xSize) + "x" + std::to_string(t.ySize) + " tiles";
        } else {
            info.encoding += "scanlines";
        }
        info.encoding += "; channels";
        for (auto it = header.channels().begin(); it != header.channels().end(); ++it) {
            info.encoding +=
                std::string(" ") + it.name() + " (" + pixel_type_name(it.channel().type) + ")";
        }
        info.metadata = string_attributes(header);
        return info;
    });
}

void check_exr_pixels(const std::vector<uint8_t>& data, const std::string& path) {
    guarded(path, "corrupt OpenEXR file", [&] {
        const Imf::Header checked = read_whole_file_header(data, path);
        MemoryIStream stream(data, path);
        Imf::InputFile file(stream, 0);
        if (file.header().dataWindow() != checked.dataWindow())
            fail(path, "header read inconsistently");
        // Every channel, of any name and sampling, into one scratch row (the y stride is 0):
        // the library reads and decompresses every block, and only a row is allocated.
        const Imath::Box2i dw = checked.dataWindow();
        const int64_t w = int64_t(dw.max.x) - dw.min.x + 1;
        std::vector<float> row(size_t(w) + 1);
        Imf::FrameBuffer fb;
        for (auto it = checked.channels().begin(); it != checked.channels().end(); ++it) {
            const int xs = it.channel().xSampling, ys = it.channel().ySampling;
            // Pixel x of this channel lands at base + (x / xs) * 4: row[0] for dw.min.x
            // (which sanityCheck() made a multiple of xs).
            const uintptr_t base = reinterpret_cast<uintptr_t>(row.data()) -
                                   uintptr_t(intptr_t(dw.min.x / xs) * intptr_t(sizeof(float)));
            fb.insert(it.name(), Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(base),
                                            sizeof(float), 0, xs, ys));
        }
        if (fb.begin() == fb.end()) return;
        file.setFrameBuffer(fb);
        file.readPixels(dw.min.y, dw.max.y);
    });
}

std::vector<uint8_t> encode_exr(const std::string& path, const ImageRGB& image,
                                const ImageMetadata& metadata, ExrCompression compression) {
    set_library_limits();
    Imf::Header header(image.width, image.height);
    header.compression() = kCompression[size_t(compression)];
    for (const char* c : {"R", "G", "B"}) header.channels().insert(c, Imf::Channel(Imf::FLOAT));
    // Coverage as OpenEXR's A channel over premultiplied RGB, as the format defines it.
    const bool alpha = !image.alpha.empty();
    if (alpha) header.channels().insert("A", Imf::Channel(Imf::FLOAT));
    for (const auto& [key, value] : metadata) {
        if (key.empty() || key.size() > 255 || key.find('\0') != std::string::npos ||
            is_structural(key)) {
            fail(path, "invalid OpenEXR metadata key '" + key +
                           "' (1-255 bytes without NUL, not a structural attribute)");
        }
        if (header.find(key) != header.end())
            fail(path, "OpenEXR metadata key '" + key + "' given twice");
        if (value.size() > size_t(std::numeric_limits<int>::max() / 2))
            fail(path, "metadata value too long for key '" + key + "'");
        header.insert(key, Imf::StringAttribute(value));
    }
    return guarded(path, "cannot write OpenEXR", [&] {
        ExrMemoryOStream stream(path);
        {
            Imf::OutputFile file(stream, header, 0);
            Imf::FrameBuffer fb;
            const size_t x_stride = 3 * sizeof(float), y_stride = x_stride * size_t(image.width);
            // The library only reads through the slices' pointers when writing.
            char* base = reinterpret_cast<char*>(const_cast<float*>(image.rgb.data()));
            fb.insert("R", Imf::Slice(Imf::FLOAT, base, x_stride, y_stride));
            fb.insert("G", Imf::Slice(Imf::FLOAT, base + 4, x_stride, y_stride));
            fb.insert("B", Imf::Slice(Imf::FLOAT, base + 8, x_stride, y_stride));
            if (alpha) {
                char* a = reinterpret_cast<char*>(const_cast<float*>(image.alpha.data()));
                fb.insert("A", Imf::Slice(Imf::FLOAT, a, sizeof(float),
                                          sizeof(float) * size_t(image.width)));
            }
            file.setFrameBuffer(fb);
            file.writePixels(image.height);
        }
        return stream.take();
    });
}

}  // namespace kdt
