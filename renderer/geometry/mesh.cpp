#include "renderer/geometry/mesh.h"

#include <cmath>
#include <cstring>
#include <unordered_map>
#include <utility>

#include "renderer/core/error.h"
#include "renderer/core/hash.h"

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

uint64_t TriangleMesh::content_hash() const {
    uint64_t h = kFnvOffset;
    uint64_t counts[2] = {positions.size(), triangles.size()};
    h = fnv1a(h, counts, sizeof(counts));
    h = fnv1a(h, positions.data(), positions.size() * sizeof(Vec3f));
    h = fnv1a(h, triangles.data(), triangles.size() * sizeof(Vec3u));
    return h;
}

namespace {

// Spreads the low 10 bits of v to every third bit (bit i goes to bit 3i).
uint32_t spread_bits(uint32_t v) {
    v &= 0x3ffu;
    v = (v | (v << 16)) & 0x030000ffu;
    v = (v | (v << 8)) & 0x0300f00fu;
    v = (v | (v << 4)) & 0x030c30c3u;
    v = (v | (v << 2)) & 0x09249249u;
    return v;
}

}  // namespace

MeshOrder spatial_order(const TriangleMesh& mesh) {
    const size_t nt = mesh.triangles.size(), nv = mesh.positions.size();
    MeshOrder order;
    // Centres on a 1024^3 grid over the bounds of the finite vertices.
    Bounds3f b;
    for (const Vec3f& p : mesh.positions)
        if (is_finite(p)) b.extend(p);
    const Vec3f lower = b.empty() ? Vec3f(0.0f) : b.lower;
    const Vec3f ext = b.empty() ? Vec3f(0.0f) : b.extent();
    Vec3f scale;
    for (int k = 0; k < 3; ++k) scale[k] = ext[k] > 0.0f ? 1023.0f / ext[k] : 0.0f;
    std::vector<uint32_t> code(nt);
    for (size_t i = 0; i < nt; ++i) {
        const Vec3u& t = mesh.triangles[i];
        uint32_t c = 0;
        if (t.x < nv && t.y < nv && t.z < nv) {
            const Vec3f lo =
                glm::min(mesh.positions[t.x], glm::min(mesh.positions[t.y], mesh.positions[t.z]));
            const Vec3f hi =
                glm::max(mesh.positions[t.x], glm::max(mesh.positions[t.y], mesh.positions[t.z]));
            const Vec3f g = (0.5f * (lo + hi) - lower) * scale;
            uint32_t q[3];
            for (int k = 0; k < 3; ++k) {
                // NaN and out-of-range values clamp to the grid (a NaN compares false).
                const float v = g[k] >= 0.0f ? std::min(g[k], 1023.0f) : 0.0f;
                q[k] = uint32_t(v);
            }
            c = (spread_bits(q[0]) << 2) | (spread_bits(q[1]) << 1) | spread_bits(q[2]);
        }
        code[i] = c;
    }
    // Stable LSD radix sort of the 30-bit codes in two 15-bit passes.
    std::vector<uint32_t> a(nt), tmp(nt);
    for (size_t i = 0; i < nt; ++i) a[i] = uint32_t(i);
    std::vector<uint32_t> count(1u << 15);
    for (int pass = 0; pass < 2; ++pass) {
        const int shift = 15 * pass;
        std::fill(count.begin(), count.end(), 0u);
        for (size_t i = 0; i < nt; ++i) ++count[(code[a[i]] >> shift) & 0x7fffu];
        uint32_t sum = 0;
        for (uint32_t& c : count) {
            const uint32_t n = c;
            c = sum;
            sum += n;
        }
        for (size_t i = 0; i < nt; ++i) tmp[count[(code[a[i]] >> shift) & 0x7fffu]++] = a[i];
        a.swap(tmp);
    }
    order.triangles = std::move(a);
    // Vertices in order of first use.
    constexpr uint32_t kUnset = 0xffffffffu;
    std::vector<uint32_t> new_index(nv, kUnset);
    order.vertices.reserve(nv);
    for (uint32_t ti : order.triangles) {
        const Vec3u& t = mesh.triangles[ti];
        for (int k = 0; k < 3; ++k) {
            if (t[k] < nv && new_index[t[k]] == kUnset) {
                new_index[t[k]] = uint32_t(order.vertices.size());
                order.vertices.push_back(t[k]);
            }
        }
    }
    for (uint32_t v = 0; v < nv; ++v)
        if (new_index[v] == kUnset) order.vertices.push_back(v);
    return order;
}

void apply_order(TriangleMesh& mesh, const MeshOrder& order) {
    const size_t nv = mesh.positions.size();
    std::vector<uint32_t> new_index(nv);
    for (size_t i = 0; i < order.vertices.size(); ++i) new_index[order.vertices[i]] = uint32_t(i);
    mesh.positions = permuted(mesh.positions, order.vertices);
    if (!mesh.normals.empty()) mesh.normals = permuted(mesh.normals, order.vertices);
    if (!mesh.colors.empty()) mesh.colors = permuted(mesh.colors, order.vertices);
    std::vector<Vec3u> tris(order.triangles.size());
    for (size_t i = 0; i < tris.size(); ++i) {
        const Vec3u& t = mesh.triangles[order.triangles[i]];
        // Out-of-range indices (possible only for unchecked meshes) stay out of range.
        auto map = [&](uint32_t v) { return v < nv ? new_index[v] : v; };
        tris[i] = Vec3u(map(t.x), map(t.y), map(t.z));
    }
    mesh.triangles = std::move(tris);
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
    const glm::dmat3 m{Mat3f{world_from_object}};
    const bool mirrors = glm::determinant(m) < 0.0;
    // A transform that swaps handedness turns counter-clockwise windings clockwise: without
    // the swap the geometric normals would point inwards, which the dielectric (one-sided,
    // entering or leaving by that normal) would read as an inside-out object (pbrt's
    // SwapsHandedness()).
    if (mirrors)
        for (Vec3u& t : mesh.triangles) std::swap(t.y, t.z);
    if (!mesh.normals.empty()) {
        // Normals go by the inverse transpose; they are normalised, so any positive multiple
        // of it serves: the cofactor matrix (det times the inverse transpose) needs no
        // division, and double keeps its products of tiny or huge scales finite (a float
        // inverse of a scale of 1e-15 divides by a determinant that underflows to 0).
        glm::dmat3 cof(glm::cross(m[1], m[2]), glm::cross(m[2], m[0]), glm::cross(m[0], m[1]));
        if (mirrors) cof = -cof;
        for (Vec3f& v : mesh.normals) {
            const Vec3d w = cof * Vec3d(v);
            const double len = glm::length(w);
            v = len > 0.0 ? Vec3f(w / len) : Vec3f(w);
        }
    }
}

std::vector<Vec3f> compute_vertex_normals(const TriangleMesh& mesh) {
    std::vector<Vec3f> n(mesh.positions.size(), Vec3f(0.0f));
    for (const Vec3u& t : mesh.triangles) {
        const Vec3f p[3] = {mesh.positions[t.x], mesh.positions[t.y], mesh.positions[t.z]};
        const Vec3f fn = triangle_normal(p[0], p[1], p[2]);
        if (fn == Vec3f(0.0f)) continue;
        for (int k = 0; k < 3; ++k) {
            // The corner's angle, in double for the same reason as triangle_normal().
            const Vec3d e0 = Vec3d(p[(k + 1) % 3]) - Vec3d(p[k]);
            const Vec3d e1 = Vec3d(p[(k + 2) % 3]) - Vec3d(p[k]);
            const double l0 = glm::length(e0), l1 = glm::length(e1);
            if (!(l0 > 0.0) || !(l1 > 0.0)) continue;
            const double c = glm::clamp(glm::dot(e0, e1) / (l0 * l1), -1.0, 1.0);
            n[t[k]] += float(std::acos(c)) * fn;
        }
    }
    for (Vec3f& v : n) {
        float len = glm::length(v);
        v = len > 0.0f ? v / len : Vec3f(0.0f, 0.0f, 1.0f);
    }
    return n;
}

uint64_t subdivided_triangle_count(uint64_t triangles, int levels) {
    uint64_t n = triangles;
    for (int i = 0; i < levels && n > 0; ++i)
        n = n >= (uint64_t(1) << 61) ? uint64_t(1) << 63 : n * 4;
    return n;
}

TriangleMesh subdivide_mesh(const TriangleMesh& mesh, int levels) {
    const uint64_t result = subdivided_triangle_count(mesh.triangle_count(), levels);
    if (result >= kMaxSubdividedTriangles) {
        throw Error("subdividing " + std::to_string(mesh.triangle_count()) + " triangles " +
                    std::to_string(levels) + " times would make " + std::to_string(result) +
                    " triangles; the kd-tree takes fewer than 2^30");
    }
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
