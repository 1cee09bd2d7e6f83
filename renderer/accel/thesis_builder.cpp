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
// are placeholders for subtrees built by other tasks, spliced in by flatten().
struct Subtree {
    std::vector<KdNode> nodes;
    std::vector<uint32_t> indices;
    std::vector<std::pair<uint32_t, std::unique_ptr<Subtree>>> links;
    uint64_t median_splits = 0, center_splits = 0, cutoff_splits = 0;
};

struct Work {
    std::vector<uint32_t> tris;
    Bounds3f box;
    int depth = 0;
    uint64_t budget = 0;  // references this subtree may hold, >= tris.size()
};

struct Context {
    const TriangleMesh& mesh;
    const KdTreeParams& params;
    int max_depth = 0;
    bool parallel = false;
    std::atomic<int64_t> live_bytes{0};
    std::atomic<int64_t> peak_bytes{0};

    void add_bytes(int64_t delta) {
        int64_t now = live_bytes.fetch_add(delta, std::memory_order_relaxed) + delta;
        int64_t peak = peak_bytes.load(std::memory_order_relaxed);
        while (now > peak && !peak_bytes.compare_exchange_weak(peak, now)) {
        }
    }
};

// Per-thread scratch reused from node to node (the parent's is dead once it has split), so
// the build does not fault in fresh pages at every level.
struct Scratch {
    std::vector<float> coords;  // 3 vertex coordinates per triangle, for the median
    std::vector<float> lo, hi;  // per-triangle extent along `axis`
    int axis = -1;              // axis of lo/hi
    std::vector<uint32_t> histogram;
    std::vector<float> bucket;
    size_t counted = 0;  // bytes reported to Context for these buffers
};
thread_local Scratch tls_scratch;

// The k-th smallest of v (all in [lo, hi]), exactly: one histogram pass over about n / 4
// bins of the range, then nth_element on the one bin holding rank k. Binning is monotone,
// so the k-th value lies in the bin where the cumulative count passes k. Faster than
// nth_element on all 3N coordinates, whose partition loop mispredicts branches.
float select_kth(std::vector<float>& v, size_t k, float lo, float hi, Scratch& s) {
    const int kBins =
        int(std::min<size_t>(4096, std::bit_floor(std::max<size_t>(v.size() / 4, 1))));
    const float scale = float(kBins) / (hi - lo);
    if (v.size() < 64 || !std::isfinite(scale) || !(scale > 0.0f)) {
        std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(k), v.end());
        return v[k];
    }
    auto bin = [&](float x) {
        return int(std::min(std::max((x - lo) * scale, 0.0f), float(kBins - 1)));
    };
    s.histogram.assign(kBins, 0);
    for (float x : v) ++s.histogram[size_t(bin(x))];
    size_t before = 0;
    int b = 0;
    while (before + s.histogram[size_t(b)] <= k) before += s.histogram[size_t(b++)];
    s.bucket.clear();
    for (float x : v)
        if (bin(x) == b) s.bucket.push_back(x);
    const size_t r = k - before;
    std::nth_element(s.bucket.begin(), s.bucket.begin() + std::ptrdiff_t(r), s.bucket.end());
    return s.bucket[r];
}

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

// Evaluates the thesis's candidates on one axis, keeping the cheapest in `best`.
void evaluate_axis(Context& ctx, const Work& w, int axis, Scratch& s, Choice& best) {
    const size_t n = w.tris.size();
    const Vec3f* pos = ctx.mesh.positions.data();
    const Vec3u* tri = ctx.mesh.triangles.data();
    const bool want_median = ctx.params.use_median_split;
    s.lo.resize(n);
    s.hi.resize(n);
    s.axis = axis;
    if (want_median) s.coords.resize(3 * n);
    float tmin = kInfinity, tmax = -kInfinity;
    for (size_t i = 0; i < n; ++i) {
        const Vec3u& t = tri[w.tris[i]];
        const float a = pos[t.x][axis], b = pos[t.y][axis], c = pos[t.z][axis];
        const float l = std::min(a, std::min(b, c)), h = std::max(a, std::max(b, c));
        s.lo[i] = l;
        s.hi[i] = h;
        tmin = std::min(tmin, l);
        tmax = std::max(tmax, h);
        if (want_median) {
            s.coords[3 * i] = a;
            s.coords[3 * i + 1] = b;
            s.coords[3 * i + 2] = c;
        }
    }
    size_t bytes = s.lo.capacity() * 8 + s.coords.capacity() * 4 + s.bucket.capacity() * 4;
    if (bytes > s.counted) {
        ctx.add_bytes(int64_t(bytes - s.counted));
        s.counted = bytes;
    }

    const float box_lo = w.box.lower[axis], box_hi = w.box.upper[axis];
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
    // Spatial middle and median vertex, counted in one pass.
    const float center = 0.5f * (box_lo + box_hi);
    const bool use_center = ctx.params.use_center_split && center > box_lo && center < box_hi;
    float median = 0.0f;
    bool use_median = false;
    if (want_median) {
        median = select_kth(s.coords, s.coords.size() / 2, tmin, tmax, s);
        use_median = median > box_lo && median < box_hi;
    }
    if (!use_center && !use_median) return;
    size_t c_left = 0, c_right = 0, m_left = 0, m_right = 0;
    for (size_t i = 0; i < n; ++i) {
        c_left += s.hi[i] < center;
        c_right += s.lo[i] >= center;
        m_left += s.hi[i] < median;
        m_right += s.lo[i] >= median;
    }
    if (use_center) consider(SplitKind::center, center, c_left, c_right, n - c_left - c_right);
    if (use_median) consider(SplitKind::median, median, m_left, m_right, n - m_left - m_right);
}

void build_node(Context& ctx, Subtree& st, uint32_t slot, Work w);

void make_leaf(Subtree& st, uint32_t slot, const std::vector<uint32_t>& tris) {
    st.nodes[slot] = KdNode::make_leaf(uint32_t(tris.size()), uint32_t(st.indices.size()));
    st.indices.insert(st.indices.end(), tris.begin(), tris.end());
}

void build_child_task(Context& ctx, Subtree* sub, Work* w) {
    std::unique_ptr<Work> owned(w);
    sub->nodes.resize(1);
    build_node(ctx, *sub, 0, std::move(*owned));
}

void build_node(Context& ctx, Subtree& st, uint32_t slot, Work w) {
    const size_t n = w.tris.size();
    if (n <= size_t(ctx.params.n0) || w.depth >= ctx.max_depth || !(box_area(w.box) > 0.0)) {
        make_leaf(st, slot, w.tris);
        ctx.add_bytes(-int64_t(n) * 4);
        return;
    }
    Scratch& s = tls_scratch;
    Choice best;
    best.cost = double(n);  // "terminate": every triangle tested in this leaf
    if (ctx.params.thesis_all_axes) {
        for (int axis = 0; axis < 3; ++axis) evaluate_axis(ctx, w, axis, s, best);
    } else {
        evaluate_axis(ctx, w, w.depth % 3, s, best);  // the thesis alternates x, y, z
    }
    if (best.kind == SplitKind::none || best.n_left + best.n_right > w.budget) {
        make_leaf(st, slot, w.tris);
        ctx.add_bytes(-int64_t(n) * 4);
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

    // Partition against exactly the float stored in the node.
    const int axis = best.axis;
    const float p = best.pos;
    auto left = std::make_unique<Work>();
    auto right = std::make_unique<Work>();
    left->tris.reserve(best.n_left);
    right->tris.reserve(best.n_right);
    const Vec3f* pos = ctx.mesh.positions.data();
    const Vec3u* tri = ctx.mesh.triangles.data();
    if (s.axis == axis) {  // the extents along this axis are still in the scratch
        for (size_t i = 0; i < n; ++i) {
            if (s.lo[i] < p) left->tris.push_back(w.tris[i]);
            if (s.hi[i] >= p) right->tris.push_back(w.tris[i]);
        }
    } else {
        for (uint32_t id : w.tris) {
            const Vec3u& t = tri[id];
            const float a = pos[t.x][axis], b = pos[t.y][axis], c = pos[t.z][axis];
            if (std::min(a, std::min(b, c)) < p) left->tris.push_back(id);
            if (std::max(a, std::max(b, c)) >= p) right->tris.push_back(id);
        }
    }
    const int64_t child_bytes = int64_t(left->tris.size() + right->tris.size()) * 4;
    ctx.add_bytes(child_bytes - int64_t(n) * 4);
    std::vector<uint32_t>().swap(w.tris);
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
        if (ctx.parallel && c->tris.size() >= kTaskMinTriangles) {
            auto sub = std::make_unique<Subtree>();
            Subtree* sp = sub.get();
            st.links.emplace_back(first + uint32_t(k), std::move(sub));
#pragma omp task default(none) firstprivate(sp, c) shared(ctx)
            build_child_task(ctx, sp, c);
        } else {
            std::unique_ptr<Work> owned(c);
            build_node(ctx, st, first + uint32_t(k), std::move(*owned));
        }
    }
}

// Appends `st` to `out` with its root stored at out.nodes[root_slot], relocating child and
// index offsets and splicing in linked subtrees. Frees `st` as it goes.
void flatten(Subtree& st, uint32_t root_slot, KdBuildOutput& out, KdTreeStats& stats) {
    stats.median_splits += st.median_splits;
    stats.center_splits += st.center_splits;
    stats.cutoff_splits += st.cutoff_splits;
    const size_t base = out.nodes.size();  // local node k >= 1 goes to base + k - 1
    const size_t index_base = out.indices.size();
    if (base + st.nodes.size() > (size_t(1) << 30) ||
        index_base + st.indices.size() > (size_t(1) << 32) - 1) {
        throw Error("kd-tree too large: more than 2^30 nodes or 2^32 references");
    }
    auto global = [&](uint32_t k) { return k == 0 ? size_t(root_slot) : base + k - 1; };
    out.nodes.resize(base + st.nodes.size() - 1);
    for (size_t k = 0; k < st.nodes.size(); ++k) {
        const KdNode& n = st.nodes[k];
        KdNode g = n.is_leaf() ? KdNode::make_leaf(n.count(), uint32_t(n.first + index_base))
                               : KdNode::make_inner(n.axis(), n.split, uint32_t(global(n.child())));
        out.nodes[global(uint32_t(k))] = g;
    }
    out.indices.insert(out.indices.end(), st.indices.begin(), st.indices.end());
    std::vector<KdNode>().swap(st.nodes);
    std::vector<uint32_t>().swap(st.indices);
    for (auto& [slot, sub] : st.links) {
        flatten(*sub, uint32_t(global(slot)), out, stats);
        sub.reset();
    }
}

}  // namespace

KdBuildOutput build_thesis_tree(const TriangleMesh& mesh, const KdTreeParams& params) {
    KdBuildOutput out;
    const size_t vertex_count = mesh.positions.size();
    if (mesh.triangles.size() >= (size_t(1) << 30)) {
        throw Error("mesh has " + std::to_string(mesh.triangles.size()) +
                    " triangles; the kd-tree supports fewer than 2^30");
    }
    // Triangles that cannot be hit are left out: out-of-range indices, repeated vertices
    // (zero area), non-finite coordinates.
    Work root;
    root.tris.reserve(mesh.triangles.size());
    for (size_t i = 0; i < mesh.triangles.size(); ++i) {
        const Vec3u& t = mesh.triangles[i];
        if (t.x >= vertex_count || t.y >= vertex_count || t.z >= vertex_count) continue;
        if (t.x == t.y || t.y == t.z || t.z == t.x) continue;
        const Vec3f &a = mesh.positions[t.x], &b = mesh.positions[t.y], &c = mesh.positions[t.z];
        if (!is_finite(a) || !is_finite(b) || !is_finite(c)) continue;
        root.box.extend(a);
        root.box.extend(b);
        root.box.extend(c);
        root.tris.push_back(uint32_t(i));
    }
    Context ctx{mesh, params};
    const double n = double(std::max<size_t>(root.tris.size(), 1));
    ctx.max_depth =
        params.max_depth > 0 ? params.max_depth : std::min(64, int(8.0 + 1.3 * std::log2(n)));
    ctx.add_bytes(int64_t(root.tris.capacity()) * 4);
    root.budget = kMaxReferencesPerTriangle * root.tris.size();
    out.bounds = root.box;

    auto top = std::make_unique<Subtree>();
    top->nodes.resize(1);
    if (root.tris.empty()) {
        top->nodes[0] = KdNode::make_leaf(0, 0);
    } else {
        const int threads = params.threads > 0 ? params.threads : omp_get_max_threads();
        ctx.parallel = threads > 1 && root.tris.size() >= 2 * kTaskMinTriangles;
        if (ctx.parallel) {
#pragma omp parallel num_threads(threads)
            {
#pragma omp single
                build_node(ctx, *top, 0, std::move(root));
                // After the barrier every task is done: free this thread's scratch.
                tls_scratch = Scratch{};
            }
        } else {
            build_node(ctx, *top, 0, std::move(root));
            tls_scratch = Scratch{};
        }
    }
    KdTreeStats stats;
    out.nodes.reserve(1);
    out.nodes.resize(1);
    flatten(*top, 0, out, stats);
    out.stats = stats;
    // Scratch peak, or the finished arrays plus the subtrees being spliced, if larger.
    out.stats.peak_build_bytes =
        uint64_t(std::max<int64_t>(ctx.peak_bytes.load(), 0)) +
        uint64_t(out.nodes.size() * sizeof(KdNode) + out.indices.size() * 4);
    finalize_stats(out, mesh.triangles.size());
    return out;
}

}  // namespace kdt
