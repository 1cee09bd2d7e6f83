// OpenEXR reading and writing through the OpenEXR library (Debian's libopenexr-dev 3.1),
// behind image_io.h: every exception the library throws becomes a kdt::Error naming the
// file. Depends on core and the OpenEXR library.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <ImfIO.h>

#include "renderer/io/image_io.h"

namespace kdt {

/// Throws kdt::Error for `path` with the message (and the byte offset when >= 0).
[[noreturn]] void throw_file_error(const std::string& path, const std::string& message,
                                   int64_t offset = -1);

/// An OpenEXR output stream into a growing byte vector (writers seek back to fill in
/// their offset tables). `name` only names the stream in the library's messages.
class ExrMemoryOStream final : public Imf::OStream {
public:
    explicit ExrMemoryOStream(const std::string& name) : Imf::OStream(name.c_str()) {}
    void write(const char c[], int n) override;
    uint64_t tellp() override { return pos_; }
    void seekp(uint64_t pos) override { pos_ = size_t(pos); }
    std::vector<uint8_t> take() { return std::move(data_); }

private:
    std::vector<uint8_t> data_;
    size_t pos_ = 0;
};

/// True when data starts with the OpenEXR magic number.
bool is_exr(const std::vector<uint8_t>& data);

/// Decodes a single-part scanline or tiled OpenEXR file (level 0 of a mipmapped one):
/// R, G, B by name, or else a Y or single channel as grey; half, float and uint channels.
/// Throws kdt::Error naming path for anything else, for sizes beyond kMaxImagePixels and
/// for corrupt data. metadata (if given) receives the header's string attributes, and an
/// envmap attribute as ("envmap", "latlong", "cube" or "unknown").
ImageRGB load_exr(const std::vector<uint8_t>& data, const std::string& path,
                  ImageMetadata* metadata);

/// Reads an OpenEXR header only: size, compression, channels, string attributes.
ImageInfo read_exr_info(const std::vector<uint8_t>& data, const std::string& path);

/// Reads and decodes every channel's pixels (of any name, type and sampling) and discards
/// them; throws kdt::Error naming path, as load_exr() does, for a truncated or corrupt file.
void check_exr_pixels(const std::vector<uint8_t>& data, const std::string& path);

/// Encodes image as 32-bit float R, G, B scanlines with the given compression and the
/// metadata as string attributes; path only names errors. Throws kdt::Error for keys that
/// OpenEXR reserves or cannot store, and for repeated keys.
std::vector<uint8_t> encode_exr(const std::string& path, const ImageRGB& image,
                                const ImageMetadata& metadata, ExrCompression compression);

}  // namespace kdt
