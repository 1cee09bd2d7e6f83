// The OBJ reader with blocks of a few bytes (obj::set_block_bytes, as the fuzzer sets it):
// every line then takes the long-line path and block ends fall between CR and LF, '\' and
// its line end, inside keywords, values and the byte order mark, yet each input gives the
// mesh or the message of the default 1 MiB block.
#include <cstring>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/io/obj_reader.h"

namespace kdt {
namespace {

struct Result {
    TriangleMesh mesh;
    MeshLoadInfo info;
    std::string error;
};

Result read_with_block(const std::string& text, size_t block, const MeshLoadOptions& options) {
    const size_t old = obj::set_block_bytes(block);
    Result r;
    try {
        r.mesh = read_obj_memory(text.data(), text.size(), "t.obj", options, &r.info);
    } catch (const Error& e) {
        r.error = e.what();
    }
    obj::set_block_bytes(old);
    return r;
}

template <typename T>
bool same_bytes(const std::vector<T>& a, const std::vector<T>& b) {
    return a.size() == b.size() &&
           (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

const std::string kTri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
const std::string kBom = "\xef\xbb\xbf";

TEST(ObjSmallBlock, TrickyInputsReadAsWithTheDefaultBlock) {
    const std::string nul(1, '\0');
    const std::vector<std::string> inputs = {
        kTri,
        "v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 3\r\n",  // CRLF
        "v 0 0 0\rv 1 0 0\rv 0 1 0\rf 1 2 3\r",          // CR only
        "v 0 0 0\r\nv 1 0 0\rv 0 1 0\nf 1 2 3",          // mixed, no final line end
        "# " + std::string(300, 'c') + "\n" + kTri + "# " + std::string(200, 'c'),
        "v 0 0 0 # " + std::string(100, 'c') + "\\\n" + kTri,     // trailing comment continued
        "# comment \\\r\n" + kTri,                                // a comment line never is
        "v 0 \\\n0 \\\r\n 0\nv 1 0 0\\\rv 0 1 0\nf 1\\\n 2 3\n",  // continuations
        kTri + "f" + std::string(200, ' ') + "1 2 3 1 2 3 1 2 3 1 2 3\n",  // a long face
        kTri + "vt " + std::string(300, '1') + " 0\nf 1/1 2/1 3/1\n",
        kTri + "o " + std::string(100, 'n') + "\\\n" + std::string(100, 'm') + "\nf 3 2 1\n",
        kBom + kTri,
        kBom + "v 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0\n" + kTri,
        // Found by the fuzzer: a BOM split from its line by a block end; a BOM before a
        // comment line ending in '\'; a line of blanks continued onto a comment line; a NUL
        // after an invalid number (a NUL anywhere in a statement is the first error).
        kBom + "v 1 x\n",
        kBom + "# c \\\n" + kTri,
        "   \\\n  # c \\\n" + kTri + "f 1 2 " + nul + "\n",
        "v 0 0 0\nv na" + std::string(60, '\xf5') + " 0 " + nul + "\n" + kTri,
        kTri + "f 1 2 3 x" + std::string(50, ' ') + nul + "\n",
        // ... and a first token whose '\' ends a block, its line end unread.
        "\f\f\f\xa9" + nul + std::string(37, '\xff') + "?" + nul + "\\\n" +
            std::string(99, '\x9f') + "\nv 5\n",
        // A '\' ending the data, in a value, alone or after a continued line.
        kTri + "f 1 2 3\\",
        kTri + "f 1 2\\\r\n 3\\",
        kTri + "v\\",
        kTri + "\\",
        // Faces of fewer than 3 corners (dropped with drop_invalid) before one with normals.
        kTri + "vn 0 0 1\nf 1" + std::string(40, ' ') + "2\nf 2//1 1//1 3//1\nf\nf 9 3\n",
        // Errors and their lines.
        kTri + "f 1 2 9\n",
        kTri + "v 1 2\n",
        kTri + "vn 1 2 3 4\n",
        kTri + "f 1 2 \\\n 0\n",
        "v 1e99 0 0\n" + kTri + "f 4 2 3\n",
        kTri + std::string(100, '\x01') + "\n",
        std::string(64, '\0'),
        "",
    };
    for (size_t i = 0; i < inputs.size(); ++i) {
        for (const bool drop_invalid : {false, true}) {
            for (const bool keep_normals : {false, true}) {
                MeshLoadOptions options;
                options.drop_invalid = drop_invalid;
                options.keep_normals = keep_normals;
                const Result ref = read_with_block(inputs[i], size_t(1) << 20, options);
                for (const size_t block : {1, 2, 3, 4, 5, 7, 16, 33, 44, 64}) {
                    const Result r = read_with_block(inputs[i], block, options);
                    SCOPED_TRACE("input " + std::to_string(i) + ", block " + std::to_string(block));
                    EXPECT_EQ(r.error, ref.error);
                    EXPECT_TRUE(same_bytes(r.mesh.positions, ref.mesh.positions));
                    EXPECT_TRUE(same_bytes(r.mesh.triangles, ref.mesh.triangles));
                    EXPECT_TRUE(same_bytes(r.mesh.normals, ref.mesh.normals));
                    EXPECT_EQ(r.info.source_faces, ref.info.source_faces);
                    EXPECT_EQ(r.info.degenerate_faces, ref.info.degenerate_faces);
                    EXPECT_EQ(r.info.dropped_faces, ref.info.dropped_faces);
                }
            }
        }
    }
}

TEST(ObjSmallBlock, FuzzFoundInputsGiveTheShortFormsResult) {
    // A comment line after a BOM, or after a continued line of blanks, is not continued.
    const std::string a = kBom + "# c \\\n" + kTri;
    EXPECT_EQ(read_with_block(a, size_t(1) << 20, {}).mesh.triangles.size(), 1u);
    const std::string b = "   \\\n  # c \\\n" + kTri;
    EXPECT_EQ(read_with_block(b, size_t(1) << 20, {}).mesh.triangles.size(), 1u);
    // A NUL anywhere in a statement is reported before its values' errors.
    const std::string c = kTri + "v x" + std::string(50, ' ') + std::string(1, '\0') + "\n";
    EXPECT_EQ(read_with_block(c, 8, {}).error,
              "t.obj: line 5: NUL byte in a statement (binary data or UTF-16 text?)");
}

}  // namespace
}  // namespace kdt
