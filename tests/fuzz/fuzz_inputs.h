// What the fuzzers and their seed generator share: the fixed mesh and parameters that
// kd-tree cache inputs are checked against, and the meaning of a cache input's first byte.
// Depends on geometry and the kd-tree (header only).
#pragma once

#include <cstdint>
#include <memory>

#include "renderer/accel/kdtree.h"
#include "renderer/geometry/mesh.h"

namespace kdt::fuzz {

/// A small deterministic mesh (a 4x4 grid of quads on z = 0 and a dozen tilted triangles
/// above it): big enough for trees of a few dozen nodes, small enough for seeds of ~1 KB.
inline std::shared_ptr<const TriangleMesh> cache_mesh() {
    auto mesh = std::make_shared<TriangleMesh>();
    for (int y = 0; y <= 4; ++y) {
        for (int x = 0; x <= 4; ++x) mesh->positions.push_back(Vec3f(float(x), float(y), 0.0f));
    }
    for (uint32_t y = 0; y < 4; ++y) {
        for (uint32_t x = 0; x < 4; ++x) {
            const uint32_t a = y * 5 + x;
            mesh->triangles.push_back(Vec3u(a, a + 1, a + 6));
            mesh->triangles.push_back(Vec3u(a, a + 6, a + 5));
        }
    }
    uint32_t state = 12345u;  // a fixed LCG, so the mesh (and its hash) never changes
    auto next = [&state] {
        state = state * 1664525u + 1013904223u;
        return float(state >> 8) / float(1u << 24);
    };
    for (int i = 0; i < 12; ++i) {
        const uint32_t base = uint32_t(mesh->positions.size());
        const Vec3f c(4.0f * next(), 4.0f * next(), 0.5f + 2.0f * next());
        for (int k = 0; k < 3; ++k) {
            mesh->positions.push_back(c + Vec3f(next() - 0.5f, next() - 0.5f, next() - 0.5f));
        }
        mesh->triangles.push_back(Vec3u(base, base + 1, base + 2));
    }
    return mesh;
}

/// Cache inputs start with one mode byte, then the file image. Bits 0-1: the image is
/// resealed (checksums recomputed) unless both are 0, so three inputs in four reach the
/// structure checks behind the checksums. Bit 2: thesis builder parameters, else SAH.
inline bool cache_mode_reseal(uint8_t mode) { return (mode & 3u) != 0; }
inline KdTreeParams cache_params(uint8_t mode) {
    KdTreeParams p;
    if (mode & 4u) {
        p.builder = KdBuilder::thesis;
        p.max_depth = 12;
    }
    p.threads = 1;
    return p;
}

}  // namespace kdt::fuzz
