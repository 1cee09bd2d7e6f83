// libFuzzer target for the OBJ reader: any input must load or throw a kdt::Error naming the
// file with a message safe to print, never crash, leak, hang or trip a sanitizer. Each input
// is read twice, with the default block of 1 MiB and with a block of 1..64 bytes (from the
// input), so that the long-line path and block ends are reached; the two must give the same
// mesh bit for bit or the same message. Built by tests/fuzz/tests.cmake (KDT_FUZZ=ON, clang);
// run by scripts/run_fuzz.sh.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "renderer/core/error.h"
#include "renderer/io/obj_reader.h"
#include "tests/fuzz/fuzz_mesh.h"

namespace {

kdt::fuzz::ReadResult read(const uint8_t* data, size_t size, const kdt::MeshLoadOptions& options) {
    return kdt::fuzz::result_of([&](kdt::MeshLoadInfo* info) {
        return kdt::read_obj_memory(data, size, "fuzz.obj", options, info);
    });
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    kdt::MeshLoadOptions options;
    // Exercise both the default (non-finite is an error) and the --drop-invalid path, and
    // the reader with and without normals.
    options.drop_invalid = size % 2 == 1;
    options.keep_normals = size % 4 < 2;
    const kdt::fuzz::ReadResult r = read(data, size, options);
    if (r.error.empty()) {
        const kdt::TriangleMesh& mesh = r.mesh;
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
        if (r.info.dropped_faces > r.info.source_faces) __builtin_trap();
    } else {
        if (std::strncmp(r.error.c_str(), "fuzz.obj: ", 10) != 0) {
            std::fprintf(stderr, "error without the file name: %s\n", r.error.c_str());
            __builtin_trap();
        }
        // Messages are safe to print: bytes from the file come out escaped.
        for (const char c : r.error)
            if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) __builtin_trap();
    }

    // The same input through a tiny block: the long-line path, block ends between CR and
    // LF, '\' and its line end, inside values and keywords.
    size_t hash = size;
    for (size_t i = 0; i < size && i < 16; ++i) hash = hash * 31 + data[i];
    const size_t block = 1 + hash % 64;
    const size_t old = kdt::obj::set_block_bytes(block);
    const kdt::fuzz::ReadResult small = read(data, size, options);
    kdt::obj::set_block_bytes(old);
    if (small.error != r.error) {
        std::fprintf(stderr, "block %zu: '%s'\ndefault: '%s'\n", block, small.error.c_str(),
                     r.error.c_str());
        __builtin_trap();
    }
    if (!kdt::fuzz::same_mesh(small.mesh, r.mesh) ||
        small.info.source_faces != r.info.source_faces ||
        small.info.dropped_faces != r.info.dropped_faces ||
        small.info.degenerate_faces != r.info.degenerate_faces) {
        std::fprintf(stderr, "block %zu: a different mesh\n", block);
        __builtin_trap();
    }
    return 0;
}
