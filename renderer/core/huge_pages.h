// Transparent huge pages for big arrays that are about to be filled: a 2 MiB fault instead of
// 512 faults of 4 KiB, which is most of what a cold process pays to first touch a mesh.
// Advice only: where THP is off or unsupported nothing changes. Depends on the standard
// library only.
#pragma once

#include <cstddef>
#include <vector>

namespace kdt {

/// Size of a transparent huge page on x86-64 and of the alignment advise_huge_pages uses.
inline constexpr size_t kHugePageBytes = size_t(2) << 20;

/// Asks the kernel to back the 2 MiB-aligned huge pages lying wholly inside
/// [data, data + bytes) with transparent huge pages when they are first touched; the
/// bytes around them keep 4 KiB pages, so resident memory never grows past the range.
/// Call before writing the memory (pages already touched stay as they are). Returns whether
/// the advice was taken: false when the range holds no whole huge page or the kernel has
/// THP off or unsupported, which is never an error.
bool advise_huge_pages(const void* data, size_t bytes);

/// v.reserve(n), then advise_huge_pages on the storage past v.size(). For arrays about to be
/// filled to n elements; a no-op when v already holds capacity for n.
template <typename T>
void reserve_huge(std::vector<T>& v, size_t n) {
    if (n <= v.capacity()) return;
    v.reserve(n);
    advise_huge_pages(v.data() + v.size(), (v.capacity() - v.size()) * sizeof(T));
}

}  // namespace kdt
