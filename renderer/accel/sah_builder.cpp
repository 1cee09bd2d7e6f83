// The SAH kd-tree builder of Wald & Havran 2006 ("On building fast kd-trees for ray tracing,
// and on doing that in O(N log N)"): perfect splits (references clipped to the node box),
// planar triangles sent to the cheaper side, an empty-space bonus and the thesis's f(n).
// Large nodes are split by binned SAH over the clipped references (sah_binned.cpp); below
// SahTuning::sweep_threshold references each subtree runs the exact O(N log N) event sweep
// on its own OpenMP task (sah_sweep.cpp). This file checks the mesh, sets up the root and
// copies the subtrees into the final arrays. Depends on core, geometry and the builder.
#include "renderer/accel/sah_builder.h"
#include "renderer/accel/sah_internal.h"

#include <malloc.h>
#include <omp.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "renderer/core/check.h"
#include "renderer/core/error.h"

namespace kdt {
namespace {

using namespace sah_detail;

// ---------------------------------------------------------------------------------------
// Assembly: one depth-first pass copies every subtree into the final arrays.

void count_output(const TopNode& t, size_t& nodes, size_t& indices, uint64_t& splits) {
    if (t.axis >= 0) {
        nodes += 2;
        ++splits;
        count_output(*t.child[0], nodes, indices, splits);
        count_output(*t.child[1], nodes, indices, splits);
    } else {
        nodes += t.sub.nodes.size() - 1;
        indices += t.sub.indices.size();
        splits += t.sub.splits;
    }
}

// Two passes so that only one of the two arrays exists twice at a time: first every
// subtree's nodes (relocated; leaf offsets from the running index count), then every
// subtree's indices in the same depth-first order. Each array is freed once copied, and
// glibc is asked every kTrimBytes to hand the freed pages back, so that the final arrays
// replace the subtrees in memory instead of adding to them.
constexpr size_t kTrimBytes = size_t(1) << 20;

void return_free_pages() { malloc_trim(0); }

void emit_nodes(TopNode& t, uint32_t slot, std::vector<KdNode>& out, size_t& index_base,
                size_t& freed) {
    if (t.axis >= 0) {
        const auto first_child = uint32_t(out.size());
        out.resize(first_child + 2);
        out[slot] = KdNode::make_inner(t.axis, t.split, first_child);
        emit_nodes(*t.child[0], first_child, out, index_base, freed);
        emit_nodes(*t.child[1], first_child + 1, out, index_base, freed);
        return;
    }
    const auto index_offset = uint32_t(index_base);
    const auto base = uint32_t(out.size());  // local node i >= 1 goes to base + i - 1
    for (size_t i = 0; i < t.sub.nodes.size(); ++i) {
        KdNode nd = t.sub.nodes[i];
        nd = nd.is_leaf() ? KdNode::make_leaf(nd.count(), nd.first + index_offset)
                          : KdNode::make_inner(nd.axis(), nd.split, base + nd.child() - 1);
        if (i == 0) {
            out[slot] = nd;
        } else {
            out.push_back(nd);
        }
    }
    index_base += t.sub.indices.size();
    freed += t.sub.nodes.capacity() * sizeof(KdNode);
    release(t.sub.nodes);
    if (freed >= kTrimBytes) {
        return_free_pages();
        freed = 0;
    }
}

void emit_indices(TopNode& t, std::vector<uint32_t>& out, size_t& freed) {
    if (t.axis >= 0) {
        emit_indices(*t.child[0], out, freed);
        t.child[0].reset();
        emit_indices(*t.child[1], out, freed);
        t.child[1].reset();
        return;
    }
    out.insert(out.end(), t.sub.indices.begin(), t.sub.indices.end());
    freed += t.sub.indices.capacity() * sizeof(uint32_t);
    release(t.sub.indices);
    if (freed >= kTrimBytes) {
        return_free_pages();
        freed = 0;
    }
}

/// The next float towards -infinity / +infinity (finite, non-NaN input).
inline float next_float_down(float x) {
    if (x == 0.0f) return -std::numeric_limits<float>::denorm_min();
    uint32_t bits = std::bit_cast<uint32_t>(x);
    bits = x > 0.0f ? bits - 1 : bits + 1;
    return std::bit_cast<float>(bits);
}
inline float next_float_up(float x) { return -next_float_down(-x); }

}  // namespace

bool clip_triangle_to_box(const Vec3f& a, const Vec3f& b, const Vec3f& c, const Bounds3f& box,
                          Bounds3f& clipped) {
    // Sutherland-Hodgman against the planes that cut the triangle's bounds; a triangle has at
    // most 3 + 6 vertices after six planes. Each vertex remembers on which axes its
    // coordinate is exact (an input vertex, the clipping plane itself, or an edge parallel
    // to that axis); only interpolated coordinates get a safety margin.
    struct V {
        double p[3];
        unsigned exact;  // bit k: coordinate k is exact
    };
    V poly[2][9];
    int count = 3;
    int cur = 0;
    const Vec3f* input[3] = {&a, &b, &c};
    for (int i = 0; i < 3; ++i) {
        poly[0][i] = {{double((*input[i])[0]), double((*input[i])[1]), double((*input[i])[2])}, 7u};
    }
    for (int k = 0; k < 3; ++k) {
        for (int upper = 0; upper < 2; ++upper) {
            const double plane = upper ? double(box.upper[k]) : double(box.lower[k]);
            const V* in = poly[cur];
            bool inside[9];
            int n_inside = 0;
            for (int i = 0; i < count; ++i) {
                inside[i] = upper ? in[i].p[k] <= plane : in[i].p[k] >= plane;
                n_inside += inside[i];
            }
            if (n_inside == 0) return false;
            if (n_inside == count) continue;
            V* out = poly[1 - cur];
            int m = 0;
            for (int i = 0; i < count; ++i) {
                const int next = i + 1 == count ? 0 : i + 1;
                const V& p = in[i];
                const V& q = in[next];
                if (inside[i]) out[m++] = p;
                if (inside[i] == inside[next]) continue;
                const double t = (plane - p.p[k]) / (q.p[k] - p.p[k]);
                if (t <= 0.0 || t >= 1.0) {  // the edge meets the plane in a vertex
                    out[m++] = t <= 0.0 ? p : q;
                    continue;
                }
                V& x = out[m++];
                x.exact = 1u << k;
                for (int j = 0; j < 3; ++j) {
                    if (j == k) {
                        x.p[j] = plane;  // exactly on the plane
                    } else if (p.p[j] == q.p[j] && (p.exact & q.exact & (1u << j))) {
                        x.p[j] = p.p[j];
                        x.exact |= 1u << j;
                    } else {
                        x.p[j] = p.p[j] + t * (q.p[j] - p.p[j]);
                    }
                }
            }
            count = m;
            cur = 1 - cur;
        }
    }
    const V* poly_out = poly[cur];
    unsigned all_exact = 7u;
    for (int i = 0; i < count; ++i) all_exact &= poly_out[i].exact;
    double margin = 0.0;
    if (all_exact != 7u) {
        double magnitude = 0.0;
        for (int k = 0; k < 3; ++k) {
            magnitude =
                std::max({magnitude, std::abs(double(box.lower[k])), std::abs(double(box.upper[k])),
                          std::abs(double(a[k])), std::abs(double(b[k])), std::abs(double(c[k]))});
        }
        // Interpolated coordinates carry a few double ulps of error relative to the largest
        // coordinate involved; widen them by far more than that before rounding to float.
        margin = magnitude * 1e-13;
    }
    for (int k = 0; k < 3; ++k) {
        double lo = kInfinity, hi = -kInfinity;
        for (int i = 0; i < count; ++i) {
            const V& v = poly_out[i];
            const double e = (v.exact >> k) & 1u ? 0.0 : margin;
            lo = std::min(lo, v.p[k] - e);
            hi = std::max(hi, v.p[k] + e);
        }
        // Round outward so the float box contains the exact clipped triangle.
        float l = float(lo), h = float(hi);
        if (double(l) > lo) l = next_float_down(l);
        if (double(h) < hi) h = next_float_up(h);
        clipped.lower[k] = std::max(l, box.lower[k]);
        clipped.upper[k] = std::min(h, box.upper[k]);
    }
    return !clipped.empty();
}

KdBuildOutput build_sah_tree(const TriangleMesh& mesh, const KdTreeParams& params) {
    return build_sah_tree(mesh, params, SahTuning{});
}

KdBuildOutput build_sah_tree(const TriangleMesh& mesh, const KdTreeParams& params,
                             const SahTuning& tuning, const std::atomic<bool>* cancel) {
    const size_t tri_count = mesh.triangle_count();
    if (tri_count >= kMaxRefs) {
        throw Error(ErrorLocation{"", "mesh", -1, -1, -1},
                    std::to_string(tri_count) + " triangles is more than the kd-tree supports (" +
                        std::to_string(kMaxRefs - 1) + ")");
    }
    Context ctx;
    ctx.mesh = &mesh;
    ctx.params = params;
    ctx.tuning = tuning;
    ctx.cancel = cancel;
    ctx.max_depth = params.max_depth > 0 ? std::min(params.max_depth, kMaxTreeDepth)
                                         : automatic_max_depth(tri_count);
    const int threads = params.threads > 0 ? params.threads : omp_get_max_threads();
    ctx.workspace_budget = std::min(kWorkspaceBudget, kWorkspaceBytesPerTriangle * tri_count);
    // f(n) tabulated for the node sizes that dominate the build (pow() is slow).
    const size_t table = std::min<size_t>(tri_count, 1u << 16) + 1;
    ctx.f_table.resize(table);
#pragma omp parallel for num_threads(threads) schedule(static)
    for (size_t i = 0; i < table; ++i) ctx.f_table[i] = thesis_f(float(i), params.q, params.n0);
    ctx.meter.add(int64_t(ctx.f_table.capacity() * sizeof(float)));

    // Every triangle that can be hit (TriangleMesh::triangle_hittable: finite vertices, three
    // distinct indices), as the thesis builder takes them; the others are never referenced, so
    // a scan's faces with a repeated index cost no references or tests. Checked in
    // chunks on all threads: flags, counts and bounds per chunk, then the indices are
    // written at each chunk's offset, so the order is the mesh's whatever the threads.
    TopNode top(&ctx.meter);
    auto root = std::make_unique<TopJob>(ctx, top, Bounds3f{}, 0);
    const size_t vertex_count = mesh.vertex_count();
    constexpr int kSetupChunks = 16;
    struct Chunk {
        size_t begin = 0, end = 0, valid = 0, offset = 0;
        size_t bad = std::numeric_limits<size_t>::max();  // first triangle out of range
        Bounds3f bounds;
    };
    Chunk chunks[kSetupChunks];
    const size_t chunk_size = (tri_count + kSetupChunks - 1) / kSetupChunks;
    MeteredVector<uint8_t> usable(tri_count, MeteredAllocator<uint8_t>(&ctx.meter));
#pragma omp parallel for num_threads(threads) schedule(static)
    for (int c = 0; c < kSetupChunks; ++c) {
        Chunk& ch = chunks[c];
        ch.begin = std::min(tri_count, size_t(c) * chunk_size);
        ch.end = std::min(tri_count, ch.begin + chunk_size);
        for (size_t i = ch.begin; i < ch.end; ++i) {
            const Vec3u& t = mesh.triangles[i];
            if (t.x >= vertex_count || t.y >= vertex_count || t.z >= vertex_count) {
                ch.bad = i;
                break;
            }
            usable[i] = mesh.triangle_hittable(i);
            if (!usable[i]) continue;
            ++ch.valid;
            ch.bounds.extend(mesh.triangle_bounds(i));
        }
    }
    Bounds3f valid_bounds;
    size_t valid_count = 0;
    for (Chunk& ch : chunks) {
        if (ch.bad != std::numeric_limits<size_t>::max()) {
            const Vec3u& t = mesh.triangles[ch.bad];
            const uint32_t v = t.x >= vertex_count ? t.x : t.y >= vertex_count ? t.y : t.z;
            throw Error(ErrorLocation{"", "triangle", int64_t(ch.bad), -1, -1},
                        "vertex index " + std::to_string(v) + " out of range (" +
                            std::to_string(vertex_count) + " vertices)");
        }
        ch.offset = valid_count;
        valid_count += ch.valid;
        valid_bounds.extend(ch.bounds);
    }
    root->whole.resize(valid_count);
#pragma omp parallel for num_threads(threads) schedule(static)
    for (int c = 0; c < kSetupChunks; ++c) {
        uint32_t* w = root->whole.data() + chunks[c].offset;
        for (size_t i = chunks[c].begin; i < chunks[c].end; ++i) {
            if (usable[i]) *w++ = uint32_t(i);
        }
    }
    release(usable);

    KdBuildOutput out;
    Bounds3f mesh_bounds = mesh.bounds();
    out.bounds =
        (is_finite(mesh_bounds.lower) && is_finite(mesh_bounds.upper)) ? mesh_bounds : valid_bounds;
    // The root box must hold every reference; valid_bounds is inside mesh_bounds anyway.
    Bounds3f root_box = out.bounds;
    root_box.extend(valid_bounds);

    root->box = root_box;
    root->budget = tuning.ref_budget_per_triangle * double(valid_count);
    build_top(ctx, std::move(root), threads);
    if (build_cancelled(cancel)) throw BuildCancelled();

    size_t node_count = 1, index_count = 0;
    uint64_t splits = 0;
    count_output(top, node_count, index_count, splits);
    check_node_count(node_count);
    // The final arrays count towards the peak from the moment they are reserved.
    return_free_pages();
    size_t freed = 0, index_base = 0;
    out.nodes.reserve(node_count);
    ctx.meter.add(int64_t(out.nodes.capacity() * sizeof(KdNode)));
    out.nodes.emplace_back();
    emit_nodes(top, 0, out.nodes, index_base, freed);
    return_free_pages();
    freed = 0;
    out.indices.reserve(index_count);
    ctx.meter.add(int64_t(out.indices.capacity() * sizeof(uint32_t)));
    emit_indices(top, out.indices, freed);
    KDT_CHECK(out.nodes.size() == node_count && out.indices.size() == index_count);
    finalize_stats(out, tri_count);
    out.stats.sah_splits = splits;
    out.stats.peak_build_bytes = uint64_t(std::max<int64_t>(ctx.meter.peak(), 0));
    return out;
}

}  // namespace kdt
