// Stream queries: many independent rays (bounces, shadow rays) traced with several of them
// in flight per thread, each advanced one memory access at a time in turn, so that the
// loads of different rays overlap instead of each ray waiting on its own chain of nodes.
// Depends on accel/kdtree.h.
#pragma once

#include <cstddef>
#include <cstdint>

#include "renderer/accel/kdtree.h"

namespace kdt {

/// Rays a stream query keeps in flight per thread unless told otherwise.
inline constexpr int kStreamLanes = 16;
/// The lane counts a stream query accepts (others are rounded down to one of these). On
/// AVX2 builds multiples of eight step eight rays at once in SIMD registers.
inline constexpr int kStreamLaneChoices[] = {1, 4, 8, 16, 24, 32};

/// Closest hits of rays[0, count): hits[i] is bit for bit what tree.intersect(rays[i],
/// hits[i]) gives (same t, triangle, u, v), for any `lanes`. The rays need not be coherent;
/// `lanes` of them (see kStreamLaneChoices) are traced at a time, interleaved step by step.
/// Never throws or allocates. counters, when set, gets the nodes visited and triangles
/// tested that the single-ray queries would count for these rays (the same totals).
void intersect_stream(const KdTree& tree, const Ray* rays, size_t count, Hit* hits,
                      int lanes = kStreamLanes, TraversalCounters* counters = nullptr);
/// Any-hit queries: occluded[i] = 1 exactly when tree.occluded(rays[i]) is true, else 0.
void occluded_stream(const KdTree& tree, const Ray* rays, size_t count, uint8_t* occluded,
                     int lanes = kStreamLanes, TraversalCounters* counters = nullptr);

}  // namespace kdt
