// The binned top levels of the SAH builder: min/max bins over clipped references (no
// sorting), the same cost as the sweep; large nodes count and classify on OpenMP tasks, and
// every node at or below SahTuning::sweep_threshold references goes to the exact sweep.
// Depends on core, geometry and the SAH internals (sah_internal.h).
#include <omp.h>

#include <algorithm>
#include <utility>

#include "renderer/accel/sah_internal.h"

namespace kdt::sah_detail {
namespace {

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
    TopBuilder(Context& ctx, std::vector<WorkspacePtr>& workspaces)
        : ctx_(ctx), workspaces_(workspaces) {}

    void build(std::unique_ptr<TopJob> job) {
        Context& ctx = ctx_;
        const TriangleMesh& mesh = *ctx.mesh;
        const size_t n = job->size();
        if (build_cancelled(ctx.cancel)) return;  // the tree is dropped: no more work
        // (A split's N_L + N_R is at least N: none fits a budget below N.)
        if (n <= ctx.tuning.sweep_threshold || job->depth >= ctx.max_depth ||
            !fits_budget(n, 0, job->budget)) {
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
        // The split's N_L and N_R, exact (clipping below only drops references). Over the
        // budget the node is the sweep's to decide after all (sah_internal.h).
        const size_t n_left = whole_count[kLeft] + clipped_count[kLeft] + straddlers;
        const size_t n_right = whole_count[kRight] + clipped_count[kRight] + straddlers;
        if (!fits_budget(n_left, n_right, job->budget)) {
            release(side);
            child[0].reset();  // before the nodes they refer to
            child[1].reset();
            node.axis = -1;
            node.child[0].reset();
            node.child[1].reset();
            sweep_task(std::move(job));
            return;
        }
        for (int c = 0; c < 2; ++c)
            child[c]->budget =
                child_budget(job->budget, c == 0 ? n_left : n_right, n_left, n_right);
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
            if (!ws) ws = make_workspace(&ctx.meter);
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
            sweep_subtree(ctx, *ws, refs, own->box, own->depth, own->budget, own->node.sub);
        }
    }

    Context& ctx_;
    std::vector<WorkspacePtr>& workspaces_;
};

}  // namespace

void build_top(Context& ctx, std::unique_ptr<TopJob> root, int threads) {
    std::vector<WorkspacePtr> workspaces(size_t(std::max(threads, 1)));
    TopBuilder builder(ctx, workspaces);
#pragma omp parallel num_threads(threads)
#pragma omp single
    builder.build(std::move(root));
}

}  // namespace kdt::sah_detail
