// Loading and writing images: Radiance .hdr (stb_image), OpenEXR (the OpenEXR library, see
// exr_io.h), PFM (our own), 8-bit PNG (written with zlib, read with stb_image) with
// tEXt/iTXt metadata. The only module that touches files. Depends on core and OpenEXR.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "renderer/core/color.h"
#include "renderer/core/math.h"

namespace kdt {

/// Linear float RGB, row-major, row 0 = top of the image, 3 floats per pixel.
struct ImageRGB {
    int width = 0;
    int height = 0;
    std::vector<float> rgb;
    /// Coverage per pixel in [0, 1] (row-major), empty = opaque. With it, rgb is premultiplied
    /// (an uncovered pixel is black): EXR stores it as an A channel over rgb, PNG as 8-bit
    /// straight alpha; PFM and HDR have no alpha and refuse such an image.
    std::vector<float> alpha;

    ImageRGB() = default;
    ImageRGB(int w, int h) : width(w), height(h), rgb(size_t(w) * size_t(h) * 3, 0.0f) {}

    size_t pixel_count() const { return size_t(width) * size_t(height); }
    Vec3f at(int x, int y) const {
        const float* p = &rgb[(size_t(y) * size_t(width) + size_t(x)) * 3];
        return {p[0], p[1], p[2]};
    }
    void set(int x, int y, const Vec3f& c) {
        float* p = &rgb[(size_t(y) * size_t(width) + size_t(x)) * 3];
        p[0] = c.x;
        p[1] = c.y;
        p[2] = c.z;
    }
};

/// Ordered key/value text pairs stored in PNG tEXt/iTXt chunks and EXR string attributes.
/// PNG keeps their order and repeated keys; an EXR header holds each key once and reads
/// them back sorted by key.
using ImageMetadata = std::vector<std::pair<std::string, std::string>>;

/// The standard OpenEXR compressions. Lossless: none, rle, zips, zip, piz. pxr24 rounds
/// float channels to 24 bits; b44 and b44a are lossy for half channels only (lossless for
/// the float files write_exr() makes); dwaa and dwab quantise R, G, B (float ones too) in
/// a DCT, to about 1% here.
enum class ExrCompression : uint8_t { none, rle, zips, zip, piz, pxr24, b44, b44a, dwaa, dwab };
inline constexpr std::array<const char*, 10> kExrCompressionNames = {
    "none", "rle", "zips", "zip", "piz", "pxr24", "b44", "b44a", "dwaa", "dwab"};

/// What an image file holds, read without decoding the pixels where the format allows.
struct ImageInfo {
    std::string format;  ///< "OpenEXR", "PNG", "PFM" or "Radiance HDR"
    int width = 0;
    int height = 0;
    std::string encoding;  ///< e.g. "piz compression, scanlines; channels B G R (float)"
    ImageMetadata metadata;
};

/// Images larger than this many pixels (or wider/taller than kMaxImageDimension) are rejected
/// as corrupt before anything is allocated.
inline constexpr uint64_t kMaxImagePixels = uint64_t(1) << 27;
inline constexpr int kMaxImageDimension = 1 << 16;

/// Loads .hdr (Radiance RGBE), .exr (OpenEXR: RGB(A) or Y channels, half/float/uint), .pfm
/// (colour "PF" or grey "Pf") or .png (8/16-bit sRGB, decoded to linear). The format is
/// chosen by the file's magic bytes, not its extension. Grey images are replicated to RGB;
/// alpha is dropped. Throws kdt::Error naming the file for a missing, truncated or
/// malformed file, absurd dimensions, and for NaN or infinite pixels (naming the pixel).
/// If metadata is given, it receives the PNG text chunks or EXR string attributes.
ImageRGB load_image(const std::string& path, ImageMetadata* metadata = nullptr);

/// load_image() on a file's bytes already in memory; `path` names it in error messages.
/// For tests and fuzzers.
ImageRGB load_image_memory(const std::vector<uint8_t>& data, const std::string& path,
                           ImageMetadata* metadata = nullptr);

/// Writes linear float PFM ("PF", little-endian, rows bottom-to-top as the format wants).
void write_pfm(const std::string& path, const ImageRGB& image);

/// Writes OpenEXR with 32-bit float R, G, B scanline channels; metadata become attributes of
/// type "string" (keys of 1-255 bytes without NUL, each once, none of the structural ones
/// such as "channels" or "compression"; a bad key throws kdt::Error).
void write_exr(const std::string& path, const ImageRGB& image, const ImageMetadata& metadata = {},
               ExrCompression compression = ExrCompression::zip);

/// Writes an 8-bit sRGB PNG: radiance * 2^exposure, tone curve, sRGB encoding, rounding.
/// Metadata become tEXt chunks (iTXt when a value is not 7-bit ASCII). Keys must be 1-79
/// printable Latin-1 characters without NUL; a bad key throws kdt::Error.
void write_png(const std::string& path, const ImageRGB& image, const ToneParams& tone = {},
               const ImageMetadata& metadata = {});

/// Writes a Radiance .hdr (RGBE, run-length encoded) via stb_image_write; no metadata.
void write_hdr(const std::string& path, const ImageRGB& image);

/// Chooses the writer by extension: .png, .exr, .pfm or .hdr (case-insensitive); an
/// unknown extension throws kdt::Error. tone applies to .png only; metadata to .png/.exr.
void write_image(const std::string& path, const ImageRGB& image, const ToneParams& tone = {},
                 const ImageMetadata& metadata = {});

/// Throws kdt::Error naming path when write_image() could not write there: an unknown
/// extension, a path or file name too long, a missing directory, a directory in its place,
/// or no write permission; with `with_alpha` (film.transparent), a format without alpha.
/// For callers to check before long work; it writes nothing.
void check_image_output(const std::string& path, bool with_alpha = false);

/// Reads the tEXt, zTXt and iTXt chunks of a PNG file without decoding its pixels.
/// Throws kdt::Error for a file that is not a well-formed PNG chunk stream.
ImageMetadata read_png_metadata(const std::string& path);

/// Reads the string attributes of an EXR file's header (sorted by key).
ImageMetadata read_exr_metadata(const std::string& path);

/// Size, format, encoding and metadata of an image file (.exr, .png, .pfm, .hdr by content).
/// The pixels are decoded too: throws kdt::Error naming path as load_image() does, for a
/// truncated or corrupt file as well (an EXR of any channels, not only those load_image reads).
ImageInfo read_image_info(const std::string& path);

}  // namespace kdt
