// Internal interface between build_kdtree() and the two builders.
// Builders see triangle bounds and clipping only; they never trace rays.
#pragma once

#include <atomic>
#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

#include "renderer/accel/kdtree.h"

namespace kdt {

/// A finished build: nodes in depth-first order with adjacent children (node 0 = root),
/// leaf triangle indices, the root box, and statistics (filled by finalize_stats()).
struct KdBuildOutput {
    Bounds3f bounds;
    std::vector<KdNode> nodes;
    std::vector<uint32_t> indices;
    KdTreeStats stats;
};

/// Scratch memory accounting shared by the builders: every buffer a builder holds goes
/// through MeteredAllocator (or is added by hand), so KdTreeStats::peak_build_bytes is the
/// measured peak of the bytes allocated at once (capacities, not sizes), not a guess.
class ScratchMeter {
public:
    void add(int64_t bytes) {
        const int64_t now = current_.fetch_add(bytes, std::memory_order_relaxed) + bytes;
        int64_t peak = peak_.load(std::memory_order_relaxed);
        while (now > peak && !peak_.compare_exchange_weak(peak, now, std::memory_order_relaxed)) {
        }
    }
    int64_t current() const { return current_.load(std::memory_order_relaxed); }
    int64_t peak() const { return peak_.load(std::memory_order_relaxed); }

private:
    std::atomic<int64_t> current_{0};
    std::atomic<int64_t> peak_{0};
};

template <class T>
struct MeteredAllocator {
    using value_type = T;
    ScratchMeter* meter = nullptr;

    explicit MeteredAllocator(ScratchMeter* m) : meter(m) {}
    template <class U>
    MeteredAllocator(const MeteredAllocator<U>& other) : meter(other.meter) {}  // NOLINT

    T* allocate(size_t n) {
        meter->add(int64_t(n * sizeof(T)));
        return std::allocator<T>{}.allocate(n);
    }
    void deallocate(T* p, size_t n) {
        meter->add(-int64_t(n * sizeof(T)));
        std::allocator<T>{}.deallocate(p, n);
    }
    template <class U>
    bool operator==(const MeteredAllocator<U>& other) const {
        return meter == other.meter;
    }
};

template <class T>
using MeteredVector = std::vector<T, MeteredAllocator<T>>;

/// Frees v's memory (clear() keeps the capacity).
template <class T>
void release(MeteredVector<T>& v) {
    MeteredVector<T>(v.get_allocator()).swap(v);
}

/// The thesis's builder (section 5.2.2): candidates cut-off left/right, spatial middle,
/// median vertex and terminate, under the Szécsi cost with the f(n) correction.
/// `cancel` as for build_kdtree(): BuildCancelled once it is set.
KdBuildOutput build_thesis_tree(const TriangleMesh& mesh, const KdTreeParams& params,
                                const std::atomic<bool>* cancel = nullptr);

/// Wald & Havran 2006 O(N log N) SAH builder with perfect splits.
KdBuildOutput build_sah_tree(const TriangleMesh& mesh, const KdTreeParams& params);

/// Whether a build's cancel flag (build_kdtree()) is set; read relaxed at every node, as a
/// late read only delays the stop.
inline bool build_cancelled(const std::atomic<bool>* cancel) {
    return cancel && cancel->load(std::memory_order_relaxed);
}

/// The thesis's f(n): n for n <= n0, (n - n0)^(1 + log2 q) + n0 otherwise.
inline float thesis_f(float n, float q, int n0) {
    if (n <= float(n0)) return n;
    return std::pow(n - float(n0), 1.0f + std::log2(q)) + float(n0);
}

/// Fills out.stats from the node array (counts, leaf sizes, depth histogram, bytes).
/// Split-kind counters and build_seconds are left as the builder set them.
void finalize_stats(KdBuildOutput& out, size_t triangle_count);

/// Throws kdt::Error when a tree of `nodes` nodes cannot be stored (KdNode::kMaxNodes):
/// builders call it before assembling their final arrays, KdTree on every tree it is given.
void check_node_count(uint64_t nodes);

}  // namespace kdt
