#include "renderer/core/huge_pages.h"

#include <cstdint>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace kdt {

bool advise_huge_pages(const void* data, size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    const uintptr_t begin = (uintptr_t(data) + kHugePageBytes - 1) & ~uintptr_t(kHugePageBytes - 1);
    const uintptr_t end = (uintptr_t(data) + bytes) & ~uintptr_t(kHugePageBytes - 1);
    if (!data || end <= begin) return false;
    // EINVAL when the kernel has no THP: the pages stay small, as without the call.
    return ::madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE) == 0;
#else
    (void)data;
    (void)bytes;
    return false;
#endif
}

}  // namespace kdt
