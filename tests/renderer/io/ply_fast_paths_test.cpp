// Tests of the fast paths of renderer/io/ply_reader against the plain ones: binary face and
// vertex runs against record-by-record decoding, the ascii float parser against from_chars,
// two-thread ascii against one thread, and mapped files against memory.

#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/io/ply_reader.h"
#include "renderer/io/ply_writer.h"
#include "tests/renderer/io/ply_test_util.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

using test::Bytes;
using test::error_of;
using test::error_of_file;
using test::expect_same_mesh;
using test::load;
using test::write_text;

// Binary faces of 4-byte indices are decoded in runs; a polygon, a degenerate face or a bad
// index anywhere (at a run's start, end or middle) leaves the run to the record-by-record
// path: same triangles, counts and errors in both byte orders, signed and unsigned, as with
// 2-byte indices (no runs).
TEST(PlyReader, BinaryFaceRunsMatchRecordByRecord) {
    const int nv = 5000, nf = 9000;
    std::mt19937 rng(11);
    std::uniform_int_distribution<int> vi(0, nv - 1);
    std::vector<std::vector<int>> faces;
    std::vector<Vec3u> expected;
    for (int f = 0; f < nf; ++f) {
        std::vector<int> c;
        if (f == 0 || f == 1023 || f == 1024 || f == 5000) {
            c = {vi(rng) % 1000, 1000 + vi(rng) % 1000, 2000 + vi(rng) % 1000,
                 3000 + vi(rng) % 1000};
        } else if (f == 2047 || f == 2048 || f == 6000) {
            // a = b, b = c and c = a in turn.
            const int a = vi(rng), b = (a + 1) % nv;
            c = f % 3 == 0 ? std::vector<int>{a, a, b}
                           : (f % 3 == 1 ? std::vector<int>{b, a, a} : std::vector<int>{a, b, a});
        } else {
            c = {vi(rng) % 1500, 1500 + vi(rng) % 1500, 3000 + vi(rng) % 2000};
        }
        for (size_t k = 1; k + 1 < c.size(); ++k)
            expected.emplace_back(uint32_t(c[0]), uint32_t(c[k]), uint32_t(c[k + 1]));
        faces.push_back(c);
    }
    for (bool big : {false, true}) {
        for (const char* type : {"int", "uint", "ushort"}) {
            auto file = [&](int bad_face, int bad_index) {
                Bytes b;
                b.big = big;
                for (int i = 0; i < nv; ++i) b.put(float(i)).put(0.5f).put(-1.0f);
                for (int f = 0; f < nf; ++f) {
                    b.put(uint8_t(faces[size_t(f)].size()));
                    for (size_t k = 0; k < faces[size_t(f)].size(); ++k) {
                        const int v = f == bad_face && k == 1 ? bad_index : faces[size_t(f)][k];
                        if (std::string(type) == "ushort")
                            b.put(uint16_t(v));
                        else
                            b.put(int32_t(v));
                    }
                }
                return std::string("ply\nformat ") +
                       (big ? "binary_big_endian" : "binary_little_endian") +
                       " 1.0\nelement vertex " + std::to_string(nv) +
                       "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
                       std::to_string(nf) + "\nproperty list uchar " + type +
                       " vertex_indices\nend_header\n" + b.s;
            };
            SCOPED_TRACE(std::string(big ? "big endian, " : "little endian, ") + type);
            MeshLoadInfo info;
            TriangleMesh m = load(file(-1, 0), {}, &info);
            EXPECT_EQ(m.triangles, expected);
            EXPECT_EQ(info.source_faces, uint64_t(nf));
            EXPECT_EQ(info.degenerate_faces, 3u);
            // A bad index in the middle of a run: the error names its face and first byte.
            const std::string text = file(3000, nv + 7);
            const size_t isz = std::string(type) == "ushort" ? 2 : 4;
            size_t at = text.find("end_header\n") + 11 + size_t(nv) * 12;
            for (int f = 0; f < 3000; ++f) at += 1 + faces[size_t(f)].size() * isz;
            EXPECT_ERROR(text, "test.ply: byte " + std::to_string(at) +
                                   ": face 3000: vertex index " + std::to_string(nv + 7) +
                                   " out of range (5000 vertices)");
            if (std::string(type) == "int")
                EXPECT_ERROR(file(4095, -3), "face 4095: vertex index -3 out of range");
        }
    }
}

// Binary vertices of float x, y, z are decoded in runs; a non-finite one anywhere (at a run's
// start, end or middle) goes to the record-by-record path: the same error, or with
// drop_invalid the same dropped vertices and faces, in both byte orders, with the
// coordinates alone in the record or after another property.
TEST(PlyReader, BinaryVertexRunsMatchRecordByRecord) {
    const int nv = 5000;
    const std::vector<int> bad = {1023, 1024, 3002};  // NaN in x, y, z (i % 3)
    auto is_bad = [&](int i) { return std::find(bad.begin(), bad.end(), i) != bad.end(); };
    for (bool big : {false, true}) {
        for (bool leading : {false, true}) {
            SCOPED_TRACE(std::string(big ? "big endian" : "little endian") +
                         (leading ? ", after another property" : ""));
            // NaN in the vertices `nan_at` (x, y or z by i % 3).
            auto file = [&](const std::vector<int>& nan_at) {
                Bytes b;
                b.big = big;
                for (int i = 0; i < nv; ++i) {
                    if (leading) b.put(float(-i));
                    const bool bad_i = std::find(nan_at.begin(), nan_at.end(), i) != nan_at.end();
                    const int nan_in = bad_i ? int(i % 3) : -1;
                    b.put(nan_in == 0 ? NAN : float(i))
                        .put(nan_in == 1 ? NAN : 0.25f * float(i))
                        .put(nan_in == 2 ? NAN : -1.0f);
                }
                for (int f = 0; f + 2 < nv; ++f)
                    b.put(uint8_t(3)).put(uint32_t(f)).put(uint32_t(f + 1)).put(uint32_t(f + 2));
                return std::string("ply\nformat ") +
                       (big ? "binary_big_endian" : "binary_little_endian") +
                       " 1.0\nelement vertex " + std::to_string(nv) +
                       (leading ? "\nproperty float confidence" : "") +
                       "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
                       std::to_string(nv - 2) +
                       "\nproperty list uchar uint vertex_indices\nend_header\n" + b.s;
            };
            TriangleMesh all = load(file({}));
            ASSERT_EQ(all.vertex_count(), size_t(nv));
            for (int i = 0; i < nv; ++i)
                ASSERT_EQ(all.positions[size_t(i)], Vec3f(float(i), 0.25f * float(i), -1.0f));
            // Each bad vertex alone is an error naming it and its first byte.
            const size_t rec = leading ? 16 : 12;
            for (int i : bad) {
                const std::string text = file({i});
                const size_t at = text.find("end_header\n") + 11 + size_t(i) * rec;
                EXPECT_ERROR(text, "test.ply: byte " + std::to_string(at) + ": vertex " +
                                       std::to_string(i) + ": non-finite coordinate (");
            }
            const std::string text = file(bad);
            MeshLoadOptions o;
            o.drop_invalid = true;
            MeshLoadInfo info;
            TriangleMesh m = load(text, o, &info);
            std::vector<Vec3f> positions;
            for (int i = 0; i < nv; ++i)
                if (!is_bad(i)) positions.emplace_back(float(i), 0.25f * float(i), -1.0f);
            EXPECT_EQ(m.positions, positions);
            // Faces (f, f + 1, f + 2) touching 1023, 1024 or 3002: f = 1021 to 1024, 3000 to 3002.
            EXPECT_EQ(info.dropped_faces, 7u);
            EXPECT_EQ(m.triangle_count(), size_t(nv - 2 - 7));
        }
    }
}

// The ascii fast path (Clinger with a reciprocal multiply) must give the correctly rounded
// float for every input: compare against from_chars on random floats in several notations.
TEST(PlyReader, AsciiFloatsParseExactly) {
    std::mt19937 rng(12345);
    std::uniform_int_distribution<uint32_t> bits;
    std::string data;
    std::vector<float> expect;
    const int n = 20000;
    char buf[64];
    for (int i = 0; i < n; ++i) {
        float f;
        do {
            f = std::bit_cast<float>(bits(rng));
        } while (!std::isfinite(f));
        if (i % 3 == 1)
            f = float(std::ldexp(double(bits(rng) % 2000000) - 1e6, -int(bits(rng) % 20)));
        int style = i % 4;
        if (style == 0) {
            auto r = std::to_chars(buf, buf + 64, f);
            *r.ptr = 0;
        } else if (style == 1) {
            std::snprintf(buf, sizeof buf, "%.9g", double(f));
        } else if (style == 2) {
            std::snprintf(buf, sizeof buf, "%.6f", double(f));
        } else {
            std::snprintf(buf, sizeof buf, "%.7e", double(f));
        }
        float ref = 0;
        std::from_chars(buf, buf + std::strlen(buf), ref);
        expect.push_back(ref);
        data += std::string(buf) + " 0 0\n";
    }
    std::string h = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(n) +
                    "\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
    TriangleMesh m = load(h + data);
    ASSERT_EQ(m.vertex_count(), size_t(n));
    int wrong = 0;
    for (int i = 0; i < n; ++i)
        wrong += std::bit_cast<uint32_t>(m.positions[size_t(i)].x) !=
                 std::bit_cast<uint32_t>(expect[size_t(i)]);
    EXPECT_EQ(wrong, 0);
}

// A large ascii file (several parallel chunks) with the irregular lines the two-thread
// path must hand to the serial one: blank lines, a polygon, a degenerate face, and with
// drop_invalid a non-finite vertex. One and two threads must agree exactly, and report
// errors on the same line.
std::string big_ascii(bool with_nan, bool irregular = true) {
    const int nv = 60000, nf = 120000;
    std::string s = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(nv) +
                    "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
                    std::to_string(nf) + "\nproperty list uchar int vertex_indices\nend_header\n";
    std::mt19937 rng(99);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    char buf[96];
    for (int i = 0; i < nv; ++i) {
        if (with_nan && i == 40000) {
            s += "nan 0 0\n";
            continue;
        }
        std::snprintf(buf, sizeof buf, "%.7g %.7g %.7g\n", double(u(rng)), double(u(rng)),
                      double(u(rng)));
        s += buf;
        if (i == 20000 && irregular) s += "\n   \n";
    }
    std::uniform_int_distribution<int> vi(0, nv - 1);
    for (int f = 0; f < nf; ++f) {
        if (f == 70000 && irregular) {
            s += "4 1 2 3 4\n";
        } else if (f == 90000 && irregular) {
            s += "3 5 5 6\n";
        } else {
            s += "3 " + std::to_string(vi(rng)) + " " + std::to_string(vi(rng)) + " " +
                 std::to_string(vi(rng)) + "\n";
        }
    }
    return s;
}

TEST(PlyReader, TwoThreadAsciiMatchesOneThread) {
    for (bool with_nan : {false, true}) {
        std::string text = big_ascii(with_nan);
        MeshLoadOptions one, two;
        one.threads = 1;
        two.threads = 2;
        one.drop_invalid = two.drop_invalid = with_nan;
        MeshLoadInfo i1, i2;
        TriangleMesh a = load(text, one, &i1), b = load(text, two, &i2);
        EXPECT_EQ(a.positions, b.positions);
        EXPECT_EQ(a.triangles, b.triangles);
        EXPECT_EQ(a.triangle_count(), with_nan ? 120001u - i1.dropped_faces : 120001u);
        EXPECT_EQ(i1.dropped_faces > 0, with_nan);
        EXPECT_EQ(i1.degenerate_faces, i2.degenerate_faces);
        EXPECT_EQ(i1.dropped_faces, i2.dropped_faces);
        EXPECT_EQ(i1.source_faces, 120000u);
        EXPECT_EQ(i2.source_faces, 120000u);
        EXPECT_GE(i2.degenerate_faces, 1u);
    }
    // Regular lines only: every chunk is taken whole by the tight loop.
    {
        std::string text = big_ascii(false, false);
        MeshLoadOptions one, two;
        one.threads = 1;
        two.threads = 2;
        TriangleMesh a = load(text, one), b = load(text, two), c = load(text);
        EXPECT_EQ(a.triangle_count(), 120000u);
        EXPECT_EQ(a.positions, b.positions);
        EXPECT_EQ(a.triangles, b.triangles);
        EXPECT_EQ(a.triangles, c.triangles);
    }
    // An error deep in the file: same message (same line) either way.
    std::string text = big_ascii(false);
    size_t pos = text.find("\n3 ", text.size() - 200000);
    text.replace(pos + 1, 1, "2");
    std::string e1, e2;
    MeshLoadOptions one, two;
    one.threads = 1;
    two.threads = 2;
    try {
        load(text, one);
    } catch (const Error& e) {
        e1 = e.what();
    }
    try {
        load(text, two);
    } catch (const Error& e) {
        e2 = e.what();
    }
    EXPECT_NE(e1.find("indices, a face needs at least 3"), std::string::npos) << e1;
    EXPECT_EQ(e1, e2);
}

// Files of 1 MiB and more are mapped and read through a sliding window instead of a buffer:
// same meshes and same errors as from memory, in every encoding, for a file ending exactly
// on a page without a final newline, and for one cut short.
TEST(PlyReader, MappedFilesMatchMemory) {
    const std::filesystem::path dir = test::temp_dir("ply_mapped");
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    const int nv = 100000, nf = 200000;
    std::string text = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(nv) +
                       "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
                       std::to_string(nf) +
                       "\nproperty list uchar int vertex_indices\nend_header\n";
    char buf[96];
    for (int i = 0; i < nv; ++i) {
        std::snprintf(buf, sizeof buf, "%.7g %.7g %.7g\n", double(u(rng)), double(u(rng)),
                      double(u(rng)));
        text += buf;
    }
    std::uniform_int_distribution<int> vi(0, nv - 1);
    for (int f = 0; f < nf; ++f) {
        int a = vi(rng), b = (a + 1 + vi(rng) % 1000) % nv, c = (b + 1 + vi(rng) % 1000) % nv;
        if (c == a) c = (c + 1) % nv;
        text += (f == 150000 ? "4 " : "3 ") + std::to_string(a) + " " + std::to_string(b) + " " +
                std::to_string(c) + (f == 150000 ? " 7" : "") + "\n";
    }
    ASSERT_GT(text.size(), size_t(6) << 20);  // more than one window
    auto write = [&](const std::string& name, const std::string& data) {
        return write_text(dir, name, data);
    };
    const auto same = expect_same_mesh;
    const TriangleMesh ref = load(text);
    ASSERT_EQ(ref.triangle_count(), size_t(nf + 1));
    for (int threads : {1, 2}) {
        MeshLoadOptions options;
        options.threads = threads;
        MeshLoadInfo info;
        same(read_ply(write("a.ply", text), options, &info), ref);
        EXPECT_EQ(info.file_bytes, text.size());
        // Ends on a page boundary, last line without its newline: the parser reads the
        // padding past the mapped file.
        std::string cut = text.substr(0, text.size() - 1);
        const size_t pad = (4096 - cut.size() % 4096) % 4096;
        cut.insert(cut.find("end_header"),
                   "comment " + std::string(pad > 9 ? pad - 9 : 0, 'x') + "\n");
        cut.insert(cut.find("end_header"), std::string((4096 - cut.size() % 4096) % 4096, ' '));
        ASSERT_EQ(cut.size() % 4096, 0u);
        same(read_ply(write("b.ply", cut), options), ref);
    }
    // Truncated mid-file: the same message as from memory.
    const std::string trunc = text.substr(0, text.size() * 3 / 4);
    const std::string from_file = error_of_file(write("c.ply", trunc));
    const std::string from_memory = error_of(trunc);
    EXPECT_NE(from_memory.find("unexpected end of data"), std::string::npos) << from_memory;
    EXPECT_EQ(from_file.substr(from_file.find(':')), from_memory.substr(from_memory.find(':')));
    // Binary copies, little- and big-endian, through the same window.
    for (PlyEncoding enc : {PlyEncoding::binary_little_endian, PlyEncoding::binary_big_endian}) {
        const std::string path = (dir / "bin.ply").string();
        write_ply(path, ref, enc);
        ASSERT_GT(std::filesystem::file_size(path), uint64_t(1) << 20);
        same(read_ply(path), ref);
    }
    std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace kdt
