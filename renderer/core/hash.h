// One 64-bit hash over bytes for content fingerprints (meshes, files compared across MPI
// ranks). Not a checksum for files on disk (kdtree_cache's checksum64) and not cryptographic.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>

namespace kdt {

inline constexpr uint64_t kFnvOffset = 0xcbf29ce484222325ull;

/// FNV-1a over 8-byte words (then the remaining bytes), continuing from h: fast enough for
/// multi-million-vertex meshes. Data hashed in pieces gives the same result as in one piece
/// when every piece but the last is a multiple of 8 bytes long.
inline uint64_t fnv1a(uint64_t h, const void* data, size_t bytes) {
    const auto* p = static_cast<const unsigned char*>(data);
    size_t i = 0;
    for (; i + 8 <= bytes; i += 8) {
        uint64_t w;
        std::memcpy(&w, p + i, 8);
        h = (h ^ w) * 0x100000001b3ull;
    }
    for (; i < bytes; ++i) h = (h ^ p[i]) * 0x100000001b3ull;
    return h;
}

}  // namespace kdt
