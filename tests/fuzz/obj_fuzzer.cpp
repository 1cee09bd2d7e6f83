// libFuzzer target for the OBJ reader: any input must load or throw a kdt::Error naming the
// file with a message safe to print, never crash, leak, hang or trip a sanitizer. Built by
// tests/fuzz/tests.cmake (KDT_FUZZ=ON, clang); run by scripts/run_fuzz.sh.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>

#include "renderer/core/error.h"
#include "renderer/io/obj_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    kdt::MeshLoadOptions options;
    // Exercise both the default (non-finite is an error) and the --drop-invalid path, and
    // the reader with and without normals.
    options.drop_invalid = size % 2 == 1;
    options.keep_normals = size % 4 < 2;
    try {
        kdt::MeshLoadInfo info;
        kdt::TriangleMesh mesh = kdt::read_obj_memory(data, size, "fuzz.obj", options, &info);
        // Every index must be in range: read them all so ASan sees any stray one.
        for (const kdt::Vec3u& t : mesh.triangles) {
            if (t.x >= mesh.positions.size() || t.y >= mesh.positions.size() ||
                t.z >= mesh.positions.size())
                __builtin_trap();
        }
        if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size()) __builtin_trap();
        for (const kdt::Vec3f& p : mesh.positions) {
            if (!kdt::is_finite(p)) __builtin_trap();
        }
        if (info.dropped_faces > info.source_faces) __builtin_trap();
    } catch (const kdt::Error& e) {
        if (std::strncmp(e.what(), "fuzz.obj: ", 10) != 0) {
            std::fprintf(stderr, "error without the file name: %s\n", e.what());
            __builtin_trap();
        }
        // Messages are safe to print: bytes from the file come out escaped.
        for (const char* p = e.what(); *p; ++p)
            if (static_cast<unsigned char>(*p) < 0x20 || *p == 0x7f) __builtin_trap();
    }
    return 0;
}
