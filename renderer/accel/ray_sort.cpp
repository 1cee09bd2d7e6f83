#include "renderer/accel/ray_sort.h"

#include <algorithm>
#include <cmath>

namespace kdt {

namespace {

// Spreads the low 10 bits of x to every third bit.
uint32_t spread_bits(uint32_t x) {
    x &= 0x3ffu;
    x = (x | (x << 16)) & 0x030000ffu;
    x = (x | (x << 8)) & 0x0300f00fu;
    x = (x | (x << 4)) & 0x030c30c3u;
    x = (x | (x << 2)) & 0x09249249u;
    return x;
}

uint32_t quantise(float v, float lo, float extent) {
    const float f = extent > 0.0f ? (v - lo) / extent * 1024.0f : 0.0f;
    // Written so that NaN goes to 0.
    return f > 0.0f ? uint32_t(std::min(f, 1023.0f)) : 0u;
}

}  // namespace

uint64_t packet_sort_key(const Ray& ray, const Bounds3f& bounds) {
    const Vec3f d = ray.dir, a = glm::abs(d);
    if (!(a.x >= 0.0f && a.y >= 0.0f && a.z >= 0.0f)) return uint64_t(31) << 30;
    // The dominant axis as intersect.h's WatertightRay picks it (ties to the lower axis).
    const uint32_t kz = a.x >= a.y ? (a.x >= a.z ? 0u : 2u) : (a.y >= a.z ? 1u : 2u);
    const uint32_t signs = (d.x > 0.0f ? 0u : 1u) | (d.y > 0.0f ? 0u : 2u) | (d.z > 0.0f ? 0u : 4u);
    const Vec3f lo = bounds.lower, ext = bounds.extent();
    const uint32_t morton = spread_bits(quantise(ray.origin.x, lo.x, ext.x)) |
                            (spread_bits(quantise(ray.origin.y, lo.y, ext.y)) << 1) |
                            (spread_bits(quantise(ray.origin.z, lo.z, ext.z)) << 2);
    return (uint64_t(kz * 8u + signs) << 30) | morton;
}

void packet_order(const Ray* rays, size_t count, const Bounds3f& bounds,
                  std::vector<uint32_t>& order) {
    std::vector<uint64_t> keys(count);
    for (size_t i = 0; i < count; ++i) keys[i] = packet_sort_key(rays[i], bounds);
    order.resize(count);
    for (size_t i = 0; i < count; ++i) order[i] = uint32_t(i);
    // LSD radix sort on 35 key bits in passes of 12, 12 and 11 bits.
    std::vector<uint32_t> tmp(count);
    for (int shift = 0; shift < 35; shift += 12) {
        const int bits = std::min(12, 35 - shift);
        const uint64_t mask = (uint64_t(1) << bits) - 1;
        std::vector<uint32_t> hist(size_t(1) << bits, 0);
        for (size_t i = 0; i < count; ++i) ++hist[(keys[order[i]] >> shift) & mask];
        uint32_t sum = 0;
        for (uint32_t& h : hist) {
            const uint32_t c = h;
            h = sum;
            sum += c;
        }
        for (size_t i = 0; i < count; ++i) tmp[hist[(keys[order[i]] >> shift) & mask]++] = order[i];
        order.swap(tmp);
    }
}

}  // namespace kdt
