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
#include <cstdint>
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

// The constants the inner-node step reads, 32 bytes a ray: org[axis] is float k, inv[axis]
// float 3 + k, neg_bits word 6.
struct Slab {
    float org[3];
    float inv[3];
    uint32_t neg_bits;
    uint32_t pad;
};

struct Task {
    uint32_t node;
    uint32_t begin, count;  // entries [begin, begin + count)
    uint32_t reserve_end;   // the entries above this are dead once the task is taken
    bool pushed;            // pop()'s rule applies to its entries
};

// Entries (ray, t0, t1) as three arrays, so that the step loads and stores eight at once.
// Each list a step writes gets kPad spare slots: eight-wide stores write whole vectors.
constexpr uint32_t kPad = 8;

// Per-thread storage, grown to the largest batch and then reused.
struct Workspace {
    std::vector<RayState> rs;
    std::vector<Slab> slab;
    std::vector<BestHit> best;
    std::vector<uint32_t> ray_of;  // caller's index of each ray
    std::vector<uint32_t> done;    // any-hit: the ray has hit (words, for gathers)
    std::vector<uint32_t> ray;
    std::vector<float> t0, t1;
    std::vector<Task> tasks;

    void reserve_entries(size_t n) {
        if (ray.size() >= n) return;
        ray.resize(2 * n);
        t0.resize(2 * n);
        t1.resize(2 * n);
    }
};

Workspace& workspace() {
    thread_local Workspace w;
    return w;
}

// Where the step's four lists grow: continuing entries in [cont, cont + count + kPad), left
// child from the front (cl), right child from the back (cr); pushed entries likewise in
// [push, push + count + kPad) (pl, pr). Each entry adds at most one entry to each region,
// so the gap between the ends of a region always exceeds what is left to add by kPad.
struct Lists {
    uint32_t cl, cr, pl, pr;
};

// descend()'s step at an inner node for entries [begin, end), one at a time: the same
// decisions and float operations. Rays of different directions decide as good as at random,
// so each entry is written to both candidate slots of its lists and only the ends move.
template <bool kAnyHit>
void step_scalar(const KdNode node, bool pushed, uint32_t begin, uint32_t end, Workspace& w,
                 Lists& l, uint64_t& visited) {
    const int axis = node.axis();
    const float split = node.split;
    const uint32_t empty = node.empty_children();
    uint32_t* er = w.ray.data();
    float* e0 = w.t0.data();
    float* e1 = w.t1.data();
    auto put = [&](uint32_t i, uint32_t r, float a, float b) {
        er[i] = r;
        e0[i] = a;
        e1[i] = b;
    };
    // descend()'s min and max: SSE's, whose NaN rule (the second operand) the decisions need.
    auto max_ss = [](float a, float b) {
        return _mm_cvtss_f32(_mm_max_ss(_mm_set_ss(a), _mm_set_ss(b)));
    };
    auto min_ss = [](float a, float b) {
        return _mm_cvtss_f32(_mm_min_ss(_mm_set_ss(a), _mm_set_ss(b)));
    };
    for (uint32_t j = begin; j < end; ++j) {
        const uint32_t r = er[j];
        const float t0 = e0[j];
        float t1 = e1[j];
        bool valid = true;
        if (kAnyHit) valid = !w.done[r];
        if (pushed) {  // pop()'s rule
            const float bt = w.best[r].t;
            valid &= lower_slack(t0) <= bt;
            t1 = std::min(t1, bt);
        }
        visited += valid;
        const Slab& s = w.slab[r];
        const float ts = _mm_cvtss_f32(_mm_mul_ss(
            _mm_sub_ss(_mm_set_ss(split), _mm_set_ss(s.org[axis])), _mm_set_ss(s.inv[axis])));
        const uint32_t neg = (s.neg_bits >> axis) & 1u;
        const bool go_near = valid & !(ts < lower_slack(t0)) & !((empty >> neg) & 1u);
        const bool go_far = valid & !(ts > detail::upper_slack(t1)) & !((empty >> (1u - neg)) & 1u);
        const float far_t0 = max_ss(ts, t0);
        // The ray goes on into the near child (t1 clipped) or, far only, into the far one.
        const float c0 = go_near ? t0 : far_t0;
        const float c1 = go_near ? min_ss(ts, t1) : t1;
        const uint32_t cont_right = neg ^ uint32_t(!go_near);
        const uint32_t moves = uint32_t(go_near | go_far);
        put(l.cl, r, c0, c1);
        put(l.cr - 1, r, c0, c1);
        l.cl += moves & (cont_right ^ 1u);
        l.cr -= moves & cont_right;
        // Both: the far child is pushed (it is the left one when neg).
        const uint32_t both = uint32_t(go_near & go_far);
        put(l.pl, r, far_t0, t1);
        put(l.pr - 1, r, far_t0, t1);
        l.pl += both & neg;
        l.pr -= both & (neg ^ 1u);
    }
}

#if KDT_SIMD_TRAVERSAL
// Lane permutations that pack the lanes of an 8-bit mask to the front (kFront) or to the
// back (kBack) of a vector.
struct PackTables {
    alignas(32) uint32_t front[256][8];
    alignas(32) uint32_t back[256][8];
    PackTables() {
        for (uint32_t m = 0; m < 256; ++m) {
            uint32_t n = 0, lanes[8] = {};
            for (uint32_t j = 0; j < 8; ++j)
                if (m >> j & 1u) lanes[n++] = j;
            for (uint32_t j = 0; j < 8; ++j) {
                front[m][j] = j < n ? lanes[j] : 0u;
                back[m][j] = j >= 8 - n ? lanes[j - (8 - n)] : 0u;
            }
        }
    }
};
const PackTables kPack;

// Stores the lanes of mask m of (r, a, b) packed at [at, at + popcount) (front) or at
// [at - popcount, at) (back); the other stored lanes fall in the region's gap.
template <bool kBack>
inline uint32_t store_packed(uint32_t m, __m256i r, __m256 a, __m256 b, uint32_t at, Workspace& w) {
    const __m256i p =
        _mm256_load_si256(reinterpret_cast<const __m256i*>(kBack ? kPack.back[m] : kPack.front[m]));
    const uint32_t n = uint32_t(__builtin_popcount(m));
    const uint32_t base = kBack ? at - 8 : at;
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(w.ray.data() + base),
                        _mm256_permutevar8x32_epi32(r, p));
    _mm256_storeu_ps(w.t0.data() + base, _mm256_permutevar8x32_ps(a, p));
    _mm256_storeu_ps(w.t1.data() + base, _mm256_permutevar8x32_ps(b, p));
    return n;
}

// step_scalar() eight entries at a time: per lane the same operations (subps / mulps as
// subss / mulss; maxps / minps keep their second operand on NaN as maxss / minss; the slack
// products are exact); entries past `end` are invalid lanes, their rays read as ray 0.
template <bool kAnyHit>
void step_simd(const KdNode node, bool pushed, uint32_t begin, uint32_t end, Workspace& w, Lists& l,
               uint64_t& visited) {
    const int axis = node.axis();
    const __m256 split = _mm256_set1_ps(node.split);
    const uint32_t empty = node.empty_children();
    const __m256i e_left = _mm256_set1_epi32(-int(empty & 1u));
    const __m256i e_right = _mm256_set1_epi32(-int((empty >> 1) & 1u));
    const __m256 abs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
    const __m256 slack = _mm256_set1_ps(kIntervalSlack);
    const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const __m256i one = _mm256_set1_epi32(1);
    const float* slab = reinterpret_cast<const float*>(w.slab.data());
    const float* best = reinterpret_cast<const float*>(w.best.data());  // t is word 0 of 4
    static_assert(sizeof(Slab) == 32 && sizeof(BestHit) == 16);
    for (uint32_t j = begin; j < end; j += 8) {
        __m256i valid = _mm256_cmpgt_epi32(_mm256_set1_epi32(int(end - j)), lane);
        const __m256i r = _mm256_and_si256(
            _mm256_loadu_si256(reinterpret_cast<const __m256i*>(w.ray.data() + j)), valid);
        const __m256 t0 = _mm256_loadu_ps(w.t0.data() + j);
        __m256 t1 = _mm256_loadu_ps(w.t1.data() + j);
        if (kAnyHit) {
            const __m256i d =
                _mm256_i32gather_epi32(reinterpret_cast<const int*>(w.done.data()), r, 4);
            valid = _mm256_andnot_si256(_mm256_cmpeq_epi32(d, one), valid);
        }
        if (pushed) {  // pop()'s rule: lower_slack(t0) <= best_t, t1 = std::min(t1, best_t)
            const __m256 bt = _mm256_i32gather_ps(best, _mm256_slli_epi32(r, 2), 4);
            const __m256 lo = _mm256_sub_ps(t0, _mm256_mul_ps(slack, _mm256_and_ps(t0, abs_mask)));
            valid = _mm256_and_si256(valid, _mm256_castps_si256(_mm256_cmp_ps(lo, bt, _CMP_LE_OQ)));
            t1 = _mm256_min_ps(bt, t1);
        }
        const uint32_t vm = uint32_t(_mm256_movemask_ps(_mm256_castsi256_ps(valid)));
        visited += uint32_t(__builtin_popcount(vm));
        if (!vm) continue;
        const __m256i r8 = _mm256_slli_epi32(r, 3);
        const __m256 org = _mm256_i32gather_ps(slab + axis, r8, 4);
        const __m256 inv = _mm256_i32gather_ps(slab + 3 + axis, r8, 4);
        const __m256i negw = _mm256_i32gather_epi32(reinterpret_cast<const int*>(slab + 6), r8, 4);
        const __m256i neg = _mm256_and_si256(_mm256_srli_epi32(negw, axis), one);
        const __m256i negm = _mm256_cmpeq_epi32(neg, one);  // near is the right child
        const __m256 ts = _mm256_mul_ps(_mm256_sub_ps(split, org), inv);
        const __m256 lo0 = _mm256_sub_ps(t0, _mm256_mul_ps(slack, _mm256_and_ps(t0, abs_mask)));
        const __m256 hi1 = _mm256_add_ps(t1, _mm256_mul_ps(slack, _mm256_and_ps(t1, abs_mask)));
        const __m256i near_empty = _mm256_blendv_epi8(e_left, e_right, negm);
        const __m256i far_empty = _mm256_blendv_epi8(e_right, e_left, negm);
        const __m256i go_near = _mm256_andnot_si256(
            near_empty,
            _mm256_and_si256(valid, _mm256_castps_si256(_mm256_cmp_ps(ts, lo0, _CMP_NLT_UQ))));
        const __m256i go_far = _mm256_andnot_si256(
            far_empty,
            _mm256_and_si256(valid, _mm256_castps_si256(_mm256_cmp_ps(ts, hi1, _CMP_NGT_UQ))));
        const __m256 far_t0 = _mm256_max_ps(ts, t0);
        const __m256 near_t1 = _mm256_min_ps(ts, t1);
        const __m256 gn = _mm256_castsi256_ps(go_near);
        const __m256 c0 = _mm256_blendv_ps(far_t0, t0, gn);
        const __m256 c1 = _mm256_blendv_ps(t1, near_t1, gn);
        const uint32_t mn = uint32_t(_mm256_movemask_ps(gn));
        const uint32_t mf = uint32_t(_mm256_movemask_ps(_mm256_castsi256_ps(go_far)));
        const uint32_t mneg = uint32_t(_mm256_movemask_ps(_mm256_castsi256_ps(negm)));
        // Continuing: near when go_near, else far when go_far; right when near is right
        // (neg) and the ray goes near, or near is left and it goes far only.
        const uint32_t moves = mn | mf;
        const uint32_t cont_right = (mneg & mn) | (~mneg & ~mn & mf);
        const uint32_t both = mn & mf;
        l.cl += store_packed<false>(moves & ~cont_right, r, c0, c1, l.cl, w);
        l.cr -= store_packed<true>(cont_right, r, c0, c1, l.cr, w);
        l.pl += store_packed<false>(both & mneg, r, far_t0, t1, l.pl, w);
        l.pr -= store_packed<true>(both & ~mneg & 0xffu, r, far_t0, t1, l.pr, w);
    }
}
#endif

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
    w.reserve_entries(4 * count + 64);
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
        w.ray[n] = n;
        w.t0[n] = t0;
        w.t1[n] = t1;
        ++n;
    }
    if (n > 0) w.tasks.push_back(Task{0, 0, n, n + kPad, false});

    const KdNode* nodes = tv.nodes;
    BestHit* best = w.best.data();
    while (!w.tasks.empty()) {
        const Task task = w.tasks.back();
        w.tasks.pop_back();
        const uint32_t top = task.reserve_end;
        w.reserve_entries(size_t(top) + 2 * (task.count + kPad));
        const KdNode node = nodes[task.node];
        const uint32_t end = task.begin + task.count;
        // Takes entry j: false when the single-ray query would not visit the node for it
        // (its ray is done, or pop() would skip it); else sets its interval there.
        auto take = [&](uint32_t j, float& t0, float& t1) {
            const uint32_t r = w.ray[j];
            if (kAnyHit && w.done[r]) return false;
            t0 = w.t0[j];
            t1 = w.t1[j];
            if (task.pushed) {
                const float bt = best[r].t;
                if (!(lower_slack(t0) <= bt)) return false;
                t1 = std::min(t1, bt);
            }
            return true;
        };
        if (node.is_leaf()) {
            for (uint32_t j = task.begin; j < end; ++j) {
                float t0, t1;
                if (!take(j, t0, t1)) continue;
                ++visited;
                const uint32_t r = w.ray[j];
                if (detail::test_leaf<kAnyHit, kDirect>(node, tv, w.rs[r], best[r], tested))
                    w.done[r] = 1;
            }
            continue;
        }
        if (task.count < min_rays) {
            for (uint32_t j = task.begin; j < end; ++j) {
                float t0, t1;
                if (!take(j, t0, t1)) continue;
                const uint32_t r = w.ray[j];
                const RayState& rs = w.rs[r];
                StackItem stack[kStackSize];
                StackItem* stop = stack;
                uint32_t idx = task.node;
                for (;;) {
                    const KdNode leaf =
                        detail::descend<true>(nodes, idx, rs, t0, t1, stop, visited);
                    if (detail::test_leaf<kAnyHit, kDirect>(leaf, tv, rs, best[r], tested)) {
                        w.done[r] = 1;
                        break;
                    }
                    if (!detail::pop(stack, stop, best[r].t, idx, t0, t1)) break;
                }
            }
            continue;
        }
        const uint32_t cont = top, push = top + task.count + kPad;
        const uint32_t reserve_end = push + task.count + kPad;
        Lists l{cont, push, push, reserve_end};
#if KDT_SIMD_TRAVERSAL
        step_simd<kAnyHit>(node, task.pushed, task.begin, end, w, l, visited);
#else
        step_scalar<kAnyHit>(node, task.pushed, task.begin, end, w, l, visited);
#endif
        // Pushed below continuing: every ray finishes its continuing child first.
        const uint32_t first = node.child();
        if (l.pl > push) w.tasks.push_back(Task{first, push, l.pl - push, reserve_end, true});
        if (l.pr < reserve_end)
            w.tasks.push_back(Task{first + 1, l.pr, reserve_end - l.pr, reserve_end, true});
        if (l.cl > cont) w.tasks.push_back(Task{first, cont, l.cl - cont, reserve_end, false});
        if (l.cr < push) w.tasks.push_back(Task{first + 1, l.cr, push - l.cr, reserve_end, false});
    }

    for (uint32_t r = 0; r < n; ++r) {
        const uint32_t i = w.ray_of[r];
        if (kAnyHit) {
            occluded[i] = uint8_t(w.done[r]);
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
