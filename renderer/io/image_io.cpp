#include "renderer/io/image_io.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <new>
#include <utility>

#include <unistd.h>
#include <zlib.h>

#include "renderer/core/error.h"
#include "renderer/core/open_file.h"
#include "renderer/core/output_path.h"
#include "renderer/core/temp_file.h"
#include "renderer/io/exr_io.h"

// stb_image for .hdr and .png decoding, stb_image_write for .hdr encoding; the
// implementations are compiled into this translation unit only, with internal linkage
// (STB_*_STATIC) so they never clash with copies inside other libraries (Assimp exports
// its own). Debian's stb_image_write compiles the HDR writer only with stdio enabled.
#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_STATIC
#define STBI_NO_STDIO
#define STBI_ONLY_HDR
#define STBI_ONLY_PNG
#include <stb/stb_image.h>
#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STB_IMAGE_WRITE_STATIC
#include <stb/stb_image_write.h>

namespace kdt {
namespace {

[[noreturn]] void fail(const std::string& path, const std::string& message, int64_t offset = -1) {
    throw_file_error(path, message, offset);
}

std::string lower_extension(const std::string& path) {
    auto slash = path.find_last_of('/');
    auto dot = path.find_last_of('.');
    if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
    std::string ext = path.substr(dot);
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    return ext;
}

std::vector<uint8_t> read_file(const std::string& path) {
    // Image files beyond 4 GiB would decode to more than kMaxImagePixels anyway.
    return read_regular_file(path, uint64_t(1) << 32, "an image file");
}

void check_dimensions(const std::string& path, int64_t width, int64_t height) {
    if (width < 1 || height < 1) {
        fail(path, "invalid image size " + std::to_string(width) + "x" + std::to_string(height));
    }
    if (width > kMaxImageDimension || height > kMaxImageDimension ||
        uint64_t(width) * uint64_t(height) > kMaxImagePixels) {
        fail(path, "image size " + std::to_string(width) + "x" + std::to_string(height) +
                       " is too large (corrupt file?)");
    }
}

/// Rejects NaN and infinite pixels, naming the first one.
void check_finite(const std::string& path, const ImageRGB& image) {
    static const char* kChannel[3] = {"R", "G", "B"};
    for (size_t i = 0; i < image.rgb.size(); ++i) {
        if (!std::isfinite(image.rgb[i])) {
            size_t pixel = i / 3;
            ErrorLocation where;
            where.path = path;
            where.element = "pixel";
            where.index = int64_t(pixel);
            throw Error(where, "(x " + std::to_string(pixel % size_t(image.width)) + ", y " +
                                   std::to_string(pixel / size_t(image.width)) + ") channel " +
                                   kChannel[i % 3] + " is " +
                                   (std::isnan(image.rgb[i]) ? "NaN" : "infinite"));
        }
    }
}

// ---------------------------------------------------------------------------------------
// Radiance .hdr

/// Parses the header (as stb_image does) and walks the scanline structure without
/// decoding, so that truncated or inconsistent data is reported with its byte offset
/// before stb_image sees it (stb_image reads zeros past the end and can then loop forever
/// on a zero-length run, or silently restarts a mixed flat/RLE file).
/// Returns the width and height the header gives. Header lines are read as stb_image reads
/// them: a line ends at its first NUL byte (so a line starting with NUL ends the header).
std::pair<int64_t, int64_t> validate_hdr(const std::string& path,
                                         const std::vector<uint8_t>& data) {
    size_t pos = 0;
    auto next_line = [&](std::string& line) {
        if (pos >= data.size()) fail(path, "truncated header", int64_t(pos));
        size_t end = pos;
        while (end < data.size() && data[end] != '\n') ++end;
        if (end == data.size()) fail(path, "truncated header", int64_t(pos));
        if (end - pos > 4096) fail(path, "header line too long", int64_t(pos));
        line.assign(reinterpret_cast<const char*>(&data[pos]), end - pos);
        line.resize(std::strlen(line.c_str()));
        pos = end + 1;
    };
    std::string line;
    next_line(line);
    if (line != "#?RADIANCE" && line != "#?RGBE") fail(path, "not a Radiance HDR file", 0);
    bool rgbe = false;
    for (;;) {
        next_line(line);
        if (line.empty()) break;
        if (line == "FORMAT=32-bit_rle_rgbe") rgbe = true;
        if (line.rfind("FORMAT=", 0) == 0 && line != "FORMAT=32-bit_rle_rgbe") {
            fail(path, "unsupported pixel format '" + line.substr(7) + "'", int64_t(pos));
        }
    }
    if (!rgbe) fail(path, "header lacks FORMAT=32-bit_rle_rgbe", int64_t(pos));
    size_t res_offset = pos;
    next_line(line);
    long long h = 0, w = 0;
    int used = 0;
    bool parsed = std::sscanf(line.c_str(), "-Y %lld +X %lld%n", &h, &w, &used) == 2;
    while (parsed && used < int(line.size()) &&
           std::isspace(static_cast<unsigned char>(line[size_t(used)])))
        ++used;
    if (!parsed || used != int(line.size())) {
        fail(path, "unsupported resolution line '" + line + "' (only -Y H +X W)",
             int64_t(res_offset));
    }
    check_dimensions(path, w, h);
    const size_t width = size_t(w), height = size_t(h);
    auto truncated = [&](size_t at) {
        fail(path,
             "truncated pixel data (" + std::to_string(width) + "x" + std::to_string(height) +
                 " image)",
             int64_t(at));
    };
    const std::pair<int64_t, int64_t> size{w, h};
    if (width < 8 || width >= 32768) {
        if (data.size() - pos < 4 * width * height) truncated(data.size());
        return size;
    }
    for (size_t y = 0; y < height; ++y) {
        size_t line_start = pos;
        if (data.size() - pos < 4) truncated(pos);
        if (data[pos] != 2 || data[pos + 1] != 2 || (data[pos + 2] & 0x80)) {
            if (y != 0) {
                fail(path,
                     "scanline " + std::to_string(y) +
                         " is not run-length encoded although earlier ones are",
                     int64_t(pos));
            }
            if (data.size() - pos < 4 * width * height) truncated(data.size());
            return size;
        }
        size_t len = (size_t(data[pos + 2]) << 8) | data[pos + 3];
        if (len != width) {
            fail(path,
                 "scanline " + std::to_string(y) + " has length " + std::to_string(len) +
                     ", expected " + std::to_string(width),
                 int64_t(line_start));
        }
        pos += 4;
        for (int channel = 0; channel < 4; ++channel) {
            size_t x = 0;
            while (x < width) {
                if (pos >= data.size()) truncated(pos);
                size_t count = data[pos++];
                if (count > 128) {
                    count -= 128;
                    if (pos >= data.size()) truncated(pos);
                    ++pos;
                } else {
                    if (data.size() - pos < count) truncated(data.size());
                    pos += count;
                }
                if (count > width - x) {
                    fail(path, "scanline " + std::to_string(y) + ": run overflows the line",
                         int64_t(pos));
                }
                x += count;
            }
        }
    }
    return size;
}

ImageRGB load_hdr(const std::string& path, const std::vector<uint8_t>& data) {
    const auto [want_w, want_h] = validate_hdr(path, data);
    if (data.size() > size_t(std::numeric_limits<int>::max())) fail(path, "file too large");
    int w = 0, h = 0, comp = 0;
    float* pixels = stbi_loadf_from_memory(data.data(), int(data.size()), &w, &h, &comp, 3);
    if (!pixels) fail(path, std::string("cannot decode: ") + stbi_failure_reason());
    std::unique_ptr<float, void (*)(void*)> owner(pixels, stbi_image_free);
    // Belt and braces: stb_image must have read the header we checked.
    if (w != want_w || h != want_h) {
        fail(path, "header read inconsistently (" + std::to_string(w) + "x" + std::to_string(h) +
                       " decoded, " + std::to_string(want_w) + "x" + std::to_string(want_h) +
                       " checked)");
    }
    ImageRGB image;
    image.width = w;
    image.height = h;
    image.rgb.assign(pixels, pixels + size_t(w) * size_t(h) * 3);
    return image;
}

// ---------------------------------------------------------------------------------------
// PNG (reading via stb_image; metadata via our own chunk walker)

constexpr uint8_t kPngSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};

uint32_t read_be32(const uint8_t* p) {
    return (uint32_t(p[0]) << 24) | (uint32_t(p[1]) << 16) | (uint32_t(p[2]) << 8) | p[3];
}

/// What check_png_pixels() found in the header.
struct PngHeader {
    int width = 0;
    int height = 0;
    int depth = 0;            ///< bits per sample: 1, 2, 4, 8 or 16
    int color = 0;            ///< PNG colour type: 0 grey, 2 RGB, 3 palette, 4 grey + alpha, 6 RGBA
    bool empty_idat = false;  ///< an IDAT chunk of 0 bytes (valid, but see load_png())
};

/// Undoes a PNG row filter (PNG spec, section 9) on `row` for one byte per complete pixel (a
/// palette image's indices), `prev` the row above unfiltered (zeros for a pass's first row).
void unfilter_png_row(int filter, std::vector<uint8_t>& row, const std::vector<uint8_t>& prev) {
    const auto paeth = [](int a, int b, int c) {
        const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
        return pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
    };
    for (size_t i = 0; i < row.size(); ++i) {
        const int left = i > 0 ? row[i - 1] : 0, up = prev[i], up_left = i > 0 ? prev[i - 1] : 0;
        const int add = filter == 1   ? left
                        : filter == 2 ? up
                        : filter == 3 ? (left + up) >> 1
                        : filter == 4 ? paeth(left, up, up_left)
                                      : 0;
        row[i] = uint8_t(row[i] + add);
    }
}

/// Checks a PNG's pixel data without holding the image: the chunk order and the header,
/// palette and transparency rules, the colour type and bit depth pairs the PNG spec allows,
/// chunk CRCs, and the IDAT data streamed through zlib in bounded memory (a complete, valid
/// zlib stream of at least the bytes the header calls for, every row's filter type in 0..4,
/// and in a palette image every index within the palette). Like stb_image, it accepts bytes
/// after the last row (stb_image issue #276); unlike it, it checks the zlib stream's Adler-32,
/// refuses Apple's CgBI variant, and refuses palette indices past the palette, which
/// stb_image reads from memory it never set. load_png() runs it before decoding, so `info`
/// and loading accept the same files.
PngHeader check_png_pixels(const std::string& path, const std::vector<uint8_t>& data) {
    const auto corrupt = [&](const std::string& why, size_t at) {
        fail(path, "cannot decode PNG: " + why, int64_t(at));
    };
    if (data.size() < 8 || std::memcmp(data.data(), kPngSignature, 8) != 0) {
        fail(path, "not a PNG file", 0);
    }
    PngHeader header;
    int color = 0, channels = 0, interlace = 0;
    bool have_header = false, have_palette = false;
    size_t palette_entries = 0;
    // The rows stb_image decodes: one run per interlace pass (Adam7) or the whole image,
    // each row a filter byte and then row_bytes bytes.
    struct Pass {
        int number = 0;  // Adam7 pass 1-7, 0 without interlace
        uint64_t rows = 0;
        uint64_t row_bytes = 0;
        uint64_t pixels = 0;  // per row
    };
    std::vector<Pass> passes;
    size_t pass = 0, last_pass = 0;  // indices into passes
    uint64_t row = 0, last_row = 0;  // the next row to begin, the last one begun
    uint64_t to_filter = 0;          // bytes until the next filter byte
    bool rows_done = false;
    // Names a row of `pass` for errors: "row 3" or "row 3 of interlace pass 5".
    const auto row_name = [&](size_t in_pass, uint64_t r) {
        const int number = passes[in_pass].number;
        return "row " + std::to_string(r) +
               (number ? " of interlace pass " + std::to_string(number) : std::string());
    };
    // A palette image's rows are unfiltered to check every index against the palette: the
    // row being read and the one above it, unfiltered.
    std::vector<uint8_t> row_data, row_above;
    int row_filter = 0;
    const auto check_indices = [&](size_t at) {
        unfilter_png_row(row_filter, row_data, row_above);
        const Pass& in = passes[last_pass];
        const int d = header.depth;
        for (uint64_t x = 0; x < in.pixels; ++x) {
            const uint64_t bit = x * uint64_t(d);
            const int index = (row_data[bit / 8] >> (8 - d - int(bit % 8))) & ((1 << d) - 1);
            if (size_t(index) >= palette_entries) {
                corrupt(row_name(last_pass, last_row) + ": palette index " + std::to_string(index) +
                            " past the palette's " + std::to_string(palette_entries) + " entries",
                        at);
            }
        }
        row_above.swap(row_data);
    };
    z_stream zs{};
    bool inflating = false, stream_end = false;
    struct Inflater {
        z_stream* zs;
        bool* on;
        ~Inflater() {
            if (*on) inflateEnd(zs);
        }
    } inflater{&zs, &inflating};
    std::vector<uint8_t> out(size_t(1) << 16);
    size_t pos = 8;
    for (;;) {
        if (data.size() - pos < 12) fail(path, "truncated PNG: no IEND chunk", int64_t(pos));
        const uint32_t length = read_be32(&data[pos]);
        if (length > 0x7fffffffu || data.size() - pos - 12 < length) {
            fail(path, "truncated PNG chunk", int64_t(pos));
        }
        const std::string type(reinterpret_cast<const char*>(&data[pos + 4]), 4);
        const uint8_t* body = &data[pos + 8];
        if (uint32_t(crc32(0L, &data[pos + 4], uInt(length + 4))) != read_be32(body + length))
            fail(path, "CRC mismatch in chunk " + type, int64_t(pos));
        if (type == "CgBI") {
            corrupt("Apple CgBI chunk (an iOS variant, not a standard PNG)", pos);
        } else if (!have_header && type != "IHDR") {
            corrupt("first chunk is " + type + ", not IHDR", pos);
        } else if (type == "IHDR") {
            if (have_header) corrupt("multiple IHDR chunks", pos);
            have_header = true;
            if (length != 13) corrupt("IHDR chunk of " + std::to_string(length) + " bytes", pos);
            const uint32_t w = read_be32(body), h = read_be32(body + 4);
            header.depth = body[8];
            header.color = color = body[9];
            interlace = body[12];
            const int d = header.depth;
            if (d != 1 && d != 2 && d != 4 && d != 8 && d != 16)
                corrupt("bit depth " + std::to_string(d) + " (1, 2, 4, 8 or 16 only)", pos);
            // PNG spec, table 11.1: grey any depth, palette up to 8, the others 8 or 16.
            if (!(color == 0 || (color == 3 && d <= 8) ||
                  ((color == 2 || color == 4 || color == 6) && d >= 8)))
                corrupt(
                    "colour type " + std::to_string(color) + " with bit depth " + std::to_string(d),
                    pos);
            if (body[10] != 0) corrupt("unknown compression method", pos);
            if (body[11] != 0) corrupt("unknown filter method", pos);
            if (interlace > 1) corrupt("unknown interlace method", pos);
            check_dimensions(path, w, h);
            header.width = int(w);
            header.height = int(h);
            channels = color == 3 ? 1 : (color & 2 ? 3 : 1) + (color & 4 ? 1 : 0);
            // Adam7 passes: origin and spacing in x and y (PNG spec, section 8.2).
            static const int kX0[7] = {0, 4, 0, 2, 0, 1, 0}, kY0[7] = {0, 0, 4, 0, 2, 0, 1};
            static const int kDx[7] = {8, 8, 4, 4, 2, 2, 1}, kDy[7] = {8, 8, 8, 4, 4, 2, 2};
            for (int p = 0; p < (interlace ? 7 : 1); ++p) {
                const uint64_t x0 = interlace ? kX0[p] : 0, dx = interlace ? kDx[p] : 1;
                const uint64_t y0 = interlace ? kY0[p] : 0, dy = interlace ? kDy[p] : 1;
                const uint64_t pw = (w + dx - 1 - x0) / dx, ph = (h + dy - 1 - y0) / dy;
                if (w <= x0 || h <= y0 || pw == 0 || ph == 0) continue;
                const uint64_t row_bytes = (uint64_t(channels) * pw * uint64_t(d) + 7) / 8;
                if (d < 8 && row_bytes > pw) corrupt("invalid width", pos);
                passes.push_back({interlace ? p + 1 : 0, ph, row_bytes, pw});
            }
        } else if (type == "PLTE") {
            if (length == 0 || length > 256 * 3 || length % 3 != 0)
                corrupt("PLTE chunk of " + std::to_string(length) + " bytes", pos);
            have_palette = true;
            palette_entries = length / 3;
        } else if (type == "tRNS") {
            if (inflating || stream_end) corrupt("tRNS chunk after IDAT", pos);
            if (color == 3) {
                if (!have_palette || palette_entries == 0) corrupt("tRNS chunk before PLTE", pos);
                if (length > palette_entries) corrupt("tRNS chunk too long for the palette", pos);
            } else {
                if (color & 4) corrupt("tRNS chunk in an image with alpha", pos);
                if (length != uint32_t(channels) * 2) corrupt("bad tRNS chunk length", pos);
            }
        } else if (type == "IDAT") {
            header.empty_idat = header.empty_idat || length == 0;
            if (color == 3 && !have_palette) corrupt("palette image without PLTE chunk", pos);
            if (!inflating && !stream_end) {
                if (inflateInit2(&zs, 15) != Z_OK)
                    fail(path, "zlib initialisation failed", int64_t(pos));
                inflating = true;
                to_filter = 0;
            }
            zs.next_in = const_cast<Bytef*>(body);
            zs.avail_in = uInt(length);
            // Data after the end of the zlib stream is ignored, as stb_image ignores it.
            while (inflating && zs.avail_in > 0) {
                zs.next_out = out.data();
                zs.avail_out = uInt(out.size());
                const int ret = inflate(&zs, Z_NO_FLUSH);
                if (ret != Z_OK && ret != Z_STREAM_END && ret != Z_BUF_ERROR) {
                    corrupt(std::string("corrupt zlib stream in IDAT: ") +
                                (zs.msg ? zs.msg : "error " + std::to_string(ret)),
                            pos);
                }
                // Walk the rows: only the filter bytes are checked, the rest skipped.
                uint64_t have = out.size() - zs.avail_out;
                const uint8_t* p = out.data();
                while (have > 0) {
                    if (to_filter > 0) {
                        const uint64_t take = std::min(have, to_filter);
                        if (color == 3) {
                            std::memcpy(row_data.data() + (row_data.size() - to_filter), p,
                                        size_t(take));
                        }
                        to_filter -= take;
                        have -= take;
                        p += take;
                        if (to_filter == 0 && color == 3) check_indices(pos);
                        continue;
                    }
                    if (rows_done) break;  // bytes after the last row
                    if (*p > 4) {
                        corrupt(row_name(pass, row) + " has filter type " + std::to_string(*p) +
                                    " (0-4 allowed)",
                                pos);
                    }
                    row_filter = *p;
                    ++p;
                    --have;
                    to_filter = passes[pass].row_bytes;
                    if (color == 3) {
                        row_data.assign(size_t(to_filter), 0);
                        if (row == 0) row_above.assign(size_t(to_filter), 0);
                    }
                    last_pass = pass;
                    last_row = row;
                    if (++row == passes[pass].rows) {
                        row = 0;
                        if (++pass == passes.size()) rows_done = true;
                    }
                }
                if (ret == Z_STREAM_END) {
                    inflateEnd(&zs);
                    inflating = false;
                    stream_end = true;
                }
            }
        } else if (type == "IEND") {
            if (!inflating && !stream_end) corrupt("no IDAT chunk", pos);
            if (inflating) corrupt("zlib stream in IDAT ends early (truncated image data)", pos);
            // The row the data ends in: the one begun last, or the next one.
            if (to_filter > 0 || !rows_done) {
                const std::string where =
                    to_filter > 0 ? row_name(last_pass, last_row) : row_name(pass, row);
                corrupt("image data ends in " + where + " of " + std::to_string(header.width) +
                            "x" + std::to_string(header.height),
                        pos);
            }
            break;
        } else if ((data[pos + 4] & 0x20) == 0) {
            corrupt("unknown critical chunk " + type, pos);
        }
        pos += 12 + size_t(length);
    }
    return header;
}

ImageRGB load_png(const std::string& path, const std::vector<uint8_t>& data) {
    if (data.size() > size_t(std::numeric_limits<int>::max())) fail(path, "file too large");
    const PngHeader header = check_png_pixels(path, data);  // what stb_image lets through
    if (header.empty_idat) {
        // stb_image copies an empty first IDAT from a null pointer (undefined behaviour): the
        // same file without its empty IDAT chunks, which hold nothing.
        std::vector<uint8_t> kept(data.begin(), data.begin() + 8);
        for (size_t pos = 8; pos + 12 <= data.size();) {
            const uint32_t length = read_be32(&data[pos]);
            const size_t end = pos + 12 + size_t(length);  // checked: IEND comes first
            if (length != 0 || std::memcmp(&data[pos + 4], "IDAT", 4) != 0)
                kept.insert(kept.end(), data.begin() + ptrdiff_t(pos),
                            data.begin() + ptrdiff_t(end));
            if (std::memcmp(&data[pos + 4], "IEND", 4) == 0) break;
            pos = end;
        }
        return load_png(path, kept);
    }
    int w = 0, h = 0, comp = 0;
    if (!stbi_info_from_memory(data.data(), int(data.size()), &w, &h, &comp)) {
        fail(path, std::string("cannot decode PNG: ") + stbi_failure_reason());
    }
    check_dimensions(path, w, h);
    ImageRGB image(w, h);
    if (stbi_is_16_bit_from_memory(data.data(), int(data.size()))) {
        stbi_us* p = stbi_load_16_from_memory(data.data(), int(data.size()), &w, &h, &comp, 3);
        if (!p) fail(path, std::string("cannot decode PNG: ") + stbi_failure_reason());
        std::unique_ptr<stbi_us, void (*)(void*)> owner(p, stbi_image_free);
        for (size_t i = 0; i < image.rgb.size(); ++i)
            image.rgb[i] = srgb_to_linear(p[i] / 65535.0f);
    } else {
        stbi_uc* p = stbi_load_from_memory(data.data(), int(data.size()), &w, &h, &comp, 3);
        if (!p) fail(path, std::string("cannot decode PNG: ") + stbi_failure_reason());
        std::unique_ptr<stbi_uc, void (*)(void*)> owner(p, stbi_image_free);
        float table[256];
        for (int i = 0; i < 256; ++i) table[i] = srgb_to_linear(float(i) / 255.0f);
        for (size_t i = 0; i < image.rgb.size(); ++i) image.rgb[i] = table[p[i]];
    }
    return image;
}

/// The text metadata of one PNG, all chunks together, inflated: kdtrace writes a few KB, so a
/// file above this is not ours, and memory stays bounded whatever the file holds.
constexpr size_t kMaxPngText = size_t(64) << 20;

/// Inflates a zlib stream, refusing outputs above `limit` bytes.
std::string inflate_text(const std::string& path, const uint8_t* src, size_t size, int64_t offset,
                         size_t limit) {
    z_stream zs{};
    if (inflateInit(&zs) != Z_OK) fail(path, "zlib initialisation failed", offset);
    zs.next_in = const_cast<Bytef*>(src);
    zs.avail_in = uInt(size);
    std::string out;
    char buffer[16384];
    int ret = Z_OK;
    while (ret == Z_OK) {
        zs.next_out = reinterpret_cast<Bytef*>(buffer);
        zs.avail_out = sizeof(buffer);
        ret = inflate(&zs, Z_NO_FLUSH);
        out.append(buffer, sizeof(buffer) - zs.avail_out);
        if (out.size() > limit) {
            inflateEnd(&zs);
            fail(path,
                 "text metadata larger than " + std::to_string(kMaxPngText >> 20) + " MiB in all",
                 offset);
        }
        if (ret == Z_OK && zs.avail_in == 0 && zs.avail_out != 0) ret = Z_DATA_ERROR;
    }
    inflateEnd(&zs);
    if (ret != Z_STREAM_END) fail(path, "corrupt compressed text chunk", offset);
    return out;
}

ImageMetadata parse_png_metadata(const std::string& path, const std::vector<uint8_t>& data) {
    if (data.size() < 8 || std::memcmp(data.data(), kPngSignature, 8) != 0) {
        fail(path, "not a PNG file", 0);
    }
    ImageMetadata metadata;
    size_t text = 0;  // bytes of text so far
    // Adds a value, refusing text beyond kMaxPngText in all.
    const auto add = [&](std::string key, std::string value, int64_t at) {
        text += key.size() + value.size();
        if (text > kMaxPngText) {
            fail(path,
                 "text metadata larger than " + std::to_string(kMaxPngText >> 20) + " MiB in all",
                 at);
        }
        metadata.emplace_back(std::move(key), std::move(value));
    };
    size_t pos = 8;
    for (;;) {
        if (data.size() - pos < 12) fail(path, "truncated PNG: no IEND chunk", int64_t(pos));
        uint32_t length = read_be32(&data[pos]);
        if (length > 0x7fffffffu || data.size() - pos - 12 < length) {
            fail(path, "truncated PNG chunk", int64_t(pos));
        }
        std::string type(reinterpret_cast<const char*>(&data[pos + 4]), 4);
        const uint8_t* body = &data[pos + 8];
        uint32_t crc = uint32_t(crc32(0L, &data[pos + 4], uInt(length + 4)));
        if (crc != read_be32(body + length))
            fail(path, "CRC mismatch in chunk " + type, int64_t(pos));
        int64_t at = int64_t(pos);
        if (type == "IEND") break;
        const char* b = reinterpret_cast<const char*>(body);
        const char* nul = static_cast<const char*>(std::memchr(b, 0, length));
        if (type == "tEXt" || type == "zTXt" || type == "iTXt") {
            if (!nul) fail(path, type + " chunk without keyword terminator", at);
            std::string key(b, nul);
            size_t rest = size_t(nul - b) + 1;
            const size_t room = kMaxPngText - std::min(kMaxPngText, text + key.size());
            if (type == "tEXt") {
                add(key, std::string(b + rest, length - rest), at);
            } else if (type == "zTXt") {
                if (rest + 1 > length || body[rest] != 0) fail(path, "bad zTXt chunk", at);
                add(key, inflate_text(path, body + rest + 1, length - rest - 1, at, room), at);
            } else {
                if (rest + 2 > length) fail(path, "bad iTXt chunk", at);
                bool compressed = body[rest] != 0;
                rest += 2;
                for (int field = 0; field < 2; ++field) {  // language tag, translated keyword
                    const void* end = std::memchr(b + rest, 0, length - rest);
                    if (!end) fail(path, "bad iTXt chunk", at);
                    rest = size_t(static_cast<const char*>(end) - b) + 1;
                }
                if (compressed) {
                    add(key, inflate_text(path, body + rest, length - rest, at, room), at);
                } else {
                    add(key, std::string(b + rest, length - rest), at);
                }
            }
        }
        pos += 12 + size_t(length);
    }
    return metadata;
}

// ---------------------------------------------------------------------------------------
// PFM

ImageRGB load_pfm(const std::string& path, const std::vector<uint8_t>& data) {
    size_t pos = 0;
    auto is_space = [](uint8_t c) { return c == ' ' || c == '\n' || c == '\r' || c == '\t'; };
    auto token = [&]() {
        while (pos < data.size() && is_space(data[pos])) ++pos;
        size_t start = pos;
        while (pos < data.size() && !is_space(data[pos]) && pos - start < 64) ++pos;
        if (pos == start || pos >= data.size()) fail(path, "truncated PFM header", int64_t(start));
        if (!is_space(data[pos])) fail(path, "malformed PFM header", int64_t(start));
        return std::make_pair(std::string(reinterpret_cast<const char*>(&data[start]), pos - start),
                              int64_t(start));
    };
    auto [magic, magic_at] = token();
    int channels = magic == "PF" ? 3 : (magic == "Pf" ? 1 : 0);
    if (channels == 0) fail(path, "not a PFM file (magic '" + magic + "')", magic_at);
    auto parse_int = [&](const std::pair<std::string, int64_t>& t, const char* what) {
        char* end = nullptr;
        long long v = std::strtoll(t.first.c_str(), &end, 10);
        if (*end != 0)
            fail(path, std::string("malformed ") + what + " '" + t.first + "'", t.second);
        return v;
    };
    long long w = parse_int(token(), "width");
    long long h = parse_int(token(), "height");
    check_dimensions(path, w, h);
    auto scale_token = token();
    char* end = nullptr;
    double scale = std::strtod(scale_token.first.c_str(), &end);
    if (*end != 0 || !std::isfinite(scale) || scale == 0.0) {
        fail(path, "malformed scale '" + scale_token.first + "'", scale_token.second);
    }
    // Pixels are multiplied by the scale as a float: beyond float range it would make every
    // pixel infinite or NaN, and the error would blame the first pixel.
    if (std::fabs(scale) > double(std::numeric_limits<float>::max())) {
        fail(path, "scale '" + scale_token.first + "' is beyond float range", scale_token.second);
    }
    ++pos;  // exactly one whitespace character separates the header from the data
    const bool little = scale < 0.0;
    const size_t count = size_t(w) * size_t(h) * size_t(channels);
    if (data.size() - pos < count * 4) {
        fail(path,
             "truncated pixel data: " + std::to_string(count * 4) + " bytes expected, " +
                 std::to_string(data.size() - pos) + " present",
             int64_t(pos));
    }
    const float factor = float(std::abs(scale));
    ImageRGB image(static_cast<int>(w), static_cast<int>(h));
    const uint8_t* src = data.data() + pos;
    for (size_t row = 0; row < size_t(h); ++row) {
        // PFM stores rows bottom-to-top.
        size_t y = size_t(h) - 1 - row;
        for (size_t x = 0; x < size_t(w); ++x) {
            for (int c = 0; c < channels; ++c) {
                const uint8_t* p = src + ((row * size_t(w) + x) * size_t(channels) + size_t(c)) * 4;
                uint32_t bits = little ? (uint32_t(p[0]) | uint32_t(p[1]) << 8 |
                                          uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24)
                                       : read_be32(p);
                float v;
                std::memcpy(&v, &bits, 4);
                if (factor != 1.0f) v *= factor;
                float* dst = &image.rgb[(y * size_t(w) + x) * 3];
                if (channels == 1) {
                    dst[0] = dst[1] = dst[2] = v;
                } else {
                    dst[c] = v;
                }
            }
        }
    }
    return image;
}

// ---------------------------------------------------------------------------------------
// Writing

// Writes to a temporary file beside path and renames it over path, so a failed write
// (a full disk, say) leaves any earlier file at path whole instead of truncated.
// The temporary file is removed on every exit path, signals included, and an existing
// file's mode is kept (core/temp_file.h).
void write_bytes(const std::string& path, const void* data, size_t size) {
    write_file_atomically(path, data, size);
}

void check_image(const std::string& path, const ImageRGB& image) {
    check_dimensions(path, image.width, image.height);
    if (image.rgb.size() != image.pixel_count() * 3) {
        fail(path, "image buffer holds " + std::to_string(image.rgb.size()) + " floats, expected " +
                       std::to_string(image.pixel_count() * 3));
    }
    if (!image.alpha.empty() && image.alpha.size() != image.pixel_count()) {
        fail(path, "alpha holds " + std::to_string(image.alpha.size()) + " values, expected " +
                       std::to_string(image.pixel_count()));
    }
}

// PFM and HDR hold RGB only: an image with coverage would lose its transparency there.
void check_no_alpha(const std::string& path, const ImageRGB& image) {
    if (!image.alpha.empty())
        fail(path, "this format has no alpha channel (write .png or .exr for a transparent image)");
}

void put_be32(std::vector<uint8_t>& out, uint32_t v) {
    out.push_back(uint8_t(v >> 24));
    out.push_back(uint8_t(v >> 16));
    out.push_back(uint8_t(v >> 8));
    out.push_back(uint8_t(v));
}

void put_chunk(std::vector<uint8_t>& out, const char* type, const std::vector<uint8_t>& body) {
    put_be32(out, uint32_t(body.size()));
    size_t type_at = out.size();
    out.insert(out.end(), type, type + 4);
    out.insert(out.end(), body.begin(), body.end());
    put_be32(out, uint32_t(crc32(0L, &out[type_at], uInt(body.size() + 4))));
}

uint8_t paeth(int a, int b, int c) {
    int p = a + b - c;
    int pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
    return uint8_t(pa <= pb && pa <= pc ? a : (pb <= pc ? b : c));
}

/// PNG filter bytes per row, chosen by the usual minimum-sum-of-absolute-differences rule.
std::vector<uint8_t> filter_rows(const std::vector<uint8_t>& pixels, int width, int height,
                                 size_t channels) {
    const size_t stride = size_t(width) * channels;
    std::vector<uint8_t> out;
    out.reserve((stride + 1) * size_t(height));
    std::vector<uint8_t> candidate[5];
    for (auto& c : candidate) c.resize(stride);
    std::vector<uint8_t> zero(stride, 0);
    for (int y = 0; y < height; ++y) {
        const uint8_t* row = &pixels[size_t(y) * stride];
        const uint8_t* up = y > 0 ? &pixels[size_t(y - 1) * stride] : zero.data();
        uint64_t best_cost = ~uint64_t(0);
        int best = 0;
        for (int f = 0; f < 5; ++f) {
            uint64_t cost = 0;
            for (size_t i = 0; i < stride; ++i) {
                const size_t n = channels;  // bytes per pixel: the left neighbour's offset
                int a = i >= n ? row[i - n] : 0, b = up[i], c = i >= n ? up[i - n] : 0;
                int pred = f == 0   ? 0
                           : f == 1 ? a
                           : f == 2 ? b
                           : f == 3 ? (a + b) / 2
                                    : paeth(a, b, c);
                uint8_t v = uint8_t(row[i] - pred);
                candidate[f][i] = v;
                cost += uint64_t(std::abs(int(int8_t(v))));
            }
            if (cost < best_cost) {
                best_cost = cost;
                best = f;
            }
        }
        out.push_back(uint8_t(best));
        out.insert(out.end(), candidate[best].begin(), candidate[best].end());
    }
    return out;
}

void check_png_key(const std::string& path, const std::string& key) {
    bool ok = !key.empty() && key.size() <= 79 && key.front() != ' ' && key.back() != ' ';
    for (unsigned char c : key) ok = ok && ((c >= 32 && c <= 126) || c >= 161);
    if (!ok)
        fail(path, "invalid PNG metadata key '" + key + "' (1-79 printable Latin-1 characters)");
}

}  // namespace

ImageRGB load_image(const std::string& path, ImageMetadata* metadata) {
    return load_image_memory(read_file(path), path, metadata);
}

namespace {

ImageRGB decode_image(const std::vector<uint8_t>& data, const std::string& path,
                      ImageMetadata* metadata) {
    ImageRGB image;
    auto starts = [&](const char* magic, size_t n) {
        return data.size() >= n && std::memcmp(data.data(), magic, n) == 0;
    };
    if (starts("#?", 2)) {
        image = load_hdr(path, data);
    } else if (is_exr(data)) {
        image = load_exr(data, path, metadata);
    } else if (starts("PF", 2) || starts("Pf", 2)) {
        image = load_pfm(path, data);
    } else if (starts(reinterpret_cast<const char*>(kPngSignature), 8)) {
        ImageMetadata md = parse_png_metadata(path, data);
        image = load_png(path, data);
        if (metadata) *metadata = std::move(md);
    } else if (data.empty()) {
        fail(path, "empty file");
    } else {
        fail(path, "unrecognised image format (expected .hdr, .exr, .pfm or .png content)", 0);
    }
    return image;
}

}  // namespace

ImageRGB load_image_memory(const std::vector<uint8_t>& data, const std::string& path,
                           ImageMetadata* metadata) {
    if (metadata) metadata->clear();
    ImageRGB image;
    // A huge image (a 16k map decodes to 1.6 GB, twice while decoding) may not fit: an
    // error naming the file, as for any other bad input.
    try {
        image = decode_image(data, path, metadata);
    } catch (const std::bad_alloc&) {
        fail(path, "out of memory decoding the image");
    }
    check_finite(path, image);
    return image;
}

void write_pfm(const std::string& path, const ImageRGB& image) {
    check_image(path, image);
    std::string header =
        "PF\n" + std::to_string(image.width) + " " + std::to_string(image.height) + "\n-1\n";
    std::vector<uint8_t> out(header.begin(), header.end());
    const size_t stride = size_t(image.width) * 3;
    out.reserve(out.size() + image.rgb.size() * 4);
    for (int y = image.height - 1; y >= 0; --y) {
        const float* row = &image.rgb[size_t(y) * stride];
        for (size_t i = 0; i < stride; ++i) {
            uint32_t bits;
            std::memcpy(&bits, &row[i], 4);
            for (int b = 0; b < 4; ++b) out.push_back(uint8_t(bits >> (8 * b)));
        }
    }
    write_bytes(path, out.data(), out.size());
}

void write_exr(const std::string& path, const ImageRGB& image, const ImageMetadata& metadata,
               ExrCompression compression) {
    check_image(path, image);
    const std::vector<uint8_t> bytes = encode_exr(path, image, metadata, compression);
    write_bytes(path, bytes.data(), bytes.size());
}

void write_png(const std::string& path, const ImageRGB& image, const ToneParams& tone,
               const ImageMetadata& metadata) {
    check_image(path, image);
    std::vector<uint8_t> chunks;
    std::vector<uint8_t> body;
    for (const auto& [key, value] : metadata) {
        check_png_key(path, key);
        if (value.find('\0') != std::string::npos) {
            fail(path, "metadata value for key '" + key + "' contains a NUL byte");
        }
        bool ascii = std::all_of(value.begin(), value.end(),
                                 [](char c) { return static_cast<unsigned char>(c) < 0x80; });
        body.assign(key.begin(), key.end());
        body.push_back(0);
        if (!ascii) body.insert(body.end(), {0, 0, 0, 0});  // iTXt: uncompressed, no language
        body.insert(body.end(), value.begin(), value.end());
        put_chunk(chunks, ascii ? "tEXt" : "iTXt", body);
    }

    // A 4096-entry table would be faster, but tone mapping is not on the hot path.
    const bool rgba = !image.alpha.empty();
    const size_t channels = rgba ? 4 : 3;
    std::vector<uint8_t> pixels(image.pixel_count() * channels);
    for (size_t p = 0; p < image.pixel_count(); ++p) {
        // PNG alpha is straight: un-premultiply before the tone curve.
        const float a = rgba ? std::clamp(image.alpha[p], 0.0f, 1.0f) : 1.0f;
        const float inv = a > 0.0f ? 1.0f / a : 0.0f;
        for (size_t c = 0; c < 3; ++c) {
            const float v = rgba ? image.rgb[3 * p + c] * inv : image.rgb[3 * p + c];
            pixels[channels * p + c] = tonemap_to_srgb8(v, tone);
        }
        if (rgba) pixels[channels * p + 3] = uint8_t(std::lround(a * 255.0f));
    }
    std::vector<uint8_t> raw = filter_rows(pixels, image.width, image.height, channels);
    uLongf packed_size = compressBound(uLong(raw.size()));
    std::vector<uint8_t> packed(packed_size);
    if (compress2(packed.data(), &packed_size, raw.data(), uLong(raw.size()), 6) != Z_OK) {
        fail(path, "zlib compression failed");
    }
    packed.resize(packed_size);

    std::vector<uint8_t> out(kPngSignature, kPngSignature + 8);
    body.clear();
    put_be32(body, uint32_t(image.width));
    put_be32(body, uint32_t(image.height));
    // 8-bit, RGB (2) or RGBA (6), deflate, adaptive filter, no interlace.
    body.insert(body.end(), {8, uint8_t(rgba ? 6 : 2), 0, 0, 0});
    put_chunk(out, "IHDR", body);
    put_chunk(out, "sRGB", {0});  // perceptual rendering intent
    out.insert(out.end(), chunks.begin(), chunks.end());
    put_chunk(out, "IDAT", packed);
    put_chunk(out, "IEND", {});
    write_bytes(path, out.data(), out.size());
}

void write_hdr(const std::string& path, const ImageRGB& image) {
    check_image(path, image);
    std::vector<uint8_t> out;
    auto sink = [](void* context, void* data, int size) {
        auto* v = static_cast<std::vector<uint8_t>*>(context);
        v->insert(v->end(), static_cast<uint8_t*>(data), static_cast<uint8_t*>(data) + size);
    };
    if (!stbi_write_hdr_to_func(sink, &out, image.width, image.height, 3, image.rgb.data())) {
        fail(path, "cannot encode Radiance HDR");
    }
    write_bytes(path, out.data(), out.size());
}

// The formats write_image() knows, by extension; anything else is this one error.
void check_image_extension(const std::string& path, const std::string& ext) {
    if (ext != ".png" && ext != ".exr" && ext != ".pfm" && ext != ".hdr")
        fail(path, "unknown image format '" + ext + "' (use .png, .exr, .pfm or .hdr)");
}

void write_image(const std::string& path, const ImageRGB& image, const ToneParams& tone,
                 const ImageMetadata& metadata) {
    const std::string ext = lower_extension(path);
    check_image_extension(path, ext);
    if (ext == ".png") {
        write_png(path, image, tone, metadata);
    } else if (ext == ".exr") {
        write_exr(path, image, metadata);
    } else if (ext == ".pfm") {
        check_no_alpha(path, image);
        write_pfm(path, image);
    } else {
        check_no_alpha(path, image);
        write_hdr(path, image);
    }
}

void check_image_output(const std::string& path, bool with_alpha) {
    namespace fs = std::filesystem;
    std::error_code ec;
    // Before the extension: a directory has none, and "unknown image format ''" hides why.
    if (fs::is_directory(fs::path(path), ec)) fail(path, "is a directory, not an image file name");
    const std::string ext = lower_extension(path);
    check_image_extension(path, ext);
    if (with_alpha && ext != ".png" && ext != ".exr")
        fail(path, "film.transparent needs an alpha channel: write .png or .exr");
    // Before the directory: a directory name too long reads as a missing directory.
    const std::string too_long = path_length_problem(path);
    if (!too_long.empty()) fail(path, too_long);
    fs::path dir = fs::path(path).parent_path();
    if (dir.empty()) dir = ".";
    if (!fs::is_directory(dir, ec))
        fail(path, "no directory " + excerpt_path(dir.string()) + " to write into");
    if (::access(dir.c_str(), W_OK) != 0)
        fail(path, "cannot write into " + excerpt_path(dir.string()) + ": " + std::strerror(errno));
}

ImageMetadata read_png_metadata(const std::string& path) {
    return parse_png_metadata(path, read_file(path));
}

ImageMetadata read_exr_metadata(const std::string& path) {
    return read_exr_info(read_file(path), path).metadata;
}

ImageInfo read_image_info(const std::string& path) {
    const std::vector<uint8_t> data = read_file(path);
    if (is_exr(data)) {
        ImageInfo info = read_exr_info(data, path);
        check_exr_pixels(data, path);  // as the other formats are decoded whole below
        return info;
    }
    ImageInfo info;
    auto starts = [&](const char* magic, size_t n) {
        return data.size() >= n && std::memcmp(data.data(), magic, n) == 0;
    };
    if (starts(reinterpret_cast<const char*>(kPngSignature), 8)) {
        info.metadata = parse_png_metadata(path, data);
        const PngHeader header = check_png_pixels(path, data);
        info.format = "PNG";
        info.width = header.width;
        info.height = header.height;
        info.encoding = header.color == 3 ? "8-bit sRGB, palette of " +
                                                std::to_string(header.depth) + "-bit indices"
                                          : std::to_string(header.depth) + "-bit sRGB";
        return info;
    }
    // PFM and Radiance HDR hold no metadata and are small: decode them to check them whole.
    const ImageRGB image = load_image_memory(data, path);
    info.width = image.width;
    info.height = image.height;
    if (starts("#?", 2)) {
        info.format = "Radiance HDR";
        info.encoding = "RGBE";
    } else {
        info.format = "PFM";
        info.encoding = std::string(data[1] == 'F' ? "colour" : "grey") + " 32-bit float";
    }
    return info;
}

}  // namespace kdt
