// The thesis's kd-tree builder (section 5.2.2). At each node the candidates "cut off empty
// space left", "... right", "spatial middle" and "median vertex" are scored with Szecsi's
// cost C_V = [SA(L) (f(N_L) + N_sp) + SA(R) (f(N_R) + N_sp)] / SA(V) and compared with
// "terminate" (cost N). Triangles are classified by their vertex coordinates against the
// stored float plane as the thesis's section 5.2.1 does (a vertex on the plane counts as
// positive): min < split goes left, max >= split goes right. Straddlers are referenced from
// both children; a triangle touching the plane from the right or lying in it goes right
// only, one touching it from the left goes to both (the contract in kdtree.h allows either).
#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <memory>
#include <utility>
#include <vector>

#include <malloc.h>
#include <omp.h>

#include "renderer/accel/builder.h"
#include "renderer/core/error.h"

namespace kdt {
namespace {

enum class SplitKind : uint8_t { none, cutoff, center, median };

// Below this many triangles a node's children are built in the same task.
constexpr size_t kTaskMinTriangles = 4096;

// The thesis's cost has no traversal term, so in flat or tiny boxes (around a vertex
// shared by many triangles, in a planar region) a split that copies nearly every triangle
// to both children still looks cheaper than a leaf; with a deep max_depth the references
// grow exponentially (784 planar triangles, q = 1, n0 = 0, depth 64: 85 million nodes).
// Each subtree therefore gets a reference budget, split between the children in
// proportion to their sizes: a node whose split would exceed it becomes a leaf. This is
// deterministic (independent of threads) and caps the tree at 5 references per triangle,
// which keeps the default tree (automatic depth 33 for the dragon) within 32 bytes per
// triangle: 3.99 references, 27.7 B/triangle, instead of 6.9 and 53 B without the cap (and
// 85 million nodes for the planar case above). At the thesis's depth 20 it changes 0.1 % of
// the dragon's nodes.
constexpr uint64_t kMaxReferencesPerTriangle = 5;

// A part of the tree built by one task: node 0 is the part's root. Leaves listed in `links`
// are placeholders for subtrees built by other tasks, spliced in by the assembly. Children
// of kTaskMinTriangles or more triangles always get their own part, whatever the thread
// count, so every part stays small and the tree never exists twice while it grows.
struct Subtree {
    explicit Subtree(ScratchMeter* m)
        : nodes(MeteredAllocator<KdNode>(m)), indices(MeteredAllocator<uint32_t>(m)) {}
    MeteredVector<KdNode> nodes;
    MeteredVector<uint32_t> indices;
    std::vector<std::pair<uint32_t, std::unique_ptr<Subtree>>> links;
    uint64_t median_splits = 0, center_splits = 0, cutoff_splits = 0;
};

struct Work {
    explicit Work(ScratchMeter* m) : tris(MeteredAllocator<uint32_t>(m)) {}
    MeteredVector<uint32_t> tris;
    Bounds3f box;
    int depth = 0;
    uint64_t budget = 0;  // references this subtree may hold, >= tris.size()
};

// Nodes up to this many triangles, and up to 1/16 of the mesh, keep their extents and
// vertex coordinates along the evaluated axis in the per-thread scratch (20 bytes each, so
// at most 1.25 MB or 1.25 bytes per triangle per thread); larger ones, the few top levels,
// read the vertices again instead of holding 20 bytes per triangle at the root.
constexpr size_t kMaxStoredExtents = size_t(1) << 16;

// Per-thread scratch reused from node to node: the histogram of the median selection, the
// values of the one bin that holds the median, and the extents of small nodes.
struct Scratch {
    explicit Scratch(ScratchMeter* m)
        : hist(MeteredAllocator<uint32_t>(m)),
          bucket(MeteredAllocator<float>(m)),
          bucket_lo(MeteredAllocator<float>(m)),
          bucket_hi(MeteredAllocator<float>(m)),
          lo(MeteredAllocator<float>(m)),
          hi(MeteredAllocator<float>(m)),
          coords(MeteredAllocator<float>(m)) {}
    MeteredVector<uint32_t> hist;
    MeteredVector<float> bucket, bucket_lo, bucket_hi;
    MeteredVector<float> lo, hi;  // extents along `axis` of the node's triangles
    MeteredVector<float> coords;  // their vertex coordinates along `axis`
    int axis = -1;                // -1: lo/hi hold nothing valid
};

struct Context {
    const TriangleMesh& mesh;
    const KdTreeParams& params;
    const std::atomic<bool>* cancel = nullptr;  // build_kdtree()'s
    int max_depth = 0;
    bool parallel = false;
    size_t max_stored = 0;  // nodes up to this size keep extents in the scratch
    ScratchMeter meter;
    std::vector<std::unique_ptr<Scratch>> scratch;  // one per OpenMP thread

    Scratch& thread_scratch() {
        auto& s = scratch[size_t(omp_get_thread_num())];
        if (!s) s = std::make_unique<Scratch>(&meter);
        return *s;
    }
};

struct Choice {
    SplitKind kind = SplitKind::none;
    int axis = 0;
    float pos = 0.0f;
    double cost = 0.0;
    size_t n_left = 0, n_right = 0;  // sizes of the child lists (straddlers in both)
};

double box_area(const Bounds3f& b) {
    Vec3d d = Vec3d(b.upper) - Vec3d(b.lower);
    return 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x);
}

// The k-th smallest of v (all in [lo, hi]), exactly: one histogram pass over about n / 4
// bins of the range, then nth_element on the one bin holding rank k. Binning is monotone,
// so the k-th value lies in the bin where the cumulative count passes k. Faster than
// nth_element on all 3N coordinates, whose partition loop mispredicts branches.
float select_kth(MeteredVector<float>& v, size_t k, float lo, float hi, Scratch& s) {
    const int bins = int(std::min<size_t>(4096, std::bit_floor(std::max<size_t>(v.size() / 4, 1))));
    const float scale = float(bins) / (hi - lo);
    if (v.size() < 64 || !std::isfinite(scale) || !(scale > 0.0f)) {
        std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(k), v.end());
        return v[k];
    }
    auto bin = [&](float x) {
        return int(std::min(std::max((x - lo) * scale, 0.0f), float(bins - 1)));
    };
    s.hist.assign(size_t(bins), 0);
    for (float x : v) ++s.hist[size_t(bin(x))];
    size_t before = 0;
    int b = 0;
    while (before + s.hist[size_t(b)] <= k) before += s.hist[size_t(b++)];
    s.bucket.clear();
    for (float x : v)
        if (bin(x) == b) s.bucket.push_back(x);
    const size_t r = k - before;
    std::nth_element(s.bucket.begin(), s.bucket.begin() + std::ptrdiff_t(r), s.bucket.end());
    return s.bucket[r];
}

// Evaluates the thesis's candidates on one axis, keeping the cheapest in `best`.
// The first pass reads the vertices, counts the spatial-middle sides and histograms the
// vertex coordinates over the node's range for the median vertex (the k-th smallest of all
// 3N). Binning is monotone, so rank k lies in the bin where the cumulative count passes k,
// every triangle whose extent ends in a lower bin is left of the median and every one
// starting in a higher bin right of it. The second pass counts those and collects the
// values in the median's bin; nth_element on them gives the exact median and the extents in
// that bin settle the remaining side counts exactly.
void evaluate_axis(Context& ctx, const Work& w, int axis, Choice& best) {
    const size_t n = w.tris.size();
    const float box_lo = w.box.lower[axis], box_hi = w.box.upper[axis];
    const Vec3f* pos = ctx.mesh.positions.data();
    const Vec3u* tri = ctx.mesh.triangles.data();
    const bool want_median = ctx.params.use_median_split;
    const float center = 0.5f * (box_lo + box_hi);
    const bool use_center = ctx.params.use_center_split && center > box_lo && center < box_hi;

    Scratch& s = ctx.thread_scratch();
    const bool store = n <= ctx.max_stored;
    s.axis = -1;
    if (store) {
        s.lo.resize(n);
        s.hi.resize(n);
    }
    // About 4 coordinates per bin; small nodes use one bin, that is, plain nth_element.
    int bins = n < 64 ? 1 : int(std::min<size_t>(4096, std::bit_floor(3 * n / 4)));
    float scale = box_hi > box_lo ? float(bins) / (box_hi - box_lo) : 0.0f;
    if (!std::isfinite(scale) || !(scale > 0.0f)) bins = 1;
    if (bins == 1) scale = 0.0f;
    // Written so that a NaN lands in bin 0: with one bin the scale is 0, and a box wider
    // than float's range (coordinates near +-3e38) makes x - box_lo infinite, inf * 0 NaN.
    auto bin = [&](float x) {
        const float b = (x - box_lo) * scale;
        return b > 0.0f ? int(std::min(b, float(bins - 1))) : 0;
    };
    if (want_median && !store) s.hist.assign(size_t(bins), 0);
    if (store && want_median) s.coords.resize(3 * n);
    float tmin = kInfinity, tmax = -kInfinity;
    size_t c_left = 0, c_right = 0;
    for (size_t i = 0; i < n; ++i) {
        const Vec3u& t = tri[w.tris[i]];
        const float a = pos[t.x][axis], b = pos[t.y][axis], c = pos[t.z][axis];
        const float l = std::min(a, std::min(b, c)), h = std::max(a, std::max(b, c));
        tmin = std::min(tmin, l);
        tmax = std::max(tmax, h);
        c_left += h < center;
        c_right += l >= center;
        if (store) {
            s.lo[i] = l;
            s.hi[i] = h;
        }
        if (store && want_median) {
            s.coords[3 * i] = a;
            s.coords[3 * i + 1] = b;
            s.coords[3 * i + 2] = c;
        } else if (want_median) {
            ++s.hist[size_t(bin(a))];
            ++s.hist[size_t(bin(b))];
            ++s.hist[size_t(bin(c))];
        }
    }
    if (store) s.axis = axis;

    const double inv_area = 1.0 / box_area(w.box);
    const float q = ctx.params.q;
    const int n0 = ctx.params.n0;
    auto f = [&](size_t k) { return double(thesis_f(float(k), q, n0)); };
    auto consider = [&](SplitKind kind, float p, size_t left_only, size_t right_only, size_t both) {
        if (!(p > box_lo && p < box_hi)) return;  // only planes strictly inside the box
        Bounds3f lb = w.box, rb = w.box;
        lb.upper[axis] = p;
        rb.lower[axis] = p;
        const double cost = (box_area(lb) * (f(left_only) + double(both)) +
                             box_area(rb) * (f(right_only) + double(both))) *
                            inv_area;
        if (cost < best.cost) {
            best = {kind, axis, p, cost, left_only + both, right_only + both};
        }
    };

    if (ctx.params.use_cutoff_split) {
        // At the lowest vertex every triangle is right of the plane; one float above the
        // highest one every triangle is left of it: the cut-off part is really empty.
        consider(SplitKind::cutoff, tmin, 0, n, 0);
        consider(SplitKind::cutoff, std::nextafter(tmax, kInfinity), n, 0, 0);
    }
    if (use_center) consider(SplitKind::center, center, c_left, c_right, n - c_left - c_right);
    // A median strictly inside the box needs a box with extent on this axis.
    if (!want_median || !(box_hi > box_lo)) return;

    // The median vertex: rank k = 3N / 2 of the 3N coordinates, in bin mb.
    const size_t k = 3 * n / 2;
    if (store) {
        // Small nodes: select among the stored coordinates, count over the stored extents.
        const float median = select_kth(s.coords, k, tmin, tmax, s);
        if (!(median > box_lo && median < box_hi)) return;
        size_t m_left = 0, m_right = 0;
        for (size_t i = 0; i < n; ++i) {
            m_left += s.hi[i] < median;
            m_right += s.lo[i] >= median;
        }
        consider(SplitKind::median, median, m_left, m_right, n - m_left - m_right);
        return;
    }
    size_t before = 0;
    int mb = 0;
    while (before + s.hist[size_t(mb)] <= k) before += s.hist[size_t(mb++)];
    s.bucket.clear();
    s.bucket_lo.clear();
    s.bucket_hi.clear();
    size_t m_left = 0, m_right = 0;
    for (size_t i = 0; i < n; ++i) {
        float l, h;
        if (store) {
            l = s.lo[i];
            h = s.hi[i];
        } else {
            const Vec3u& t = tri[w.tris[i]];
            const float a = pos[t.x][axis], b = pos[t.y][axis], c = pos[t.z][axis];
            l = std::min(a, std::min(b, c));
            h = std::max(a, std::max(b, c));
        }
        const int bl = bin(l), bh = bin(h);
        m_left += bh < mb;
        m_right += bl > mb;
        if (bl > mb || bh < mb) continue;
        // The extent covers the median's bin: its vertices may lie in it.
        const Vec3u& t = tri[w.tris[i]];
        const float v[3] = {pos[t.x][axis], pos[t.y][axis], pos[t.z][axis]};
        for (float x : v) {
            if (bin(x) == mb) s.bucket.push_back(x);
        }
        if (bl == mb) s.bucket_lo.push_back(l);
        if (bh == mb) s.bucket_hi.push_back(h);
    }
    const size_t r = k - before;
    std::nth_element(s.bucket.begin(), s.bucket.begin() + std::ptrdiff_t(r), s.bucket.end());
    const float median = s.bucket[r];
    if (!(median > box_lo && median < box_hi)) return;
    for (float h : s.bucket_hi) m_left += h < median;
    for (float l : s.bucket_lo) m_right += l >= median;
    consider(SplitKind::median, median, m_left, m_right, n - m_left - m_right);
}

void build_node(Context& ctx, Subtree& st, uint32_t slot, Work w);

void make_leaf(Subtree& st, uint32_t slot, const MeteredVector<uint32_t>& tris) {
    st.nodes[slot] = KdNode::make_leaf(uint32_t(tris.size()), uint32_t(st.indices.size()));
    st.indices.insert(st.indices.end(), tris.begin(), tris.end());
}

void build_child_task(Context& ctx, Subtree* sub, Work* w) {
    std::unique_ptr<Work> owned(w);
    sub->nodes.resize(1);
    build_node(ctx, *sub, 0, std::move(*owned));
    owned.reset();
    // The part is finished: drop the growth slack of its arrays.
    sub->nodes.shrink_to_fit();
    sub->indices.shrink_to_fit();
}

void build_node(Context& ctx, Subtree& st, uint32_t slot, Work w) {
    if (build_cancelled(ctx.cancel)) {
        // The tree is dropped: an empty leaf ends this branch at once.
        st.nodes[slot] = KdNode::make_leaf(0, uint32_t(st.indices.size()));
        return;
    }
    const size_t n = w.tris.size();
    if (n <= size_t(ctx.params.n0) || w.depth >= ctx.max_depth || !(box_area(w.box) > 0.0)) {
        make_leaf(st, slot, w.tris);
        return;
    }
    Choice best;
    best.cost = double(n);  // "terminate": every triangle tested in this leaf
    if (ctx.params.thesis_all_axes) {
        for (int axis = 0; axis < 3; ++axis) evaluate_axis(ctx, w, axis, best);
    } else {
        evaluate_axis(ctx, w, w.depth % 3, best);  // the thesis alternates x, y, z
    }
    const Scratch& s = ctx.thread_scratch();
    if (best.kind == SplitKind::none || best.n_left + best.n_right > w.budget) {
        make_leaf(st, slot, w.tris);
        return;
    }
    switch (best.kind) {
        case SplitKind::cutoff:
            ++st.cutoff_splits;
            break;
        case SplitKind::center:
            ++st.center_splits;
            break;
        case SplitKind::median:
            ++st.median_splits;
            break;
        case SplitKind::none:
            break;
    }

    // Partition against exactly the float stored in the node, into exactly sized lists.
    const int axis = best.axis;
    const float p = best.pos;
    auto left = std::make_unique<Work>(&ctx.meter);
    auto right = std::make_unique<Work>(&ctx.meter);
    left->tris.reserve(best.n_left);
    right->tris.reserve(best.n_right);
    if (s.axis == axis) {  // the extents along this axis are still in the scratch
        for (size_t i = 0; i < n; ++i) {
            if (s.lo[i] < p) left->tris.push_back(w.tris[i]);
            if (s.hi[i] >= p) right->tris.push_back(w.tris[i]);
        }
    } else {
        const Vec3f* pos = ctx.mesh.positions.data();
        const Vec3u* tri = ctx.mesh.triangles.data();
        for (uint32_t id : w.tris) {
            const Vec3u& t = tri[id];
            const float a = pos[t.x][axis], b = pos[t.y][axis], c = pos[t.z][axis];
            if (std::min(a, std::min(b, c)) < p) left->tris.push_back(id);
            if (std::max(a, std::max(b, c)) >= p) right->tris.push_back(id);
        }
    }
    release(w.tris);
    left->box = right->box = w.box;
    left->box.upper[axis] = p;
    right->box.lower[axis] = p;
    left->depth = right->depth = w.depth + 1;
    const uint64_t total = left->tris.size() + right->tris.size();
    left->budget = uint64_t(double(w.budget) * double(left->tris.size()) / double(total));
    left->budget = std::max<uint64_t>(left->budget, left->tris.size());
    right->budget = std::max<uint64_t>(w.budget - left->budget, right->tris.size());

    const auto first = uint32_t(st.nodes.size());
    st.nodes.resize(st.nodes.size() + 2);
    st.nodes[slot] = KdNode::make_inner(axis, p, first);
    Work* children[2] = {left.release(), right.release()};
    for (int k = 0; k < 2; ++k) {
        Work* c = children[k];
        if (c->tris.size() >= kTaskMinTriangles) {
            auto sub = std::make_unique<Subtree>(&ctx.meter);
            Subtree* sp = sub.get();
            st.links.emplace_back(first + uint32_t(k), std::move(sub));
            if (ctx.parallel) {
#pragma omp task default(none) firstprivate(sp, c) shared(ctx)
                build_child_task(ctx, sp, c);
            } else {
                build_child_task(ctx, sp, c);
            }
        } else {
            std::unique_ptr<Work> owned(c);
            build_node(ctx, st, first + uint32_t(k), std::move(*owned));
        }
    }
}

// Assembly in two passes so that only one of the two arrays exists twice at a time:
// first every part's nodes (relocated; leaf offsets from the running index count), then
// every part's indices, in the same depth-first order. Each part is freed once copied.
void count_parts(const Subtree& st, size_t& nodes, size_t& indices) {
    nodes += st.nodes.size() - 1;
    indices += st.indices.size();
    for (const auto& link : st.links) count_parts(*link.second, nodes, indices);
}

void flatten_nodes(Subtree& st, uint32_t root_slot, std::vector<KdNode>& out, size_t& index_base,
                   KdTreeStats& stats) {
    stats.median_splits += st.median_splits;
    stats.center_splits += st.center_splits;
    stats.cutoff_splits += st.cutoff_splits;
    const size_t base = out.size();  // local node k >= 1 goes to base + k - 1
    auto global = [&](uint32_t k) { return k == 0 ? size_t(root_slot) : base + k - 1; };
    out.resize(base + st.nodes.size() - 1);
    for (size_t k = 0; k < st.nodes.size(); ++k) {
        const KdNode& n = st.nodes[k];
        KdNode g = n.is_leaf() ? KdNode::make_leaf(n.count(), uint32_t(n.first + index_base))
                               : KdNode::make_inner(n.axis(), n.split, uint32_t(global(n.child())));
        out[global(uint32_t(k))] = g;
    }
    index_base += st.indices.size();
    release(st.nodes);
    for (auto& [slot, sub] : st.links)
        flatten_nodes(*sub, uint32_t(global(slot)), out, index_base, stats);
}

// glibc keeps freed heap memory resident; the assembly hands the parts' pages back every
// kTrimBytes so that the arrays it fills replace them instead of adding to them.
constexpr size_t kTrimBytes = size_t(1) << 20;

void return_free_pages() { malloc_trim(0); }

void flatten_indices(Subtree& st, std::vector<uint32_t>& out, size_t& freed) {
    out.insert(out.end(), st.indices.begin(), st.indices.end());
    freed += st.indices.capacity() * sizeof(uint32_t);
    release(st.indices);
    if (freed >= kTrimBytes) {
        return_free_pages();
        freed = 0;
    }
    for (auto& link : st.links) {
        flatten_indices(*link.second, out, freed);
        link.second.reset();
    }
}

}  // namespace

KdBuildOutput build_thesis_tree(const TriangleMesh& mesh, const KdTreeParams& params,
                                const std::atomic<bool>* cancel) {
    KdBuildOutput out;
    if (mesh.triangles.size() >= (size_t(1) << 30)) {
        throw Error("mesh has " + std::to_string(mesh.triangles.size()) +
                    " triangles; the kd-tree supports fewer than 2^30");
    }
    Context ctx{mesh, params, cancel};
    // Triangles that cannot be hit are left out (TriangleMesh::triangle_hittable):
    // out-of-range indices, repeated vertices (zero area), non-finite coordinates.
    Work root(&ctx.meter);
    size_t valid = 0;
    for (size_t pass = 0; pass < 2; ++pass) {  // count, then fill an exactly sized list
        if (pass == 1) root.tris.reserve(valid);
        for (size_t i = 0; i < mesh.triangles.size(); ++i) {
            if (!mesh.triangle_hittable(i)) continue;
            const Vec3u& t = mesh.triangles[i];
            const Vec3f &a = mesh.positions[t.x], &b = mesh.positions[t.y],
                        &c = mesh.positions[t.z];
            if (pass == 0) {
                ++valid;
                continue;
            }
            root.box.extend(a);
            root.box.extend(b);
            root.box.extend(c);
            root.tris.push_back(uint32_t(i));
        }
    }
    ctx.max_depth = params.max_depth > 0 ? params.max_depth : automatic_max_depth(root.tris.size());
    root.budget = kMaxReferencesPerTriangle * root.tris.size();
    ctx.max_stored = std::min(kMaxStoredExtents, root.tris.size() / 16);
    out.bounds = root.box;

    const int threads = params.threads > 0 ? params.threads : omp_get_max_threads();
    ctx.scratch.resize(size_t(std::max(threads, 1)));
    auto top = std::make_unique<Subtree>(&ctx.meter);
    top->nodes.resize(1);
    if (root.tris.empty()) {
        top->nodes[0] = KdNode::make_leaf(0, 0);
    } else {
        ctx.parallel = threads > 1 && root.tris.size() >= 2 * kTaskMinTriangles;
        if (ctx.parallel) {
#pragma omp parallel num_threads(threads)
#pragma omp single
            build_node(ctx, *top, 0, std::move(root));
        } else {
            build_node(ctx, *top, 0, std::move(root));
        }
    }
    ctx.scratch.clear();
    release(root.tris);
    if (build_cancelled(cancel)) throw BuildCancelled();
    return_free_pages();

    size_t node_count = 1, index_count = 0;
    count_parts(*top, node_count, index_count);
    check_node_count(node_count);
    if (index_count > (size_t(1) << 32) - 1) {
        throw Error("kd-tree too large: " + std::to_string(index_count) +
                    " references, more than 2^32 - 1");
    }
    // The final arrays count towards the peak from the moment they are reserved.
    KdTreeStats stats;
    out.nodes.reserve(node_count);
    ctx.meter.add(int64_t(out.nodes.capacity() * sizeof(KdNode)));
    out.nodes.resize(1);
    size_t index_base = 0;
    flatten_nodes(*top, 0, out.nodes, index_base, stats);
    return_free_pages();
    out.indices.reserve(index_count);
    ctx.meter.add(int64_t(out.indices.capacity() * sizeof(uint32_t)));
    size_t freed = 0;
    flatten_indices(*top, out.indices, freed);
    top.reset();
    out.stats = stats;
    out.stats.peak_build_bytes = uint64_t(std::max<int64_t>(ctx.meter.peak(), 0));
    finalize_stats(out, mesh.triangles.size());
    return out;
}

}  // namespace kdt
