#include "renderer/core/huge_pages.h"

#include <cstdint>
#include <filesystem>
#include <vector>

#include <gtest/gtest.h>

namespace kdt {
namespace {

TEST(HugePages, RangesWithoutAWholeHugePageAreNotAdvised) {
    EXPECT_FALSE(advise_huge_pages(nullptr, 0));
    EXPECT_FALSE(advise_huge_pages(nullptr, 64 * kHugePageBytes));
    std::vector<char> small(kHugePageBytes - 1);  // too short for a whole 2 MiB page
    EXPECT_FALSE(advise_huge_pages(small.data(), small.size()));
}

TEST(HugePages, AdvisedStorageHoldsWhatIsWritten) {
    std::vector<uint32_t> v{7, 8};
    const size_t n = 5 * kHugePageBytes / sizeof(uint32_t);
    reserve_huge(v, n);
    ASSERT_GE(v.capacity(), n);
    ASSERT_EQ(v.size(), 2u);
    EXPECT_EQ(v[0], 7u);
    EXPECT_EQ(v[1], 8u);
    for (size_t i = 2; i < n; ++i) v.push_back(uint32_t(i * 2654435761u));
    for (size_t i = 2; i < n; ++i) ASSERT_EQ(v[i], uint32_t(i * 2654435761u));
    // Enough capacity already: the storage stays where it is.
    const uint32_t* before = v.data();
    reserve_huge(v, n / 2);
    EXPECT_EQ(v.data(), before);
}

TEST(HugePages, KernelWithThpTakesTheAdvice) {
    if (!std::filesystem::exists("/sys/kernel/mm/transparent_hugepage/enabled"))
        GTEST_SKIP() << "kernel without transparent huge pages";
    std::vector<char> v;
    v.reserve(3 * kHugePageBytes);
    EXPECT_TRUE(advise_huge_pages(v.data(), v.capacity()));
}

}  // namespace
}  // namespace kdt
