// Helpers shared by the PLY reader tests (ply_reader_test, ply_errors_test,
// ply_fast_paths_test): loading from memory, expected errors, a binary record builder and a
// small ascii model. Header only; depends on io and GoogleTest.
#pragma once

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/io/ply_reader.h"

namespace kdt::test {

inline TriangleMesh load(const std::string& text, MeshLoadOptions options = {},
                         MeshLoadInfo* info = nullptr) {
    return read_ply_memory(text.data(), text.size(), "test.ply", options, info);
}

// Loads `text`, expects a kdt::Error and returns its message ("" when none was thrown).
inline std::string error_of(const std::string& text, MeshLoadOptions options = {}) {
    try {
        load(text, options);
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

#define EXPECT_ERROR(text, substring)                                                            \
    do {                                                                                         \
        std::string msg_ = ::kdt::test::error_of(text);                                          \
        EXPECT_NE(msg_.find(substring), std::string::npos)                                       \
            << "expected an error containing \"" << (substring) << "\", got \"" << msg_ << "\""; \
    } while (0)

// Writes `data` to dir/name and returns the path.
inline std::string write_text(const std::filesystem::path& dir, const std::string& name,
                              const std::string& data) {
    std::ofstream(dir / name, std::ios::binary) << data;
    return (dir / name).string();
}

// Reads the file, expects a kdt::Error and returns its message ("" when none was thrown).
inline std::string error_of_file(const std::string& path) {
    try {
        read_ply(path);
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

inline void expect_same_mesh(const TriangleMesh& a, const TriangleMesh& b) {
    EXPECT_EQ(a.positions, b.positions);
    EXPECT_EQ(a.triangles, b.triangles);
}

// Binary record builder.
struct Bytes {
    std::string s;
    bool big = false;
    template <typename T>
    Bytes& put(T v) {
        char b[sizeof(T)];
        std::memcpy(b, &v, sizeof(T));
        if (big) std::reverse(b, b + sizeof(T));
        s.append(b, sizeof(T));
        return *this;
    }
};

inline constexpr const char* kCubeAscii =
    "ply\n"
    "format ascii 1.0\n"
    "comment a unit square and a triangle\n"
    "obj_info made by hand\n"
    "element vertex 5\n"
    "property float x\n"
    "property float y\n"
    "property float z\n"
    "element face 2\n"
    "property list uchar int vertex_indices\n"
    "end_header\n"
    "0 0 0\n"
    "1 0 0\n"
    "1 1 0\n"
    "0 1 0\n"
    "0.5 0.5 1\n"
    "4 0 1 2 3\n"
    "3 0 1 4\n";

}  // namespace kdt::test
