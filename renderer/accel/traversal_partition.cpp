// Partition queries (traversal_partition.h): breadth over the batch, depth over the tree.
//
// A task is a node and a list of entries (ray, t0, t1), one per ray that is at that node.
// A task of continuing entries comes from the parent's descent: the ray enters the node as
// descend() of traversal_detail.h would go on into it. A task of pushed entries holds far
// children that descend() would have pushed: pop()'s rule applies to each entry when the
// task is taken (skipped when it starts beyond the ray's closest hit, t1 clipped to it).
// At an inner node each entry makes descend()'s decision; the entries go to four tasks,
// pushed in this order: (left, pushed), (right, pushed), (left, continuing), (right,
// continuing). Every ray thus finishes the child it continues into before the far child it
// pushed, and both before anything its ancestors pushed (lower on the task stack), which is
// the single-ray query's order of leaves for each ray. Since rays share nothing but the
// tree, every result and every count is the single-ray query's.
// A task with few entries is finished ray by ray with the single-ray loop (descend(),
// test_leaf(), pop() on a stack that starts empty at the task's node).
#include "renderer/accel/traversal_partition.h"

#include <algorithm>
#include <vector>

#include <immintrin.h>

#include "renderer/accel/traversal_detail.h"

namespace kdt {
namespace {

using detail::BestHit;
using detail::kStackSize;
using detail::lower_slack;
using detail::RayState;
using detail::StackItem;
using detail::TreeView;

// One ray at one node: its interval there (internal units).
struct Entry {
    uint32_t ray;
    float t0, t1;
};

// The constants the inner-node loop reads, 32 bytes a ray.
struct Slab {
    float org[3];
    float inv[3];
    uint32_t neg_bits;
    uint32_t pad;
};

struct Task {
    uint32_t node;
    uint32_t begin, count;  // entries[begin, begin + count)
    uint32_t reserve_end;   // the entries above this are dead once the task is taken
    bool pushed;            // pop()'s rule applies to its entries
};

// Per-thread storage, grown to the largest batch and then reused.
struct Workspace {
    std::vector<RayState> rs;
    std::vector<Slab> slab;
    std::vector<BestHit> best;
    std::vector<uint32_t> ray_of;  // caller's index of each ray
    std::vector<uint8_t> done;     // any-hit: the ray has hit
    std::vector<Entry> entries;
    std::vector<Task> tasks;
};

Workspace& workspace() {
    thread_local Workspace w;
    return w;
}

inline float max_ss(float a, float b) {
    return _mm_cvtss_f32(_mm_max_ss(_mm_set_ss(a), _mm_set_ss(b)));
}
inline float min_ss(float a, float b) {
    return _mm_cvtss_f32(_mm_min_ss(_mm_set_ss(a), _mm_set_ss(b)));
}

template <bool kAnyHit, bool kDirect>
void trace_batch(const TreeView& tv, const Ray* rays, size_t count, Hit* hits, uint8_t* occluded,
                 TraversalCounters* counters, uint32_t min_rays) {
    Workspace& w = workspace();
    if (w.rs.size() < count) {
        w.rs.resize(count);
        w.slab.resize(count);
        w.best.resize(count);
        w.ray_of.resize(count);
        w.done.resize(count);
    }
    if (w.entries.size() < 4 * count + 64) w.entries.resize(4 * count + 64);
    w.tasks.clear();
    uint64_t visited = 0, tested = 0;

    // The root task: every ray that meets the tree's box, as setup_ray() leaves it.
    uint32_t n = 0;
    for (size_t i = 0; i < count; ++i) {
        RayState& rs = w.rs[n];
        rs.t_scale = 1.0f;  // setup_ray() sets it only for rays it rescales
        float t0, t1, tmax;
        if (!detail::setup_ray(rays[i], tv.bounds, rs, t0, t1, tmax)) continue;
        Slab& s = w.slab[n];
        for (int k = 0; k < 3; ++k) {
            s.org[k] = rs.org[k];
            s.inv[k] = rs.inv[k];
        }
        s.neg_bits = rs.neg_bits;
        w.best[n] = BestHit{tmax};
        w.ray_of[n] = uint32_t(i);
        w.done[n] = 0;
        w.entries[n] = Entry{n, t0, t1};
        ++n;
    }
    if (n > 0) w.tasks.push_back(Task{0, 0, n, n, false});

    const KdNode* nodes = tv.nodes;
    const Slab* slab = w.slab.data();
    BestHit* best = w.best.data();
    uint8_t* done = w.done.data();
    while (!w.tasks.empty()) {
        const Task task = w.tasks.back();
        w.tasks.pop_back();
        uint32_t top = task.reserve_end;
        if (w.entries.size() < size_t(top) + 2 * task.count)
            w.entries.resize(2 * (size_t(top) + 2 * task.count));
        Entry* e = w.entries.data();
        const KdNode node = nodes[task.node];
        // Takes entry j: false when the single-ray query would not visit the node for it
        // (its ray is done, or pop() would skip it); else sets its interval there.
        auto take = [&](const Entry& en, float& t0, float& t1) {
            if (kAnyHit && done[en.ray]) return false;
            t0 = en.t0;
            t1 = en.t1;
            if (task.pushed) {
                const float bt = best[en.ray].t;
                if (!(lower_slack(t0) <= bt)) return false;
                t1 = std::min(t1, bt);
            }
            return true;
        };
        if (node.is_leaf()) {
            for (uint32_t j = task.begin; j < task.begin + task.count; ++j) {
                float t0, t1;
                if (!take(e[j], t0, t1)) continue;
                ++visited;
                const uint32_t r = e[j].ray;
                if (detail::test_leaf<kAnyHit, kDirect>(node, tv, w.rs[r], best[r], tested))
                    done[r] = 1;
            }
            continue;
        }
        if (task.count < min_rays) {
            for (uint32_t j = task.begin; j < task.begin + task.count; ++j) {
                float t0, t1;
                if (!take(e[j], t0, t1)) continue;
                const uint32_t r = e[j].ray;
                const RayState& rs = w.rs[r];
                StackItem stack[kStackSize];
                StackItem* stop = stack;
                uint32_t idx = task.node;
                for (;;) {
                    const KdNode leaf =
                        detail::descend<true>(nodes, idx, rs, t0, t1, stop, visited);
                    if (detail::test_leaf<kAnyHit, kDirect>(leaf, tv, rs, best[r], tested)) {
                        done[r] = 1;
                        break;
                    }
                    if (!detail::pop(stack, stop, best[r].t, idx, t0, t1)) break;
                }
            }
            continue;
        }
        // descend()'s step for each entry (same operations, same NaN behaviour): continuing
        // entries fill [top, top + count) from both ends, left from the front, right from
        // the back; pushed entries fill [top + count, top + 2 count) alike.
        const int axis = node.axis();
        const float split = node.split;
        const uint32_t first = node.child();
        const uint32_t empty = node.empty_children();
        const uint32_t cont = top, push = top + task.count;
        uint32_t cl = cont, cr = push, pl = push, pr = push + task.count;
        // Branch-free: the decisions of rays whose directions differ are as good as random,
        // so each entry is written to both candidate slots of its lists and only the
        // pointers move (the writes stay inside the free middle of each region).
        for (uint32_t j = task.begin; j < task.begin + task.count; ++j) {
            const uint32_t r = e[j].ray;
            const float t0 = e[j].t0;
            float t1 = e[j].t1;
            bool valid = true;
            if (kAnyHit) valid = !done[r];
            if (task.pushed) {  // pop()'s rule
                const float bt = best[r].t;
                valid &= lower_slack(t0) <= bt;
                t1 = std::min(t1, bt);
            }
            visited += valid;
            const Slab& s = slab[r];
            const float ts = _mm_cvtss_f32(_mm_mul_ss(
                _mm_sub_ss(_mm_set_ss(split), _mm_set_ss(s.org[axis])), _mm_set_ss(s.inv[axis])));
            const uint32_t neg = (s.neg_bits >> axis) & 1u;
            const bool go_near = valid & !(ts < lower_slack(t0)) & !((empty >> neg) & 1u);
            const bool go_far =
                valid & !(ts > detail::upper_slack(t1)) & !((empty >> (1u - neg)) & 1u);
            const float far_t0 = max_ss(ts, t0);
            // The ray goes on into the near child (t1 clipped) or, far only, into the far one.
            const Entry c = go_near ? Entry{r, t0, min_ss(ts, t1)} : Entry{r, far_t0, t1};
            const uint32_t cont_right = neg ^ uint32_t(!go_near);
            const uint32_t moves = uint32_t(go_near | go_far);
            e[cl] = c;
            e[cr - 1] = c;
            cl += moves & (cont_right ^ 1u);
            cr -= moves & cont_right;
            // Both: the far child is pushed (it is the left one when neg).
            const Entry f{r, far_t0, t1};
            const uint32_t both = uint32_t(go_near & go_far);
            e[pl] = f;
            e[pr - 1] = f;
            pl += both & neg;
            pr -= both & (neg ^ 1u);
        }
        const uint32_t reserve_end = push + task.count;
        if (pl > push) w.tasks.push_back(Task{first, push, pl - push, reserve_end, true});
        if (pr < reserve_end)
            w.tasks.push_back(Task{first + 1, pr, reserve_end - pr, reserve_end, true});
        if (cl > cont) w.tasks.push_back(Task{first, cont, cl - cont, reserve_end, false});
        if (cr < push) w.tasks.push_back(Task{first + 1, cr, push - cr, reserve_end, false});
    }

    for (uint32_t r = 0; r < n; ++r) {
        const uint32_t i = w.ray_of[r];
        if (kAnyHit) {
            occluded[i] = done[r];
        } else if (best[r].prim != Hit::kNoHit) {
            hits[i].t = best[r].t * w.rs[r].t_scale;
            hits[i].u = best[r].u;
            hits[i].v = best[r].v;
            hits[i].prim = best[r].prim;
        }
    }
    if (counters) {
        counters->nodes_visited += visited;
        counters->triangles_tested += tested;
    }
}

template <bool kAnyHit>
void dispatch(const KdTree& tree, const Ray* rays, size_t count, Hit* hits, uint8_t* occluded,
              TraversalCounters* counters, int min_rays) {
    const TreeView tv = detail::view_of(tree);
    const uint32_t m = uint32_t(std::max(min_rays, 1));
    if (tv.reference_triangles)
        trace_batch<kAnyHit, true>(tv, rays, count, hits, occluded, counters, m);
    else
        trace_batch<kAnyHit, false>(tv, rays, count, hits, occluded, counters, m);
}

}  // namespace

void intersect_partition(const KdTree& tree, const Ray* rays, size_t count, Hit* hits,
                         TraversalCounters* counters, int min_rays) {
    for (size_t i = 0; i < count; ++i) hits[i] = Hit{};
    if (count == 0 || tree.nodes().empty() || tree.mesh_ptr() == nullptr) return;
    dispatch<false>(tree, rays, count, hits, nullptr, counters, min_rays);
}

void occluded_partition(const KdTree& tree, const Ray* rays, size_t count, uint8_t* occluded,
                        TraversalCounters* counters, int min_rays) {
    for (size_t i = 0; i < count; ++i) occluded[i] = 0;
    if (count == 0 || tree.nodes().empty() || tree.mesh_ptr() == nullptr) return;
    dispatch<true>(tree, rays, count, nullptr, occluded, counters, min_rays);
}

}  // namespace kdt
