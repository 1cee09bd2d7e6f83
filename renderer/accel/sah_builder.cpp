// The SAH kd-tree builder of Wald & Havran 2006 ("On building fast kd-trees for ray tracing,
// and on doing that in O(N log N)"): perfect splits (references clipped to the node box),
// planar triangles sent to the cheaper side, an empty-space bonus and the thesis's f(n).
// Large nodes are split by binned SAH over the clipped references; below
// SahTuning::sweep_threshold references each subtree runs the exact O(N log N) event sweep
// on its own OpenMP task. Depends on core, geometry and the builder interface.
#include "renderer/accel/sah_builder.h"

#include <malloc.h>
#include <omp.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <deque>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "renderer/core/check.h"
#include "renderer/core/error.h"

namespace kdt {
namespace {

// ---------------------------------------------------------------------------------------
// References and events.

/// A triangle reference: its conservative box inside the current node, and the triangle.
struct Ref {
    Ref() {}  // left uninitialised: reference buffers are resized before being written
    Ref(const Bounds3f& b, uint32_t t) : box(b), tri(t) {}
    union {  // no default member initialisers run on resize
        Bounds3f box;
    };
    uint32_t tri;
};

/// A sweep event (Wald & Havran 2006, section 4.1): position on one axis and
/// (local reference index << 2 | type). Sorted by position, then end < planar < start.
struct Event {
    Event() {}  // left uninitialised: event buffers are resized before being written
    Event(float p, uint32_t c) : pos(p), code(c) {}
    float pos;
    uint32_t code;
};
constexpr uint32_t kEnd = 0, kPlanar = 1, kStart = 2;
constexpr uint32_t kMaxRefs = 1u << 30;  // local indices and leaf counts have 30 bits

struct EventLess {
    bool operator()(const Event& a, const Event& b) const {
        return a.pos < b.pos || (a.pos == b.pos && (a.code & 3u) < (b.code & 3u));
    }
};
constexpr EventLess event_less{};

template <class Vec>
void add_events(const Bounds3f& box, uint32_t index, Vec* events) {
    for (int k = 0; k < 3; ++k) {
        if (box.lower[k] == box.upper[k]) {
            events[k].push_back({box.lower[k], (index << 2) | kPlanar});
        } else {
            events[k].push_back({box.lower[k], (index << 2) | kStart});
            events[k].push_back({box.upper[k], (index << 2) | kEnd});
        }
    }
}

/// Float bits mapped so that unsigned order is float order (-0 is folded into +0).
inline uint32_t ordered_bits(float x) {
    const uint32_t bits = std::bit_cast<uint32_t>(x + 0.0f);
    return bits & 0x80000000u ? ~bits : bits | 0x80000000u;
}
inline float from_ordered_bits(uint32_t o) {
    return std::bit_cast<float>(o & 0x80000000u ? o & 0x7fffffffu : ~o);
}

enum Side : uint8_t { kBoth = 0, kLeft = 1, kRight = 2 };

/// Which side of the plane `split` on `axis` a reference goes to; planar references lying
/// in the plane go to `planar_side`. Compares against exactly the float stored in the node.
inline Side classify(const Bounds3f& box, int axis, float split, Side planar_side) {
    const float lo = box.lower[axis], hi = box.upper[axis];
    if (hi <= split && lo < split) return kLeft;
    if (lo >= split && hi > split) return kRight;
    if (lo == split && hi == split) return planar_side;
    return kBoth;
}

/// Sorts event keys (ordered position << 32 | type << 30 | index) that were generated in
/// increasing index order. A stable LSD radix sort on the 34 bits of position and type gives
/// exactly the order of sorting the full keys, since keys equal in those bits come from
/// different references, already in index order. 8-bit digits; a digit that is the same in
/// every key (the exponent, within a small node) costs one histogram and no pass.
template <class Vec>
void radix_sort_keys(Vec& keys, Vec& tmp) {
    const size_t n = keys.size();
    if (n < 64) {
        std::sort(keys.begin(), keys.end());
        return;
    }
    constexpr int kDigits = 5;  // bits 30-37, 38-45, 46-53, 54-61, 62-63
    uint32_t count[kDigits][256] = {};
    for (const uint64_t key : keys) {
        for (int d = 0; d < kDigits; ++d) ++count[d][(key >> (30 + 8 * d)) & 0xffu];
    }
    tmp.resize(n);
    uint64_t* src = keys.data();
    uint64_t* dst = tmp.data();
    for (int d = 0; d < kDigits; ++d) {
        const int shift = 30 + 8 * d;
        if (count[d][(src[0] >> shift) & 0xffu] == n) continue;  // one bucket: order kept
        uint32_t offset[256];
        uint32_t sum = 0;
        for (int b = 0; b < 256; ++b) {
            offset[b] = sum;
            sum += count[d][b];
        }
        for (size_t i = 0; i < n; ++i) dst[offset[(src[i] >> shift) & 0xffu]++] = src[i];
        std::swap(src, dst);
    }
    if (src != keys.data()) std::copy(src, src + n, keys.data());
}

// ---------------------------------------------------------------------------------------
// Build context shared by all tasks.

struct Context {
    const TriangleMesh* mesh = nullptr;
    KdTreeParams params;
    SahTuning tuning;
    int max_depth = 0;
    std::vector<float> f_table;   // thesis_f(n) for small n
    size_t workspace_budget = 0;  // bytes a thread's workspace keeps between subtrees
    ScratchMeter meter;

    float f(size_t n) const {
        return n < f_table.size() ? f_table[n] : thesis_f(float(n), params.q, params.n0);
    }
    float leaf_cost(size_t n) const { return params.intersect_cost * f(n); }
    /// SAH cost of a split (Wald & Havran 2006, eq. 2 with the empty-space bonus lambda),
    /// with the thesis's f(n) in place of n.
    float split_cost(float p_left, float p_right, size_t n_left, size_t n_right) const {
        float c = params.intersect_cost * (p_left * f(n_left) + p_right * f(n_right));
        if (n_left == 0 || n_right == 0) c *= 1.0f - params.empty_bonus;
        return params.traversal_cost + c;
    }
    /// Clips reference r to `child`; false when nothing of the triangle is left in it.
    bool clip(const Ref& r, const Bounds3f& child, Ref& out) const {
        const Vec3u& t = mesh->triangles[r.tri];
        Bounds3f b;
        if (!clip_triangle_to_box(mesh->positions[t.x], mesh->positions[t.y], mesh->positions[t.z],
                                  child, b)) {
            return false;
        }
        // Both boxes are conservative, so is their intersection.
        b.lower = glm::max(b.lower, r.box.lower);
        b.upper = glm::min(b.upper, r.box.upper);
        if (b.empty()) return false;
        out.box = b;
        out.tri = r.tri;
        return true;
    }
};

/// A finished subtree in local depth-first order: node 0 is its root, child indices and
/// leaf offsets are local.
struct Subtree {
    explicit Subtree(ScratchMeter* m)
        : nodes(MeteredAllocator<KdNode>(m)), indices(MeteredAllocator<uint32_t>(m)) {}
    MeteredVector<KdNode> nodes;
    MeteredVector<uint32_t> indices;
    uint64_t splits = 0;
};

/// The binned top of the tree: inner nodes, each ending in a swept subtree.
struct TopNode {
    explicit TopNode(ScratchMeter* m) : sub(m) {}
    int axis = -1;  // -1: `sub` holds the subtree
    float split = 0.0f;
    std::unique_ptr<TopNode> child[2];
    Subtree sub;
};

// ---------------------------------------------------------------------------------------
// The exact event sweep (Wald & Havran 2006, section 4.3), one subtree per task.

struct SweepNode {
    explicit SweepNode(ScratchMeter* m)
        : refs(MeteredAllocator<Ref>(m)),
          events{MeteredVector<Event>(MeteredAllocator<Event>(m)),
                 MeteredVector<Event>(MeteredAllocator<Event>(m)),
                 MeteredVector<Event>(MeteredAllocator<Event>(m))} {}
    void clear() {
        refs.clear();
        for (auto& e : events) e.clear();
    }
    MeteredVector<Ref> refs;
    MeteredVector<Event> events[3];
};

/// Per-thread buffers, reused by every subtree the thread sweeps: two node slots per level
/// (the left child is processed while the right one waits), plus split scratch.
struct Workspace {
    explicit Workspace(ScratchMeter* m)
        : meter(m),
          side(MeteredAllocator<uint8_t>(m)),
          remap(MeteredAllocator<uint32_t>(m)),
          both(MeteredAllocator<uint32_t>(m)),
          keys(MeteredAllocator<uint64_t>(m)),
          keys_tmp(MeteredAllocator<uint64_t>(m)),
          tmp{MeteredVector<Event>(MeteredAllocator<Event>(m)),
              MeteredVector<Event>(MeteredAllocator<Event>(m))},
          fresh{SweepNode(m), SweepNode(m)} {}
    SweepNode& slot(int level, int which) {
        while (levels.size() <= size_t(2 * level + 1)) {
            levels.emplace_back(meter);
            levels.emplace_back(meter);
        }
        return levels[size_t(2 * level + which)];
    }
    /// Bytes held, by capacity.
    size_t bytes() const {
        size_t b =
            side.capacity() + 4 * (remap.capacity() + both.capacity()) +
            8 * (keys.capacity() + keys_tmp.capacity() + tmp[0].capacity() + tmp[1].capacity());
        auto node_bytes = [](const SweepNode& s) {
            return s.refs.capacity() * sizeof(Ref) +
                   (s.events[0].capacity() + s.events[1].capacity() + s.events[2].capacity()) *
                       sizeof(Event);
        };
        for (const SweepNode& s : levels) b += node_bytes(s);
        return b + node_bytes(fresh[0]) + node_bytes(fresh[1]);
    }
    /// Frees every buffer (between subtrees only: slots must keep their address within one).
    void trim() {
        levels.clear();
        release(side);
        release(remap);
        release(both);
        release(keys);
        release(keys_tmp);
        for (auto& t : tmp) release(t);
        for (auto& f : fresh) {
            release(f.refs);
            for (auto& e : f.events) release(e);
        }
    }
    ScratchMeter* meter;
    std::deque<SweepNode> levels;  // deque: slots keep their address as levels are added
    MeteredVector<uint8_t> side;
    MeteredVector<uint32_t> remap;
    MeteredVector<uint32_t> both;  // straddling references of the node being split
    MeteredVector<uint64_t> keys;  // sort keys of a subtree's first events
    MeteredVector<uint64_t> keys_tmp;
    MeteredVector<Event> tmp[2];  // spliced one-sided events before the merge
    SweepNode fresh[2];           // events of clipped straddlers for the left and right child
};

// Scratch bytes a thread's workspace may keep between two subtrees: 4 MB, or 8 bytes per
// triangle for small meshes. A sweep of 2048 references fills about 1-3 MB of slots; below
// that every other subtree re-allocated them all. The build's peak is at assembly, after the
// workspaces are gone.
constexpr size_t kWorkspaceBudget = size_t(4) << 20;
constexpr size_t kWorkspaceBytesPerTriangle = 8;

// Surface areas of the two sides of a split plane relative to the box's (the probabilities
// of the SAH), in double: products of float extents overflow float above extents of about
// 1e19 and underflow below about 1e-19, and an infinite or zero area left a whole model
// in one leaf.
class SplitAreas {
public:
    explicit SplitAreas(const Bounds3f& box) : lower_(box.lower), ext_(Vec3d(box.upper) - lower_) {
        const double area = 2.0 * (ext_.x * ext_.y + ext_.y * ext_.z + ext_.z * ext_.x);
        valid_ = area > 0.0 && std::isfinite(area);
        const double inv_area = valid_ ? 1.0 / area : 0.0;
        // Per split axis, what the sweep's inner loop needs, scaled by 2 / SA(box).
        for (int k = 0; k < 3; ++k) {
            const double d1 = ext_[(k + 1) % 3], d2 = ext_[(k + 2) % 3];
            cross_[k] = 2.0 * d1 * d2 * inv_area;
            sum_[k] = 2.0 * (d1 + d2) * inv_area;
        }
    }
    bool valid() const { return valid_; }
    /// SA(left) / SA(box) and SA(right) / SA(box) for the plane at p on axis k.
    void ratios(int k, float p, float& p_left, float& p_right) const {
        const double x = double(p) - lower_[k];
        p_left = float(cross_[k] + x * sum_[k]);
        p_right = float(cross_[k] + (ext_[k] - x) * sum_[k]);
    }

private:
    Vec3d lower_, ext_;
    double cross_[3] = {}, sum_[3] = {};
    bool valid_ = false;
};

struct SweepSplit {
    float cost = kInfinity;
    int axis = -1;
    float pos = 0.0f;
    Side planar_side = kLeft;
    // Sweep counts at the split: references with a part left / right of the plane
    // (Wald & Havran's N_L and N_R, planars in the plane counted on planar_side).
    uint32_t n_left = 0, n_right = 0;
};

class SweepBuilder {
public:
    SweepBuilder(const Context& ctx, Workspace& ws, Subtree& out) : ctx_(ctx), ws_(ws), out_(out) {}

    /// Sweeps the subtree over `refs` (taken over: the vector is left empty).
    void build(MeteredVector<Ref>& refs, const Bounds3f& box, int depth) {
        SweepNode& root = ws_.slot(0, 0);
        root.clear();
        root.refs.swap(refs);
        // Wald & Havran sort once per subtree; sorting 64-bit keys (position, type, index)
        // is much faster than comparing events.
        auto& keys = ws_.keys;
        const size_t n = root.refs.size();
        for (int k = 0; k < 3; ++k) {
            keys.clear();
            for (size_t i = 0; i < n; ++i) {
                const float lo = root.refs[i].box.lower[k], hi = root.refs[i].box.upper[k];
                const uint64_t index = i;
                if (lo == hi) {
                    keys.push_back(uint64_t(ordered_bits(lo)) << 32 | uint64_t(kPlanar) << 30 |
                                   index);
                } else {
                    keys.push_back(uint64_t(ordered_bits(lo)) << 32 | uint64_t(kStart) << 30 |
                                   index);
                    keys.push_back(uint64_t(ordered_bits(hi)) << 32 | uint64_t(kEnd) << 30 | index);
                }
            }
            radix_sort_keys(keys, ws_.keys_tmp);
            auto& ev = root.events[k];
            ev.resize(keys.size());
            for (size_t i = 0; i < keys.size(); ++i) {
                const uint64_t key = keys[i];
                const auto low = uint32_t(key);
                ev[i] = Event(from_ordered_bits(uint32_t(key >> 32)),
                              (low & 0x3fffffffu) << 2 | low >> 30);
            }
        }
        out_.nodes.push_back(KdNode{});
        recurse(root, box, depth, 0, 0);
    }

private:
    SweepSplit find_split(const SweepNode& node, const Bounds3f& box) const {
        SweepSplit best;
        const SplitAreas areas(box);
        if (!areas.valid()) return best;
        const size_t n = node.refs.size();
        // Context::split_cost() with its inputs in locals: the loop below evaluates it at
        // every event, and the compiler would reload them from the context each time.
        const float* f_table = ctx_.f_table.data();
        const size_t f_size = ctx_.f_table.size();
        const float traversal = ctx_.params.traversal_cost;
        const float intersect = ctx_.params.intersect_cost;
        const float bonus = 1.0f - ctx_.params.empty_bonus;
        auto f = [&](size_t count) { return count < f_size ? f_table[count] : ctx_.f(count); };
        auto cost = [&](float p_left, float p_right, size_t n_left, size_t n_right) {
            float c = intersect * (p_left * f(n_left) + p_right * f(n_right));
            if (n_left == 0 || n_right == 0) c *= bonus;
            return traversal + c;
        };
        float best_cost = kInfinity;
        for (int k = 0; k < 3; ++k) {
            const float lo = box.lower[k], hi = box.upper[k];
            if (!(hi > lo)) continue;
            const Event* ev = node.events[k].data();
            const size_t m = node.events[k].size();
            // Counters of the events seen so far (branch-free), and their values at the
            // start of the current group of equal positions.
            size_t ends = 0, planars = 0, starts = 0;
            size_t group_planars = 0, group_starts = 0;
            for (size_t i = 0; i < m; ++i) {
                const uint32_t type = ev[i].code & 3u;
                ends += type == kEnd;
                planars += type == kPlanar;
                starts += type == kStart;
                const float p = ev[i].pos;
                if (i + 1 < m && ev[i + 1].pos == p) continue;
                // All events at p seen: N_L counts what starts before p, N_R what ends after.
                const size_t in_plane = planars - group_planars;
                const size_t n_left = group_starts + group_planars;
                const size_t n_right = n - ends - planars;
                group_planars = planars;
                group_starts = starts;
                // No split on the cell boundary: it would not separate anything.
                if (!(p > lo && p < hi)) continue;
                float p_left, p_right;
                areas.ratios(k, p, p_left, p_right);
                const float c_left = cost(p_left, p_right, n_left + in_plane, n_right);
                if (c_left < best_cost) {
                    best_cost = c_left;
                    best = {c_left, k, p, kLeft, uint32_t(n_left + in_plane), uint32_t(n_right)};
                }
                if (in_plane > 0) {
                    const float c_right = cost(p_left, p_right, n_left, n_right + in_plane);
                    if (c_right < best_cost) {
                        best_cost = c_right;
                        best = {
                            c_right, k, p, kRight, uint32_t(n_left), uint32_t(n_right + in_plane)};
                    }
                }
            }
        }
        return best;
    }

    void make_leaf(const SweepNode& node, uint32_t slot) {
        const size_t n = node.refs.size();
        KDT_CHECK(n < kMaxRefs && out_.indices.size() + n <= 0xffffffffull);
        out_.nodes[slot] = KdNode::make_leaf(uint32_t(n), uint32_t(out_.indices.size()));
        for (const Ref& r : node.refs) out_.indices.push_back(r.tri);
    }

    void recurse(SweepNode& node, const Bounds3f& box, int depth, int level, uint32_t slot) {
        const size_t n = node.refs.size();
        SweepSplit best;
        // Every split costs at least traversal_cost, so a node whose leaf is no dearer
        // stays a leaf without a sweep (the sweep could not find a cheaper split).
        if (n > 0 && depth < ctx_.max_depth && ctx_.leaf_cost(n) > ctx_.params.traversal_cost) {
            best = find_split(node, box);
        }
        if (best.axis < 0 || !(best.cost < ctx_.leaf_cost(n))) {
            make_leaf(node, slot);
            node.clear();
            return;
        }
        const auto first_child = uint32_t(out_.nodes.size());
        KDT_CHECK(first_child < kMaxRefs);
        out_.nodes.resize(first_child + 2);
        out_.nodes[slot] = KdNode::make_inner(best.axis, best.pos, first_child);
        ++out_.splits;

        Bounds3f left_box = box, right_box = box;
        left_box.upper[best.axis] = best.pos;
        right_box.lower[best.axis] = best.pos;
        SweepNode& left = ws_.slot(level + 1, 0);
        SweepNode& right = ws_.slot(level + 1, 1);
        const int full = split(node, best, left_box, right_box, left, right);
        if (full >= 0) {
            // An empty-space cut-off: the full child goes on with this level's lists (no
            // copy, and the workspace does not grow a level per cut-off); the other child is
            // an empty leaf, made in the same depth-first order as any leaf.
            if (full == 0) {
                recurse(node, left_box, depth + 1, level, first_child);
                make_empty_leaf(first_child + 1);
            } else {
                make_empty_leaf(first_child);
                recurse(node, right_box, depth + 1, level, first_child + 1);
            }
            return;
        }
        node.clear();
        recurse(left, left_box, depth + 1, level + 1, first_child);
        recurse(right, right_box, depth + 1, level + 1, first_child + 1);
    }

    void make_empty_leaf(uint32_t slot) {
        out_.nodes[slot] = KdNode::make_leaf(0, uint32_t(out_.indices.size()));
    }

    /// Wald & Havran 2006, section 4.4: classify by the events of the split axis, splice the
    /// sorted event lists of one-sided references, clip straddlers and merge their events.
    /// Returns 0 or 1 when every reference lies on that side (left and right untouched; the
    /// node keeps its lists), -1 when left and right were filled.
    int split(SweepNode& node, const SweepSplit& s, const Bounds3f& left_box,
              const Bounds3f& right_box, SweepNode& left, SweepNode& right) {
        const size_t n = node.refs.size();
        auto& side = ws_.side;
        auto& remap = ws_.remap;
        // No reference reaches across the plane on one side: an empty-space cut-off (most
        // splits of a perfect-split tree are these), known without classifying.
        if (s.n_right == 0) return 0;
        if (s.n_left == 0) return 1;
        side.assign(n, kBoth);
        remap.resize(n);
        {
            // The split axis's events are sorted: before the plane only ends and planars
            // decide (left), in it every type has a fixed side, after it starts and planars
            // decide (right). Written branch-free; a reference's later events win.
            const auto& ev = node.events[s.axis];
            const Event* first = ev.data();
            const Event* last = first + ev.size();
            const Event* in_plane =
                std::partition_point(first, last, [&](const Event& e) { return e.pos < s.pos; });
            const Event* after = std::partition_point(
                in_plane, last, [&](const Event& e) { return e.pos == s.pos; });
            for (const Event* e = first; e != in_plane; ++e) {
                const uint32_t r = e->code >> 2;
                side[r] = (e->code & 3u) == kStart ? side[r] : uint8_t(kLeft);
            }
            const uint8_t at_plane[3] = {kLeft, uint8_t(s.planar_side), kRight};  // by type
            for (const Event* e = in_plane; e != after; ++e) {
                side[e->code >> 2] = at_plane[e->code & 3u];
            }
            for (const Event* e = after; e != last; ++e) {
                const uint32_t r = e->code >> 2;
                side[r] = (e->code & 3u) == kEnd ? side[r] : uint8_t(kRight);
            }
        }
        // The sweep counts the same boxes against the same float: classification finds
        // references on both sides, or the cut-off would have been caught above.
        KDT_DCHECK(std::count(side.begin(), side.end(), uint8_t(kLeft)) != std::ptrdiff_t(n) &&
                   std::count(side.begin(), side.end(), uint8_t(kRight)) != std::ptrdiff_t(n));
        // One-sided references keep their order; straddlers are appended after them.
        auto& both = ws_.both;
        left.refs.resize(n);
        right.refs.resize(n);
        both.clear();
        {
            Ref* pl = left.refs.data();
            Ref* pr = right.refs.data();
            for (size_t i = 0; i < n; ++i) {
                const Ref& r = node.refs[i];
                const uint8_t sd = side[i];
                remap[i] = sd == kLeft ? uint32_t(pl - left.refs.data())
                                       : uint32_t(pr - right.refs.data());
                *pl = r;
                *pr = r;
                pl += sd == kLeft;
                pr += sd == kRight;
                if (sd == kBoth) both.push_back(uint32_t(i));
            }
            left.refs.resize(size_t(pl - left.refs.data()));
            right.refs.resize(size_t(pr - right.refs.data()));
        }
        SweepNode* child[2] = {&left, &right};
        const Bounds3f* child_box[2] = {&left_box, &right_box};
        for (auto& f : ws_.fresh) f.clear();
        for (uint32_t i : both) {
            for (int c = 0; c < 2; ++c) {
                Ref clipped;
                if (!ctx_.clip(node.refs[i], *child_box[c], clipped)) continue;
                const auto index = uint32_t(child[c]->refs.size());
                child[c]->refs.push_back(clipped);
                add_events(clipped.box, index, ws_.fresh[c].events);
            }
        }
        for (int k = 0; k < 3; ++k) {
            // Splice: the events of one-sided references, renumbered, in their sorted order.
            const auto& ev = node.events[k];
            const size_t m = ev.size();
            auto& tmp_left = ws_.tmp[0];
            auto& tmp_right = ws_.tmp[1];
            tmp_left.resize(m);
            tmp_right.resize(m);
            Event* pl = tmp_left.data();
            Event* pr = tmp_right.data();
            for (size_t i = 0; i < m; ++i) {
                const uint32_t r = ev[i].code >> 2;
                const uint8_t sd = side[r];
                const Event moved(ev[i].pos, (remap[r] << 2) | (ev[i].code & 3u));
                *pl = moved;
                *pr = moved;
                pl += sd == kLeft;
                pr += sd == kRight;
            }
            tmp_left.resize(size_t(pl - tmp_left.data()));
            tmp_right.resize(size_t(pr - tmp_right.data()));
            // Merge in the sorted events of the clipped straddlers.
            for (int c = 0; c < 2; ++c) {
                auto& fresh = ws_.fresh[c].events[k];
                auto& tmp = ws_.tmp[c];
                auto& out = child[c]->events[k];
                out.swap(tmp);
                if (fresh.empty()) continue;
                std::sort(fresh.begin(), fresh.end(), event_less);
                // Merge from the back in place: only the suffix after the first fresh event
                // moves, and there are few straddlers.
                size_t i = out.size(), j = fresh.size(), w = out.size() + fresh.size();
                out.resize(w);
                while (j > 0) {
                    if (i > 0 && event_less(fresh[j - 1], out[i - 1])) {
                        out[--w] = out[--i];
                    } else {
                        out[--w] = fresh[--j];
                    }
                }
            }
        }
        return -1;
    }

    const Context& ctx_;
    Workspace& ws_;
    Subtree& out_;
};

// ---------------------------------------------------------------------------------------
// The binned top levels: min/max bins over clipped references (no sorting), same cost.

struct BinnedSplit {
    float cost = kInfinity;
    int axis = -1;
    float pos = 0.0f;
};

/// Binned nodes with at least this many references count and classify them in
/// kTopChunks tasks (the root would otherwise keep the other threads waiting).
constexpr size_t kParallelTopRefs = size_t(1) << 18;
constexpr int kTopChunks = 8;

/// Start and end bins of reference boxes over one node's box (the same float arithmetic
/// wherever a node's bins are counted, so the counts do not depend on who counted them).
struct Binner {
    Binner(const Bounds3f& box, int bins_per_axis) : lower(box.lower), bins(bins_per_axis) {
        const Vec3f ext = box.extent();
        for (int k = 0; k < 3; ++k) scale[k] = ext[k] > 0.0f ? float(bins) / ext[k] : 0.0f;
    }
    /// counts: 3 * bins starts (axis-major), then 3 * bins ends.
    void add(const Bounds3f& b, uint32_t* counts) const {
        // Bins below 0 (and NaN) go to 0, at or above `bins` to the last one. `bins` in a
        // local: an int may alias the counts, so it would be reloaded after every increment.
        const int n = bins;
        const float last = float(n - 1);
        int index[6];
        for (int k = 0; k < 3; ++k) {
            const float lo = (b.lower[k] - lower[k]) * scale[k];
            const float hi = (b.upper[k] - lower[k]) * scale[k];
            index[k] = k * n + (lo > 0.0f ? int(std::min(lo, last)) : 0);
            index[3 + k] = (3 + k) * n + (hi > 0.0f ? int(std::min(hi, last)) : 0);
        }
        for (const int i : index) ++counts[i];
    }
    Vec3f lower;
    float scale[3];
    int bins;
};

/// Bounds of the mesh triangle whole[i], with the triangles and vertices of later
/// references prefetched: the binned levels walk bare indices whose vertices lie all over
/// the mesh, and the dependent loads (index, triangle, vertex) would otherwise dominate.
inline Bounds3f whole_bounds(const TriangleMesh& mesh, const uint32_t* whole, size_t i,
                             size_t end) {
    constexpr size_t kAhead = 8;
    if (i + 2 * kAhead < end) __builtin_prefetch(&mesh.triangles[whole[i + 2 * kAhead]]);
    if (i + kAhead < end) {
        const Vec3u& t = mesh.triangles[whole[i + kAhead]];
        __builtin_prefetch(&mesh.positions[t.x]);
        __builtin_prefetch(&mesh.positions[t.y]);
        __builtin_prefetch(&mesh.positions[t.z]);
    }
    return mesh.triangle_bounds(whole[i]);
}

/// A node of the binned phase. References never clipped so far are stored as bare triangle
/// indices (their bounds lie inside the node and are read from the mesh), which keeps the
/// top levels' scratch at about 4 bytes per triangle; clipped ones carry their box.
struct TopJob {
    TopJob(Context& c, TopNode& t, const Bounds3f& b, int d)
        : ctx(c),
          node(t),
          whole(MeteredAllocator<uint32_t>(&c.meter)),
          clipped(MeteredAllocator<Ref>(&c.meter)),
          counts(MeteredAllocator<uint32_t>(&c.meter)),
          box(b),
          depth(d) {}
    size_t size() const { return whole.size() + clipped.size(); }
    Context& ctx;
    TopNode& node;
    MeteredVector<uint32_t> whole;
    MeteredVector<Ref> clipped;
    /// Bin counts of the references over `box` (Binner::add layout), when the parent
    /// counted them while classifying; empty otherwise.
    MeteredVector<uint32_t> counts;
    Bounds3f box;
    int depth;
};

/// Counts references [begin, end) of the node (whole ones first) into counts.
void count_bins(const Context& ctx, const TopJob& job, const Binner& binner, size_t begin,
                size_t end, uint32_t* counts) {
    const size_t n_whole = job.whole.size();
    const size_t whole_end = std::min(end, n_whole);
    for (size_t i = begin; i < whole_end; ++i) {
        binner.add(whole_bounds(*ctx.mesh, job.whole.data(), i, whole_end), counts);
    }
    for (size_t i = std::max(begin, n_whole); i < end; ++i) {
        binner.add(job.clipped[i - n_whole].box, counts);
    }
}

BinnedSplit find_binned_split(const Context& ctx, TopJob& job) {
    BinnedSplit best;
    const Bounds3f& box = job.box;
    const SplitAreas areas(box);
    if (!areas.valid()) return best;
    const int bins = std::max(2, ctx.tuning.bins);
    const auto stride = size_t(6 * bins);
    if (job.counts.empty()) {
        job.counts.assign(stride, 0);
        const Binner binner(box, bins);
        if (job.size() >= kParallelTopRefs) {
            // The top node would keep the other threads waiting: count in chunks on tasks.
            // Integer sums, so the result does not depend on which thread counted what.
            std::vector<uint32_t> part(kTopChunks * stride, 0);
            const size_t chunk = (job.size() + kTopChunks - 1) / kTopChunks;
            for (int c = 0; c < kTopChunks; ++c) {
                uint32_t* counts = part.data() + size_t(c) * stride;
                const size_t begin = std::min(job.size(), size_t(c) * chunk);
                const size_t end = std::min(job.size(), begin + chunk);
#pragma omp task default(shared) firstprivate(counts, begin, end)
                count_bins(ctx, job, binner, begin, end, counts);
            }
#pragma omp taskwait
            for (size_t j = 0; j < part.size(); ++j) job.counts[j % stride] += part[j];
        } else {
            count_bins(ctx, job, binner, 0, job.size(), job.counts.data());
        }
    }
    const uint32_t* starts = job.counts.data();
    const uint32_t* ends = starts + 3 * bins;
    const Vec3f ext = box.extent();
    const size_t n = job.size();
    for (int k = 0; k < 3; ++k) {
        const float lo = box.lower[k], hi = box.upper[k];
        if (!(hi > lo)) continue;
        size_t n_left = 0, n_right = n;
        for (int j = 1; j < bins; ++j) {
            n_left += starts[k * bins + j - 1];
            n_right -= ends[k * bins + j - 1];
            const float p = lo + ext[k] * (float(j) / float(bins));
            if (!(p > lo && p < hi)) continue;
            float p_left, p_right;
            areas.ratios(k, p, p_left, p_right);
            const float c = ctx.split_cost(p_left, p_right, n_left, n_right);
            if (c < best.cost) best = {c, k, p};
        }
    }
    return best;
}

class TopBuilder {
public:
    TopBuilder(Context& ctx, std::vector<std::unique_ptr<Workspace>>& workspaces)
        : ctx_(ctx), workspaces_(workspaces) {}

    void build(std::unique_ptr<TopJob> job) {
        Context& ctx = ctx_;
        const TriangleMesh& mesh = *ctx.mesh;
        const size_t n = job->size();
        if (n <= ctx.tuning.sweep_threshold || job->depth >= ctx.max_depth) {
            sweep_task(std::move(job));
            return;
        }
        const BinnedSplit s = find_binned_split(ctx, *job);
        if (s.axis < 0 || !(s.cost < ctx.leaf_cost(n))) {
            // The bins see no gain; the exact sweep decides.
            sweep_task(std::move(job));
            return;
        }
        release(job->counts);
        TopNode& node = job->node;
        node.axis = s.axis;
        node.split = s.pos;
        std::unique_ptr<TopJob> child[2];
        for (int c = 0; c < 2; ++c) {
            node.child[c] = std::make_unique<TopNode>(&ctx.meter);
            Bounds3f b = job->box;
            (c == 0 ? b.upper : b.lower)[s.axis] = s.pos;
            child[c] = std::make_unique<TopJob>(ctx, *node.child[c], b, job->depth + 1);
        }
        // Children that will likely be binned too get their bins counted here, while each
        // reference's bounds are at hand: one pass over the mesh per level instead of two.
        const int bins = std::max(2, ctx.tuning.bins);
        const auto stride = size_t(6 * bins);
        const bool bin_children =
            n > 2 * size_t(ctx.tuning.sweep_threshold) && job->depth + 1 < ctx.max_depth;
        const Binner binner[2] = {Binner(child[0]->box, bins), Binner(child[1]->box, bins)};
        if (bin_children) {
            for (auto& c : child) c->counts.assign(stride, 0);
        }

        // Two passes: classify and count, then fill exactly sized child arrays.
        const size_t n_whole = job->whole.size();
        MeteredVector<uint8_t> side(n, kBoth, MeteredAllocator<uint8_t>(&ctx.meter));
        size_t whole_count[3] = {0, 0, 0}, clipped_count[3] = {0, 0, 0};
        // counts: the left child's bins, then the right child's (null: no binning).
        auto classify_range = [&](size_t begin, size_t end, size_t* wc, size_t* cc,
                                  uint32_t* counts) {
            const size_t whole_end = std::min(end, n_whole);
            for (size_t i = begin; i < whole_end; ++i) {
                const Bounds3f b = whole_bounds(mesh, job->whole.data(), i, whole_end);
                const Side sd = classify(b, s.axis, s.pos, kLeft);
                side[i] = sd;
                ++wc[sd];
                if (counts && sd != kBoth) binner[sd - 1].add(b, counts + (sd - 1) * stride);
            }
            for (size_t i = std::max(begin, n_whole); i < end; ++i) {
                const Bounds3f& b = job->clipped[i - n_whole].box;
                const Side sd = classify(b, s.axis, s.pos, kLeft);
                side[i] = sd;
                ++cc[sd];
                if (counts && sd != kBoth) binner[sd - 1].add(b, counts + (sd - 1) * stride);
            }
        };
        if (n >= kParallelTopRefs) {
            size_t counts[kTopChunks][6] = {};
            std::vector<uint32_t> part(bin_children ? kTopChunks * 2 * stride : 0, 0);
            const size_t chunk = (n + kTopChunks - 1) / kTopChunks;
            for (int c = 0; c < kTopChunks; ++c) {
                size_t* wc = counts[c];
                uint32_t* bc = bin_children ? part.data() + size_t(c) * 2 * stride : nullptr;
                const size_t begin = std::min(n, size_t(c) * chunk);
                const size_t end = std::min(n, begin + chunk);
#pragma omp task default(shared) firstprivate(wc, bc, begin, end)
                classify_range(begin, end, wc, wc + 3, bc);
            }
#pragma omp taskwait
            for (int c = 0; c < kTopChunks; ++c) {
                for (int j = 0; j < 3; ++j) {
                    whole_count[j] += counts[c][j];
                    clipped_count[j] += counts[c][3 + j];
                }
            }
            // Integer sums: the same bins whichever thread counted which chunk.
            for (size_t j = 0; j < part.size(); ++j) {
                const size_t in_pair = j % (2 * stride);
                child[in_pair / stride]->counts[in_pair % stride] += part[j];
            }
        } else {
            std::vector<uint32_t> both_counts(bin_children ? 2 * stride : 0, 0);
            classify_range(0, n, whole_count, clipped_count,
                           bin_children ? both_counts.data() : nullptr);
            for (size_t j = 0; j < both_counts.size(); ++j) {
                child[j / stride]->counts[j % stride] = both_counts[j];
            }
        }
        const size_t straddlers = whole_count[kBoth] + clipped_count[kBoth];
        child[0]->whole.reserve(whole_count[kLeft]);
        child[1]->whole.reserve(whole_count[kRight]);
        child[0]->clipped.reserve(clipped_count[kLeft] + straddlers);
        child[1]->clipped.reserve(clipped_count[kRight] + straddlers);
        auto clip_both = [&](const Ref& r) {
            for (int c = 0; c < 2; ++c) {
                Ref part;
                if (!ctx.clip(r, child[c]->box, part)) continue;
                child[c]->clipped.push_back(part);
                if (bin_children) binner[c].add(part.box, child[c]->counts.data());
            }
        };
        for (size_t i = 0; i < n_whole; ++i) {
            const uint32_t t = job->whole[i];
            if (side[i] == kBoth) {
                clip_both(Ref{mesh.triangle_bounds(t), t});
            } else {
                child[side[i] == kLeft ? 0 : 1]->whole.push_back(t);
            }
        }
        for (size_t i = 0; i < job->clipped.size(); ++i) {
            const Ref& r = job->clipped[i];
            if (side[n_whole + i] == kBoth) {
                clip_both(r);
            } else {
                child[side[n_whole + i] == kLeft ? 0 : 1]->clipped.push_back(r);
            }
        }
        job.reset();
        release(side);

        if (n > ctx.tuning.task_threshold) {
            TopJob* left = child[0].release();
#pragma omp task firstprivate(left)
            build(std::unique_ptr<TopJob>(left));
        } else {
            build(std::move(child[0]));
        }
        build(std::move(child[1]));
    }

private:
    void sweep_task(std::unique_ptr<TopJob> job) {
        TopJob* raw = job.release();
#pragma omp task firstprivate(raw)
        {
            std::unique_ptr<TopJob> own(raw);
            Context& ctx = own->ctx;
            auto& ws = workspaces_[size_t(omp_get_thread_num())];
            if (!ws) ws = std::make_unique<Workspace>(&ctx.meter);
            // Full references (box + triangle) only now, for this subtree.
            MeteredVector<Ref> refs(MeteredAllocator<Ref>(&ctx.meter));
            refs.reserve(own->size());
            const size_t n_whole = own->whole.size();
            for (size_t i = 0; i < n_whole; ++i) {
                refs.push_back(
                    {whole_bounds(*ctx.mesh, own->whole.data(), i, n_whole), own->whole[i]});
            }
            refs.insert(refs.end(), own->clipped.begin(), own->clipped.end());
            release(own->whole);
            release(own->clipped);
            SweepBuilder sweep(ctx, *ws, own->node.sub);
            sweep.build(refs, own->box, own->depth);  // takes the references over
            // Drop the growth slack: the subtrees together are as large as the final tree.
            own->node.sub.nodes.shrink_to_fit();
            own->node.sub.indices.shrink_to_fit();
            // Buffers reused from subtree to subtree grow towards the largest slot ever seen
            // at every level; bound what a thread keeps between subtrees.
            if (ws->bytes() > ctx.workspace_budget) ws->trim();
        }
    }

    Context& ctx_;
    std::vector<std::unique_ptr<Workspace>>& workspaces_;
};

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
                             const SahTuning& tuning) {
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
    if (params.max_depth > 0) {
        ctx.max_depth = std::min(params.max_depth, 64);
    } else {
        const double auto_depth = 8.0 + 1.3 * std::log2(double(std::max<size_t>(tri_count, 1)));
        ctx.max_depth = std::min(64, int(auto_depth));
    }
    const int threads = params.threads > 0 ? params.threads : omp_get_max_threads();
    ctx.workspace_budget = std::min(kWorkspaceBudget, kWorkspaceBytesPerTriangle * tri_count);
    // f(n) tabulated for the node sizes that dominate the build (pow() is slow).
    const size_t table = std::min<size_t>(tri_count, 1u << 16) + 1;
    ctx.f_table.resize(table);
#pragma omp parallel for num_threads(threads) schedule(static)
    for (size_t i = 0; i < table; ++i) ctx.f_table[i] = thesis_f(float(i), params.q, params.n0);
    ctx.meter.add(int64_t(ctx.f_table.capacity() * sizeof(float)));

    // Every triangle with finite vertices; the others are never referenced. Checked in
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
            usable[i] = is_finite(mesh.positions[t.x]) && is_finite(mesh.positions[t.y]) &&
                        is_finite(mesh.positions[t.z]);
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
    {
        std::vector<std::unique_ptr<Workspace>> workspaces(size_t(std::max(threads, 1)));
        TopBuilder builder(ctx, workspaces);
#pragma omp parallel num_threads(threads)
#pragma omp single
        builder.build(std::move(root));
    }

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
