// Tests of the PLY reader's messages (renderer/io/ply_*): hostile bytes (ESC sequences, BEL,
// NUL, invalid UTF-8, C1 and bidirectional controls) put in every place whose token the
// reader echoes come out escaped and never cut the message short; faces of fewer than three
// indices say so, in ascii and binary, whatever the header's counts.
#include <cstring>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/io/ply_reader.h"

namespace kdt {
namespace {

std::string error_of(const std::string& text) {
    try {
        read_ply_memory(text.data(), text.size(), "m.ply");
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

// No control byte and no byte of 0x80 or more outside a well-formed visible sequence: the
// hostile tokens below are all escaped to ASCII.
bool ascii_printable(const std::string& s) {
    for (char c : s)
        if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f)
            return false;
    return true;
}

const std::vector<std::string>& hostile_tokens() {
    static const std::vector<std::string> kTokens = {"q\x1b[31mred",
                                                     "b\x07"
                                                     "ell",
                                                     std::string("nu\0l", 4),
                                                     "\xff\xfe"
                                                     "x",
                                                     "c\xc2\x9b"
                                                     "2J",
                                                     "r\xe2\x80\xae"
                                                     "lo",
                                                     "t\x1b]0;title\x07"};
    return kTokens;
}

const std::string kVertexHeader =
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
    "property float z\n";
const std::string kFaceHeader =
    "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
const std::string kVertices = "0 0 0\n1 0 0\n0 1 0\n";

struct Place {
    const char* what;
    std::string file;    // '@' stands for the hostile token
    std::string suffix;  // how the message must end
};

std::vector<Place> places() {
    return {
        {"format", "ply\nformat @ 1.0\n", "'"},
        {"element count", "ply\nformat ascii 1.0\nelement vertex 3@\n", "is not an integer"},
        {"element name",
         kVertexHeader + "element @ 99999999\nproperty float w\n" + kFaceHeader + kVertices,
         "bytes of data in the file"},
        {"property type", kVertexHeader + "property @ w\n", "'"},
        {"property name", kVertexHeader + "property float @\nproperty float @\n", "'"},
        {"value", kVertexHeader + kFaceHeader + "0 @ 0\n1 0 0\n0 1 0\n3 0 1 2\n", "for property y"},
        {"vertex index", kVertexHeader + kFaceHeader + kVertices + "3 0 1 @\n", "'"},
        {"extra value", kVertexHeader + kFaceHeader + "0 0 0 @\n1 0 0\n0 1 0\n3 0 1 2\n",
         "after the last property)"},
        {"trailing data", kVertexHeader + kFaceHeader + kVertices + "3 0 1 2\n@\n",
         "do not match the data"},
        {"list name",
         kVertexHeader + "property list uchar int @\n" + kFaceHeader +
             "0 0 0 -1\n1 0 0 0\n0 1 0 0\n3 0 1 2\n",
         ""},
    };
}

TEST(PlyMessages, HostileTokensAreEscapedWherevertheyAreEchoed) {
    for (const Place& place : places()) {
        for (const std::string& token : hostile_tokens()) {
            SCOPED_TRACE(std::string(place.what) + " " + printable(token));
            std::string file = place.file;
            for (size_t at; (at = file.find('@')) != std::string::npos;) file.replace(at, 1, token);
            const std::string msg = error_of(file);
            ASSERT_FALSE(msg.empty());
            EXPECT_TRUE(ascii_printable(msg)) << printable(msg);
            EXPECT_NE(msg.find(printable(token)), std::string::npos) << msg;
            const std::string suffix = place.suffix.empty() ? printable(token) : place.suffix;
            ASSERT_GE(msg.size(), suffix.size());
            EXPECT_EQ(msg.substr(msg.size() - suffix.size()), suffix) << msg;
        }
    }
}

TEST(PlyMessages, FacesOfFewerThanThreeIndicesSaySoOrAreDropped) {
    // Face k of n has `count` indices, the others three. The file is just big enough for n
    // faces of `count` indices, so a header check assuming three per face would refuse it.
    for (int count = 0; count < 3; ++count) {
        for (const int k : {0, 12}) {
            const int n = 20;
            const std::string want = "face " + std::to_string(k) + ": " + std::to_string(count) +
                                     (count == 1 ? " index" : " indices") +
                                     ", a face needs at least 3";
            std::string ascii = kVertexHeader + "element face " + std::to_string(n) +
                                "\nproperty list uchar int vertex_indices\nend_header\n" +
                                kVertices;
            std::string binary =
                "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
                "property float y\nproperty float z\nelement face " +
                std::to_string(n) + "\nproperty list uchar int vertex_indices\nend_header\n";
            binary += std::string(36, '\0');
            for (int f = 0; f < n; ++f) {
                const int m = f < k ? 3 : count;
                ascii += std::to_string(m);
                binary += char(m);
                for (int j = 0; j < m; ++j) {
                    ascii += " " + std::to_string(j);
                    const int32_t v = j;
                    binary.append(reinterpret_cast<const char*>(&v), 4);
                }
                ascii += "\n";
            }
            for (const std::string* file : {&ascii, &binary}) {
                const std::string msg = error_of(*file);
                EXPECT_NE(msg.find(want + "; --drop-invalid drops such faces"), std::string::npos)
                    << msg;
                EXPECT_EQ(msg.find("bytes"), std::string::npos) << msg;
                // drop_invalid drops them and counts them.
                MeshLoadOptions drop;
                drop.drop_invalid = true;
                MeshLoadInfo info;
                EXPECT_EQ(read_ply_memory(file->data(), file->size(), "m.ply", drop, &info)
                              .triangle_count(),
                          size_t(k));
                EXPECT_EQ(info.dropped_faces, uint64_t(n - k));
                EXPECT_EQ(info.source_faces, uint64_t(n));
            }
        }
    }
}

}  // namespace
}  // namespace kdt
