#include "renderer/geometry/mesh.h"

#include <cmath>
#include <cstring>
#include <unordered_map>

namespace kdt {

size_t TriangleMesh::memory_bytes() const {
    return positions.size() * sizeof(Vec3f) + normals.size() * sizeof(Vec3f) +
           colors.size() * sizeof(Vec3f) + triangles.size() * sizeof(Vec3u);
}

Bounds3f TriangleMesh::bounds() const {
    Bounds3f b;
    for (const Vec3f& p : positions) b.extend(p);
    return b;
}

namespace {

uint64_t fnv1a(uint64_t h, const void* data, size_t bytes) {
    const auto* p = static_cast<const unsigned char*>(data);
    // Hash 8 bytes at a time (FNV-1a over words) so multi-million-vertex meshes hash fast.
    size_t i = 0;
    for (; i + 8 <= bytes; i += 8) {
        uint64_t w;
        std::memcpy(&w, p + i, 8);
        h = (h ^ w) * 0x100000001b3ull;
    }
    for (; i < bytes; ++i) h = (h ^ p[i]) * 0x100000001b3ull;
    return h;
}

}  // namespace

uint64_t TriangleMesh::content_hash() const {
    uint64_t h = 0xcbf29ce484222325ull;
    uint64_t counts[2] = {positions.size(), triangles.size()};
    h = fnv1a(h, counts, sizeof(counts));
    h = fnv1a(h, positions.data(), positions.size() * sizeof(Vec3f));
    h = fnv1a(h, triangles.data(), triangles.size() * sizeof(Vec3u));
    return h;
}

void append_mesh(TriangleMesh& dst, const TriangleMesh& src) {
    const bool dst_empty = dst.positions.empty();
    const bool keep_normals = (dst_empty || !dst.normals.empty()) && !src.normals.empty();
    const bool keep_colors = (dst_empty || !dst.colors.empty()) && !src.colors.empty();
    const auto base = static_cast<uint32_t>(dst.positions.size());
    dst.positions.insert(dst.positions.end(), src.positions.begin(), src.positions.end());
    if (keep_normals) {
        dst.normals.insert(dst.normals.end(), src.normals.begin(), src.normals.end());
    } else {
        dst.normals.clear();
    }
    if (keep_colors) {
        dst.colors.insert(dst.colors.end(), src.colors.begin(), src.colors.end());
    } else {
        dst.colors.clear();
    }
    dst.triangles.reserve(dst.triangles.size() + src.triangles.size());
    for (const Vec3u& t : src.triangles) dst.triangles.push_back(t + Vec3u(base));
}

void transform_mesh(TriangleMesh& mesh, const Mat4f& world_from_object) {
    for (Vec3f& p : mesh.positions) p = Vec3f(world_from_object * Vec4f(p, 1.0f));
    if (!mesh.normals.empty()) {
        Mat3f n = glm::transpose(glm::inverse(Mat3f(world_from_object)));
        for (Vec3f& v : mesh.normals) {
            Vec3f w = n * v;
            float len = glm::length(w);
            v = len > 0.0f ? w / len : w;
        }
    }
}

std::vector<Vec3f> compute_vertex_normals(const TriangleMesh& mesh) {
    std::vector<Vec3f> n(mesh.positions.size(), Vec3f(0.0f));
    for (const Vec3u& t : mesh.triangles) {
        const Vec3f p[3] = {mesh.positions[t.x], mesh.positions[t.y], mesh.positions[t.z]};
        Vec3f fn = glm::cross(p[1] - p[0], p[2] - p[0]);
        float len = glm::length(fn);
        if (!(len > 0.0f) || !std::isfinite(len)) continue;
        fn /= len;
        for (int k = 0; k < 3; ++k) {
            Vec3f e0 = p[(k + 1) % 3] - p[k];
            Vec3f e1 = p[(k + 2) % 3] - p[k];
            float l0 = glm::length(e0), l1 = glm::length(e1);
            if (!(l0 > 0.0f) || !(l1 > 0.0f)) continue;
            float c = glm::clamp(glm::dot(e0, e1) / (l0 * l1), -1.0f, 1.0f);
            n[t[k]] += std::acos(c) * fn;
        }
    }
    for (Vec3f& v : n) {
        float len = glm::length(v);
        v = len > 0.0f ? v / len : Vec3f(0.0f, 0.0f, 1.0f);
    }
    return n;
}

TriangleMesh subdivide_mesh(const TriangleMesh& mesh, int levels) {
    TriangleMesh cur = mesh;
    for (int level = 0; level < levels; ++level) {
        TriangleMesh next;
        next.positions = cur.positions;
        const bool has_n = !cur.normals.empty(), has_c = !cur.colors.empty();
        next.normals = cur.normals;
        next.colors = cur.colors;
        next.triangles.reserve(cur.triangles.size() * 4);
        std::unordered_map<uint64_t, uint32_t> midpoint;
        midpoint.reserve(cur.triangles.size() * 2);
        auto mid = [&](uint32_t a, uint32_t b) {
            uint64_t key = a < b ? (uint64_t(a) << 32 | b) : (uint64_t(b) << 32 | a);
            auto [it, inserted] = midpoint.try_emplace(key, uint32_t(next.positions.size()));
            if (inserted) {
                next.positions.push_back(0.5f * (cur.positions[a] + cur.positions[b]));
                if (has_n) next.normals.push_back(glm::normalize(cur.normals[a] + cur.normals[b]));
                if (has_c) next.colors.push_back(0.5f * (cur.colors[a] + cur.colors[b]));
            }
            return it->second;
        };
        for (const Vec3u& t : cur.triangles) {
            uint32_t ab = mid(t.x, t.y), bc = mid(t.y, t.z), ca = mid(t.z, t.x);
            next.triangles.push_back({t.x, ab, ca});
            next.triangles.push_back({ab, t.y, bc});
            next.triangles.push_back({ca, bc, t.z});
            next.triangles.push_back({ab, bc, ca});
        }
        cur = std::move(next);
    }
    return cur;
}

}  // namespace kdt
