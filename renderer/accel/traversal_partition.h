// Partition queries: a batch of rays descends the kd-tree together, node by node (Overbeck,
// Ramamoorthi & Mark 2008, "Large ray packets for real-time Whitted ray tracing"; Barringer &
// Akenine-Moeller 2014, "Dynamic ray stream traversal"), so that the nodes the batch shares
// are decided for all its rays in one loop each and a leaf's triangles are loaded once for all
// rays that reach it.
// Depends on accel/kdtree.h.
#pragma once

#include <cstddef>
#include <cstdint>

#include "renderer/accel/kdtree.h"

namespace kdt {

/// Below this many rays at a node, each ray finishes that node's subtree alone with the
/// single-ray loop.
inline constexpr int kPartitionMinRays = 4;

/// Closest hits of rays[0, count): hits[i] is bit for bit what tree.intersect(rays[i],
/// hits[i]) gives (same t, triangle, u, v), for any min_rays >= 1. counters, when set, gets
/// the nodes visited and triangles tested that the single-ray queries would count. Never
/// throws; allocates only while a thread's workspace grows to its largest batch.
void intersect_partition(const KdTree& tree, const Ray* rays, size_t count, Hit* hits,
                         TraversalCounters* counters = nullptr, int min_rays = kPartitionMinRays);
/// Any-hit queries: occluded[i] = 1 exactly when tree.occluded(rays[i]) is true, else 0.
void occluded_partition(const KdTree& tree, const Ray* rays, size_t count, uint8_t* occluded,
                        TraversalCounters* counters = nullptr, int min_rays = kPartitionMinRays);

}  // namespace kdt
