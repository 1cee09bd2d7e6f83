// Tests of renderer/io/ply_* and io/file_reader against gzip bombs generated here: headers
// claiming huge counts over runs of zeros, data that ends early, runs that inflate beyond the
// reader's ratio limit, and gigabytes of trailing bytes. Each asserts an outcome that bounds
// memory and work (the error, the bytes inflated, the bytes the arrays allocated), never a
// time.
#include <zlib.h>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/io/file_reader.h"
#include "renderer/io/mesh_io.h"
#include "renderer/io/ply_reader.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

constexpr uint64_t kMiB = uint64_t(1) << 20;

// One gzip member holding `data`, at deflate's best compression.
std::string gzip_member(const std::string& data) {
    z_stream zs{};
    EXPECT_EQ(deflateInit2(&zs, 9, Z_DEFLATED, 15 + 16, 9, Z_DEFAULT_STRATEGY), Z_OK);
    std::string out(deflateBound(&zs, uLong(data.size())) + 64, '\0');
    zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
    zs.avail_in = uInt(data.size());
    zs.next_out = reinterpret_cast<Bytef*>(out.data());
    zs.avail_out = uInt(out.size());
    EXPECT_EQ(deflate(&zs, Z_FINISH), Z_STREAM_END);
    out.resize(zs.total_out);
    deflateEnd(&zs);
    return out;
}

// A gzip file: `head` (compressed as it is), then `mib` MiB of byte `fill`, then `tail`.
// gzip readers read concatenated members as one stream, so the fill is one member of 1 MiB
// repeated: a few hundred bytes of file per MiB inflated, as a bomb would be made.
std::string gzip_bomb(const std::string& head, char fill, uint64_t mib,
                      const std::string& tail = "") {
    std::string out = gzip_member(head);
    const std::string block = gzip_member(std::string(size_t(kMiB), fill));
    out.reserve(out.size() + block.size() * mib + 64);
    for (uint64_t k = 0; k < mib; ++k) out += block;
    if (!tail.empty()) out += gzip_member(tail);
    return out;
}

std::string write_file(const std::string& name, const std::string& bytes) {
    const std::filesystem::path path = test::temp_dir("ply_gz_bomb") / name;
    std::ofstream(path, std::ios::binary) << bytes;
    return path.string();
}

// Loads the file, expects a kdt::Error and returns its message ("" when none was thrown);
// info is filled as far as the load got.
std::string load_error(const std::string& path, MeshLoadInfo& info, MeshLoadOptions options = {}) {
    try {
        read_ply(path, options, &info);
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

std::string binary_xyz_header(uint64_t vertices, uint64_t faces) {
    return "ply\nformat binary_little_endian 1.0\nelement vertex " + std::to_string(vertices) +
           "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
           std::to_string(faces) + "\nproperty list uchar int vertex_indices\nend_header\n";
}

std::string ascii_xyz_header(uint64_t vertices, uint64_t faces) {
    return "ply\nformat ascii 1.0\nelement vertex " + std::to_string(vertices) +
           "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
           std::to_string(faces) + "\nproperty list uchar int vertex_indices\nend_header\n";
}

std::string repeat(const std::string& s, size_t n) {
    std::string out;
    out.reserve(s.size() * n);
    for (size_t k = 0; k < n; ++k) out += s;
    return out;
}

#define EXPECT_CONTAINS(msg, part) \
    EXPECT_NE((msg).find(part), std::string::npos) << "\"" << (part) << "\" not in: " << (msg)

TEST(PlyGzipBomb, HugeCountOverZerosIsRefusedBeforeReadingOrAllocating) {
    // 300M vertices claimed over 64 MiB of zeros (a 64 KB file): binary and ascii.
    for (const bool ascii : {false, true}) {
        SCOPED_TRACE(ascii ? "ascii" : "binary");
        const std::string head =
            ascii ? ascii_xyz_header(300000000, 1000) : binary_xyz_header(300000000, 1000);
        const std::string path = write_file("count.ply.gz", gzip_bomb(head, ascii ? '\n' : 0, 64));
        MeshLoadInfo info;
        const std::string msg = load_error(path, info);
        EXPECT_CONTAINS(msg, "count.ply.gz: line 3: header: element vertex: count 300000000");
        EXPECT_CONTAINS(msg, "bytes this compressed file may inflate to");
        EXPECT_CONTAINS(msg, "up to 200:1");
        EXPECT_EQ(info.array_bytes, 0u);
        EXPECT_LE(info.input_bytes_read, 8 * kMiB);
    }
}

TEST(PlyGzipBomb, ArraysGrowWithTheDataNotWithTheHeadersCount) {
    // Counts that fit what the file may inflate to, over far less data: the arrays hold what
    // arrived, not the 60 MB the counts would need.
    struct Case {
        const char* name;
        bool ascii;
        int threads;
    };
    for (const Case c :
         {Case{"binary", false, 1}, Case{"ascii", true, 1}, Case{"ascii2", true, 2}}) {
        SCOPED_TRACE(c.name);
        const uint64_t claimed = 5000000, real = 100000;
        std::string head = c.ascii ? ascii_xyz_header(claimed, 10) : binary_xyz_header(claimed, 10);
        std::string data;
        if (c.ascii) {
            data = repeat("0.25 1.5 -2\n", size_t(real));
        } else {
            const float xyz[3] = {0.25f, 1.5f, -2.0f};
            std::string rec(reinterpret_cast<const char*>(xyz), sizeof(xyz));
            data = repeat(rec, size_t(real));
        }
        const std::string path = write_file("short.ply.gz", gzip_member(head + data));
        MeshLoadOptions options;
        options.threads = c.threads;
        MeshLoadInfo info;
        const std::string msg = load_error(path, info, options);
        EXPECT_CONTAINS(msg, "unexpected end of data");
        EXPECT_CONTAINS(msg, "vertex 100000");
        // At most twice the positions that arrived (doubling), not claimed * 12 bytes.
        EXPECT_LE(info.array_bytes, 2 * (real + 4096) * 12 + 4096 * 12);
        EXPECT_GT(info.array_bytes, real * 12);
    }
}

TEST(PlyGzipBomb, SameCountsFromAPlainFileAreRefusedAtOnce) {
    // A file of known size holds its data or is refused before anything is read past the
    // header: 5M vertices cannot fit in 1.2 MB.
    std::string data(size_t(100000 * 12), '\0');
    const std::string path = write_file("short.ply", binary_xyz_header(5000000, 10) + data);
    MeshLoadInfo info;
    const std::string msg = load_error(path, info);
    EXPECT_CONTAINS(msg, "element vertex: count 5000000 needs at least 60000000 bytes");
    EXPECT_CONTAINS(msg, "bytes of data in the file");
    EXPECT_EQ(info.array_bytes, 0u);
}

TEST(PlyGzipBomb, ZerosBeyondTheRatioLimitStopTheReader) {
    // Enough vertices to pass the header check (the first 64 MiB inflate freely) over 128 MiB
    // of zeros, which inflate about 1000:1: reading stops just past the free 64 MiB.
    const uint64_t vertices = (kInflationFreeBytes + kMiB / 2) / 12;
    const std::string path =
        write_file("zeros.ply.gz", gzip_bomb(binary_xyz_header(vertices, 1), 0, 128));
    MeshLoadInfo info;
    const std::string msg = load_error(path, info);
    EXPECT_CONTAINS(msg, "zeros.ply.gz: the gzip data inflate ");
    EXPECT_CONTAINS(msg, "beyond the 200:1 that mesh data ever needs; stopped reading");
    EXPECT_LE(info.input_bytes_read, kInflationFreeBytes + 8 * kMiB);
    EXPECT_LE(info.array_bytes, vertices * 12 + 12);  // positions capped at the count, 1 face
}

TEST(PlyGzipBomb, FileReaderStopsAtTheRatioLimit) {
    for (const char fill : {'\0', '\n', ' '}) {
        const std::string path = write_file("fill.gz", gzip_bomb("x", fill, 256));
        FileReader reader = FileReader::open(path);
        std::vector<char> buf(size_t(3 * kMiB));
        std::string msg;
        try {
            while (reader.read(buf.data(), buf.size()) > 0) {
            }
        } catch (const Error& e) {
            msg = e.what();
        }
        EXPECT_CONTAINS(msg, "fill.gz: the gzip data inflate ");
        EXPECT_TRUE(reader.over_inflation_limit());
        EXPECT_LE(reader.bytes_read(), kInflationFreeBytes + 4 * kMiB);
        EXPECT_GT(reader.inflation_ratio(), double(kMaxInflationRatio));
    }
}

TEST(PlyGzipBomb, ErrorsAfterAbsurdInflationSaySo) {
    // Data that ends early after inflating 4.8 MB from a few KB: the error says why it is
    // likely a bomb; the same data from a plain file has no such note.
    const std::string bytes = ascii_xyz_header(500000, 1) + repeat("0.0 0.0 0.0\n", 400000);
    MeshLoadInfo info;
    const std::string msg = load_error(write_file("few.ply.gz", gzip_member(bytes)), info);
    EXPECT_CONTAINS(msg, "unexpected end of data");
    EXPECT_CONTAINS(msg, "(the gzip data inflated ");
    EXPECT_CONTAINS(msg, "far more than mesh data does: a gzip bomb?)");
    const std::string plain = load_error(write_file("few.ply", bytes), info);
    EXPECT_CONTAINS(plain, "unexpected end of data");
    EXPECT_EQ(plain.find("gzip"), std::string::npos) << plain;
}

const char* kOneTriangle =
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
    "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
    "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";

TEST(PlyGzipBomb, GigabytesOfTrailingBytesAreNotInflated) {
    // A valid mesh followed by 4 GiB of newlines or blanks (ascii) or zeros (binary): the
    // load succeeds after a bounded look at what follows the data.
    std::string binary = binary_xyz_header(3, 1);
    const float v[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    binary.append(reinterpret_cast<const char*>(v), sizeof(v));
    const int32_t tri[3] = {0, 1, 2};
    binary += char(3);
    binary.append(reinterpret_cast<const char*>(tri), sizeof(tri));
    struct Case {
        const char* name;
        std::string head;
        char fill;
    };
    for (const Case& c : {Case{"newlines", kOneTriangle, '\n'}, Case{"blanks", kOneTriangle, ' '},
                          Case{"zeros", binary, '\0'}}) {
        SCOPED_TRACE(c.name);
        const std::string path = write_file("trail.ply.gz", gzip_bomb(c.head, c.fill, 4096));
        MeshLoadInfo info;
        TriangleMesh mesh = read_ply(path, {}, &info);
        EXPECT_EQ(mesh.triangles.size(), 1u);
        EXPECT_EQ(mesh.positions.size(), 3u);
        EXPECT_LE(info.input_bytes_read, 8 * kMiB);
        // Blank text after ascii data is silent; binary bytes get a warning that can only
        // bound how many follow.
        if (c.fill == '\0') {
            ASSERT_EQ(info.warnings.size(), 1u);
            EXPECT_EQ(info.warnings[0], path + ": byte " + std::to_string(c.head.size()) +
                                            ": more than 65536 bytes after the last element, "
                                            "ignored (padding, or data the header's element "
                                            "counts leave out)");
        } else {
            EXPECT_TRUE(info.warnings.empty());
        }
    }
}

TEST(PlyGzipBomb, TextAfterTheDataIsStillFoundWithinTheLook) {
    // Non-blank text shortly after the last element is an error naming its line, gzip or not.
    const std::string bytes = std::string(kOneTriangle) + "\n\n \n" + "\x1b[31mjunk 1 2\n";
    for (const bool gz : {false, true}) {
        const std::string path =
            write_file(gz ? "t.ply.gz" : "t.ply", gz ? gzip_member(bytes) : bytes);
        MeshLoadInfo info;
        const std::string msg = load_error(path, info);
        EXPECT_CONTAINS(msg, "line 17: data after the last element");
        EXPECT_CONTAINS(msg, "junk");
    }
    // Beyond the look (2 MiB of newlines first), trailing text is not searched for.
    const std::string far = std::string(kOneTriangle) + std::string(size_t(2 * kMiB), '\n') + "x\n";
    EXPECT_EQ(read_ply(write_file("far.ply.gz", gzip_member(far))).triangles.size(), 1u);
}

}  // namespace
}  // namespace kdt
