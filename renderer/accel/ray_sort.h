// Orders a wavefront of incoherent rays (a bounce's rays) for the kd-tree's 8-ray packets:
// rays with the same direction signs and dominant axis (what one packet needs) together,
// and within them by the Morton code of the origin, so that a packet's rays share the
// first part of their descent. Depends on core only.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "renderer/core/math.h"

namespace kdt {

/// Sort key of a ray: bits 30..34 its packet class (dominant axis of the direction,
/// as the watertight test picks it, times 8 plus the sign bits, a zero component counting as
/// negative as in the packet setup), bits 0..29 the Morton code of its origin quantised to
/// 1024 steps per axis of `bounds` (clamped). Non-finite rays get the largest class.
uint64_t packet_sort_key(const Ray& ray, const Bounds3f& bounds);

/// The permutation that sorts rays[0, count) by packet_sort_key (stable, LSD radix sort):
/// order[k] is the index of the k-th ray. Allocates order and a scratch array of count.
void packet_order(const Ray* rays, size_t count, const Bounds3f& bounds,
                  std::vector<uint32_t>& order);

}  // namespace kdt
