// libFuzzer target for the PLY reader: any input must load or throw kdt::Error, never
// crash, leak, hang or trip a sanitizer. Built by tests/fuzz/tests.cmake (KDT_FUZZ=ON,
// clang); run by scripts/run_fuzz.sh.
#include <cstddef>
#include <cstdint>

#include "renderer/core/error.h"
#include "renderer/io/ply_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    kdt::MeshLoadOptions options;
    // Exercise both the default (non-finite is an error) and the --drop-invalid path.
    options.drop_invalid = size % 2 == 1;
    try {
        kdt::MeshLoadInfo info;
        kdt::TriangleMesh mesh = kdt::read_ply_memory(data, size, "fuzz.ply", options, &info);
        // Every index must be in range: read them all so ASan sees any stray one.
        for (const kdt::Vec3u& t : mesh.triangles) {
            if (t.x >= mesh.positions.size() || t.y >= mesh.positions.size() ||
                t.z >= mesh.positions.size())
                __builtin_trap();
        }
        if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size()) __builtin_trap();
        if (!mesh.colors.empty() && mesh.colors.size() != mesh.positions.size()) __builtin_trap();
    } catch (const kdt::Error&) {
    }
    return 0;
}
