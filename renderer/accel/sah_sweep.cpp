// The exact event sweep of the SAH builder (Wald & Havran 2006, sections 4.1-4.4): events
// sorted once per subtree, O(N log N) split search and splice, one subtree per OpenMP task.
// Depends on core, geometry and the SAH internals (sah_internal.h).
#include <algorithm>
#include <bit>
#include <deque>
#include <utility>

#include "renderer/accel/sah_internal.h"
#include "renderer/core/check.h"

namespace kdt::sah_detail {

// ---------------------------------------------------------------------------------------
// Events and the per-thread buffers of the sweep.

/// A sweep event (Wald & Havran 2006, section 4.1): position on one axis and
/// (local reference index << 2 | type). Sorted by position, then end < planar < start.
struct Event {
    Event() {}  // left uninitialised: event buffers are resized before being written
    Event(float p, uint32_t c) : pos(p), code(c) {}
    float pos;
    uint32_t code;
};
constexpr uint32_t kEnd = 0, kPlanar = 1, kStart = 2;

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

namespace {

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
// The exact event sweep (Wald & Havran 2006, section 4.3), one subtree per task.

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
    void build(MeteredVector<Ref>& refs, const Bounds3f& box, int depth, double budget) {
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
        recurse(root, box, depth, budget, 0, 0);
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

    void recurse(SweepNode& node, const Bounds3f& box, int depth, double budget, int level,
                 uint32_t slot) {
        const size_t n = node.refs.size();
        if (build_cancelled(ctx_.cancel)) {
            // The tree is dropped: an empty leaf ends this branch at once.
            make_empty_leaf(slot);
            node.clear();
            return;
        }
        SweepSplit best;
        // Every split costs at least traversal_cost, so a node whose leaf is no dearer
        // stays a leaf without a sweep (the sweep could not find a cheaper split).
        // A split's N_L + N_R is at least N: none fits a budget below N.
        if (n > 0 && depth < ctx_.max_depth && ctx_.leaf_cost(n) > ctx_.params.traversal_cost &&
            fits_budget(n, 0, budget)) {
            best = find_split(node, box);
        }
        if (best.axis < 0 || !(best.cost < ctx_.leaf_cost(n)) ||
            !fits_budget(best.n_left, best.n_right, budget)) {
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
            // (N_L + N_R = N: the budget goes on whole.)
            if (full == 0) {
                recurse(node, left_box, depth + 1, budget, level, first_child);
                make_empty_leaf(first_child + 1);
            } else {
                make_empty_leaf(first_child);
                recurse(node, right_box, depth + 1, budget, level, first_child + 1);
            }
            return;
        }
        node.clear();
        recurse(left, left_box, depth + 1,
                child_budget(budget, best.n_left, best.n_left, best.n_right), level + 1,
                first_child);
        recurse(right, right_box, depth + 1,
                child_budget(budget, best.n_right, best.n_left, best.n_right), level + 1,
                first_child + 1);
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

}  // namespace

void WorkspaceDeleter::operator()(Workspace* ws) const { delete ws; }

WorkspacePtr make_workspace(ScratchMeter* meter) { return WorkspacePtr(new Workspace(meter)); }

void sweep_subtree(const Context& ctx, Workspace& ws, MeteredVector<Ref>& refs, const Bounds3f& box,
                   int depth, double budget, Subtree& out) {
    SweepBuilder sweep(ctx, ws, out);
    sweep.build(refs, box, depth, budget);  // takes the references over
    // Drop the growth slack: the subtrees together are as large as the final tree.
    out.nodes.shrink_to_fit();
    out.indices.shrink_to_fit();
    // Buffers reused from subtree to subtree grow towards the largest slot ever seen
    // at every level; bound what a thread keeps between subtrees.
    if (ws.bytes() > ctx.workspace_budget) ws.trim();
}

}  // namespace kdt::sah_detail
